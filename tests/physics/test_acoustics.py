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


def _reference_noise_level(f, b, s=0.5, w=0.0):
    """The spec's ambient noise (data_collection.md, "Acoustic link"; Coates 1989 /
    Stojanovic 2007), written out term by term: PSDs in dB re uPa per Hz with f in kHz,
    shipping activity s in [0, 1], wind speed w in m/s, integrated over B Hz."""
    lf = math.log10(f)
    n = [
        17 - 30 * lf,  # turbulence
        40 + 20 * (s - 0.5) + 26 * lf - 60 * math.log10(f + 0.03),  # shipping
        50 + 7.5 * math.sqrt(w) + 20 * lf - 40 * math.log10(f + 0.4),  # wind (surface waves)
        -15 + 20 * lf,  # thermal
    ]
    return 10 * math.log10(b * sum(10 ** (x / 10) for x in n))


def _reference_rate(d, f, model, s=0.5, w=0.0):
    """Scalar re-computation from the spec's formulas, written out term by term."""
    b = 1000.0
    nl = _reference_noise_level(f, b, s, w)
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


@pytest.mark.parametrize(
    ("f", "shipping", "wind"),
    [
        (20.0, 0.0, 0.0),
        (20.0, 1.0, 0.0),
        (20.0, 0.5, 10.0),
        (20.0, 0.9, 25.0),
        (0.05, 1.0, 0.0),
        (1.0, 0.2, 5.0),
    ],
)
def test_noise_level_with_shipping_and_wind_matches_the_spec_formula(f, shipping, wind):
    got = noise_level_db(f, 1000.0, shipping, wind)
    assert got == pytest.approx(_reference_noise_level(f, 1000.0, shipping, wind), abs=1e-9)


def test_dominant_noise_component_follows_shipping_and_wind():
    """Hand estimate: where one component dominates, NL moves with it (the others, at least
    12 dB lower, change the total by less than 0.3 dB)."""
    # 50 Hz: shipping dominates (N_s ~ 72 dB/Hz at s = 0.5 vs turbulence 56, wind 38), and
    # s: 0.5 -> 1 raises N_s by 20 (s - 0.5) = 10 dB
    rise = noise_level_db(0.05, 100.0, shipping=1.0) - noise_level_db(0.05, 100.0, shipping=0.5)
    assert rise == pytest.approx(10.0, abs=0.3)
    # 20 kHz: wind dominates already at w = 0 (N_w ~ 23.6 vs thermal 11 dB/Hz); w = 16 m/s
    # adds 7.5 sqrt(16) = 30 dB to it
    rise = noise_level_db(20.0, 1000.0, wind=16.0) - noise_level_db(20.0, 1000.0, wind=0.0)
    assert rise == pytest.approx(30.0, abs=0.3)


def test_rate_with_shipping_and_wind_matches_scalar_formulas():
    distances = [5.0, 18.0, 200.0]
    d = torch.tensor(distances, dtype=torch.float64)
    for shipping, wind in ((1.0, 0.0), (0.0, 12.0), (0.8, 20.0)):
        got = link_rate(d, shipping=shipping, wind=wind)
        snr = snr_db(d, 20.5, shipping=shipping, wind=wind)
        for i, dist in enumerate(distances):
            expected = max(
                _reference_rate(dist, f, "shannon", shipping, wind) for f in (19.5, 20.5)
            )
            assert got[i].item() == pytest.approx(expected, rel=1e-9)
            sl_minus_tl = 10 * math.log10(0.09) + 170.77 - 15 * math.log10(dist)
            sl_minus_tl -= thorp_absorption_db_per_km(20.5) * dist / 1000
            assert snr[i].item() == pytest.approx(
                sl_minus_tl - _reference_noise_level(20.5, 1000.0, shipping, wind), abs=1e-9
            )


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
