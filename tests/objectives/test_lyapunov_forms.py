"""Lyapunov forms: non-negativity, shapes, the documented behaviours, priors, bad input."""

from __future__ import annotations

import pytest
import torch

from torchrl_auv.objectives import FORMS, LyapunovSpec, lyapunov_value


@pytest.mark.parametrize("form", sorted(FORMS))
def test_every_form_is_non_negative_and_shaped_b1(form):
    raw = torch.randn(64, 16) * 10
    value = lyapunov_value(raw, LyapunovSpec(form=form))
    assert value.shape == (64, 1) and (value >= 0).all()


def test_the_forms_behave_as_documented():
    small, large = torch.full((1, 4), 0.01), torch.full((1, 4), 10.0)
    sq = LyapunovSpec(form="squared")
    log = LyapunovSpec(form="log")
    # log is quadratic near zero (relaxes like squared) ...
    torch.testing.assert_close(
        lyapunov_value(small, log), lyapunov_value(small, sq), rtol=1e-3, atol=0.0
    )
    # ... and grows only logarithmically far away (gentle far from the goal)
    assert lyapunov_value(large, log) < 0.02 * lyapunov_value(large, sq)
    # softplus uses the first raw output and is positive everywhere
    sp = lyapunov_value(torch.tensor([[-30.0, 5.0]]), LyapunovSpec(form="softplus"))
    assert 0 < sp.item() < 1e-12


def test_priors_add_a_quadratic_term_on_the_named_entries():
    raw = torch.zeros(2, 1)
    observation = torch.zeros(2, 16)
    observation[0, 0] = 2.0  # position-like entry
    observation[1, 7] = 3.0  # velocity-like entry (a rate)
    position = LyapunovSpec(form="squared", prior="position", prior_weight=0.5)
    velocity = LyapunovSpec(form="squared", prior="velocity")
    assert lyapunov_value(raw, position, observation).squeeze(-1).tolist() == [2.0, 0.0]
    assert lyapunov_value(raw, velocity, observation).squeeze(-1).tolist() == [0.0, 9.0]
    with pytest.raises(ValueError, match="observation"):
        lyapunov_value(raw, position)


@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"form": "cubic"}, "form"),
        ({"prior": "acceleration"}, "prior"),
        ({"alpha": 0.0}, "alpha"),
        ({"alpha": float("nan")}, "alpha"),
        ({"prior_weight": -1.0}, "prior_weight"),
    ],
)
def test_bad_input_names_the_argument(kwargs, argument):
    with pytest.raises(ValueError, match=argument):
        LyapunovSpec(**kwargs)
