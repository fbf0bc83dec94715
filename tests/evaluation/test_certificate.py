"""The Lyapunov certificate: the Clopper-Pearson bound against its closed form and scipy's
Beta quantile, and the decrease condition on a hand-made rollout, transition by transition."""

from __future__ import annotations

import math

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule

from torchrl_auv.evaluation import LyapunovCertificate, clopper_pearson_upper
from torchrl_auv.modules import LyapunovSpec


@pytest.mark.parametrize("n", [1, 7, 100, 5000])
def test_with_no_violation_the_bound_is_the_closed_form(n):
    # P(X = 0) = (1 - p)^n = 0.05  <=>  p = 1 - 0.05^(1/n)
    assert clopper_pearson_upper(0, n) == pytest.approx(1 - 0.05 ** (1 / n), rel=1e-9)


@pytest.mark.parametrize(("k", "n"), [(1, 10), (3, 40), (50, 1000), (900, 30000), (9, 10)])
def test_the_bound_is_the_beta_quantile(k, n):
    stats = pytest.importorskip("scipy.stats")
    expected = stats.beta.ppf(0.95, k + 1, n - k)
    assert clopper_pearson_upper(k, n) == pytest.approx(expected, rel=1e-7)
    assert clopper_pearson_upper(k, n, confidence=0.99) > clopper_pearson_upper(k, n)


def test_the_bound_grows_with_the_violations_and_refuses_nonsense():
    bounds = [clopper_pearson_upper(k, 50) for k in range(51)]
    assert all(b > k / 50 or b == 1.0 for k, b in enumerate(bounds))
    assert bounds == sorted(bounds) and bounds[-1] == 1.0
    assert clopper_pearson_upper(0, 0) == 1.0
    with pytest.raises(ValueError, match="violations must be in"):
        clopper_pearson_upper(6, 5)
    with pytest.raises(ValueError, match="confidence must be in"):
        clopper_pearson_upper(1, 5, confidence=1.0)


OBS, ACT, RAW = ("agents", "observation"), ("agents", "action"), ("agents", "raw")


def _critic():
    """L(s, a) = (o_0 + a_0)^2 with the squared form: the raw output is o_0 + a_0."""
    return TensorDictModule(lambda o, a: o[..., :1] + a[..., :1], [OBS, ACT], [RAW])


def _rollout(root_l, cost, approach, start, terminated=None, done=None):
    """One scene, one AUV, T decisions: the executed action 0, the observation's entry 0
    sqrt(L) so that L(s_t, a_t) = root_l[t]^2."""
    t = len(root_l)
    flag = lambda values: torch.tensor(values, dtype=torch.bool).view(1, t, 1, 1)  # noqa: E731
    zeros = [False] * t
    return TensorDict(
        {
            OBS: torch.tensor(root_l, dtype=torch.float32).view(1, t, 1, 1),
            ACT: torch.zeros(1, t, 1, 1),
            "next": {
                "agents": {
                    "stability_cost": torch.tensor(cost).view(1, t, 1, 1),
                    "approach": flag(approach),
                    "service_start": flag(start),
                    "terminated": flag(terminated or zeros),
                },
                "done": torch.tensor(done or zeros).view(1, t, 1),
            },
        },
        batch_size=[1, t],
    )


