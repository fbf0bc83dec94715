"""Acoustic link: formulas against independent scalar arithmetic, monotonicity, bad input."""

from __future__ import annotations

import math

import pytest
import torch

from torchrl_auv.physics.acoustics import (
    link_rate,
    noise_level_db,
    snr_db,
    thorp_absorption_db_per_km,
)


def _reference_rate(d, f, model):
    """Scalar re-computation from the spec's formulas, written out term by term."""
    b = 1000.0
    lf = math.log10(f)
    n = [
        17 - 30 * lf,
        40 + 0 + 26 * lf - 60 * math.log10(f + 0.03),
        50 + 0 + 20 * lf - 40 * math.log10(f + 0.4),
        -15 + 20 * lf,
    ]
    nl = 10 * math.log10(b * sum(10 ** (x / 10) for x in n))
    alpha = 0.11 * f**2 / (1 + f**2) + 44 * f**2 / (4100 + f**2) + 2.75e-4 * f**2 + 0.003
    tl = 15 * math.log10(d) + alpha * d / 1000
    sl = 10 * math.log10(0.09) + 170.77
    snr = sl - tl - nl
    return b * math.log2(1 + 10 ** (snr / 10 if model == "shannon" else snr))


@pytest.mark.parametrize("model", ["shannon", "paper"])
def test_rate_matches_scalar_formulas(model):
    distances = [5.0, 18.0, 50.0, 200.0, 1000.0]
    got = link_rate(torch.tensor(distances, dtype=torch.float64), rate_model=model)
    for d, r in zip(distances, got.tolist(), strict=True):
        expected = max(_reference_rate(d, 19.5, model), _reference_rate(d, 20.5, model))
        assert r == pytest.approx(expected, rel=1e-9)


def test_rate_decreases_with_distance_and_paper_is_larger():
    d = torch.linspace(2.0, 2000.0, 500, dtype=torch.float64)
    shannon, paper = link_rate(d), link_rate(d, rate_model="paper")
    assert (shannon[1:] < shannon[:-1]).all()
    assert (paper > shannon).all() and torch.isfinite(paper).all()
    paper32 = link_rate(d.float(), rate_model="paper")
    assert torch.isfinite(paper32).all()
    torch.testing.assert_close(paper32.double(), paper, rtol=1e-5, atol=0)
    snr = snr_db(torch.tensor(18.0))
    assert snr > 0  # a node within service range is well above the noise


def test_component_values():
    assert thorp_absorption_db_per_km(1.0) == pytest.approx(0.11 / 2 + 44 / 4101 + 2.75e-4 + 0.003)
    assert noise_level_db(20.0, 2000.0) == pytest.approx(
        noise_level_db(20.0, 1000.0) + 10 * math.log10(2)
    )


def test_bad_input():
    with pytest.raises(ValueError, match="rate_model"):
        link_rate(torch.tensor(10.0), rate_model="magic")
    with pytest.raises(ValueError, match="bandwidth_hz"):
        noise_level_db(20.0, 0.0)
    with pytest.raises(ValueError, match="power_w"):
        link_rate(torch.tensor(10.0), power_w=0.0)