def test_each_transition_against_the_hand_calculation():
    alpha = 0.5
    certify = LyapunovCertificate(_critic(), LyapunovSpec(form="squared", alpha=alpha), raw_key=RAW)
    values = [9.0, 4.0, 4.0, 1.0, 0.0, 16.0]
    cost = [1.0, 1.0, 2.0, 1.0, 0.0, 3.0]
    # decisions 0-3 approach (3 starts service: absorbing), 4 in service, 5 a new leg whose
    # successor lies past the rollout (not counted)
    data = _rollout(
        [math.sqrt(v) for v in values],
        cost,
        approach=[True, True, True, True, False, True],
        start=[False, False, False, True, False, False],
    )
    delta, counted = certify.deltas(data, torch.ones(1, 6, dtype=torch.bool))
    by_hand = [
        4.0 - 9.0 + alpha * 1.0,  # -4.5 holds
        4.0 - 4.0 + alpha * 1.0,  # +0.5 violated (no decrease, a cost)
        1.0 - 4.0 + alpha * 2.0,  # -2.0 holds
        0.0 - 1.0 + alpha * 1.0,  # -0.5 holds: the equilibrium's L is 0, not L(s_4)
    ]
    torch.testing.assert_close(delta[0, :4, 0], torch.tensor(by_hand))
    assert counted[0, :, 0].tolist() == [True, True, True, True, False, False]
    row = certify(data, torch.ones(1, 6, dtype=torch.bool))
    assert row["lyapunov_transitions"] == 4
    assert row["lyapunov_decrease_holds"] == 0.75
    assert row["lyapunov_violation_upper95"] == pytest.approx(clopper_pearson_upper(1, 4))
    assert row["lyapunov_delta_mean"] == pytest.approx(sum(by_hand) / 4)
    changes = torch.tensor([4.0 - 9.0, 4.0 - 4.0, 1.0 - 4.0, 0.0 - 1.0], dtype=torch.float64)
    assert row["lyapunov_change_std"] == pytest.approx(changes.std().item())
    assert row["lyapunov_margin_mean"] == pytest.approx(alpha * (1.0 + 1.0 + 2.0 + 1.0) / 4)
    # one leg, 0-3, arriving: its sum telescopes to 0 - 9 + alpha (1 + 1 + 2 + 1) = -6.5
    assert (row["lyapunov_legs"], row["lyapunov_leg_decrease_holds"]) == (1, 1.0)
    assert row["lyapunov_legs_arrived"] == 1.0
    sums, _ = certify.legs(delta, counted, data["next", "agents", "service_start"][..., 0])
    assert sums.tolist() == pytest.approx([sum(by_hand)])


def test_legs_split_at_an_arrival_and_at_a_transition_not_counted():
    """Legs: a run of counted transitions ends where service starts (the next counted one
    starts a new leg) or where the next is not counted; each leg's Delta L are summed."""
    delta = torch.tensor([[1.0, 0.5], [-3.0, 0.5], [2.0, -2.0], [0.5, 0.5], [-1.0, 0.5]])
    counted = torch.tensor([[1, 1], [1, 1], [1, 1], [0, 1], [1, 0]], dtype=torch.bool)
    arrived = torch.tensor([[0, 0], [1, 0], [0, 1], [0, 0], [0, 0]], dtype=torch.bool)
    sums, ended = LyapunovCertificate.legs(delta[None], counted[None], arrived[None])
    # AUV 0: [0, 1] arrives, [2] then not counted, [4]; AUV 1: [0, 1, 2] arrives, [3]
    assert sums.tolist() == pytest.approx([-2.0, 2.0, -1.0, -1.0, 0.5])
    assert ended.tolist() == [True, False, False, True, False]


def test_an_episode_end_absorbs_and_nothing_is_compared_across_a_reset():
    certify = LyapunovCertificate(_critic(), LyapunovSpec(form="squared", alpha=0.1), raw_key=RAW)
    values = [4.0, 9.0, 1.0, 1.0]
    data = _rollout(
        [math.sqrt(v) for v in values],
        [1.0] * 4,
        approach=[True, True, True, True],
        start=[False] * 4,
        terminated=[False, True, False, False],  # the AUV left the area at decision 1
        done=[False, True, False, False],
    )
    mask = torch.tensor([[True, True, False, False]])  # the first episode: decisions 0-1
    delta, counted = certify.deltas(data, mask)
    assert counted[0, :, 0].tolist() == [True, True, False, False]
    torch.testing.assert_close(delta[0, :2, 0], torch.tensor([9.0 - 4.0 + 0.1, 0.0 - 9.0 + 0.1]))
    # a peer's exit: the AUV is truncated, not terminated; its next L is past the episode
    data["next", "agents", "terminated"][:] = False
    _, counted = certify.deltas(data, mask)
    assert counted[0, :, 0].tolist() == [True, False, False, False]
