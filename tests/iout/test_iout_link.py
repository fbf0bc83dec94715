"""Link rate with the task config: independent scalar formulas, paper vs shannon, bad input."""

from __future__ import annotations

import math

import pytest
import torch

from torchrl_auv.iout import IoUTConfig, link_rate


def _scalar_rate(
    d: float,
    f: float,
    model: str,
    power: float = 0.09,
    sl_const: float = 170.77,
    s: float = 0.5,
    w: float = 0.0,
):
    """The spec's formulas, term by term, in plain python (f in kHz, d in m, shipping activity
    s in [0, 1], wind w in m/s; noise PSDs of Coates / Stojanovic in dB re uPa per Hz)."""
    bandwidth = 1000.0
    log_f = math.log10(f)
    turbulence = 17.0 - 30.0 * log_f
    shipping = 40.0 + 20.0 * (s - 0.5) + 26.0 * log_f - 60.0 * math.log10(f + 0.03)
    wind = 50.0 + 7.5 * math.sqrt(w) + 20.0 * log_f - 40.0 * math.log10(f + 0.4)
    thermal = -15.0 + 20.0 * log_f
    psd = sum(10.0 ** (n / 10.0) for n in (turbulence, shipping, wind, thermal))
    noise = 10.0 * math.log10(bandwidth * psd)
    alpha = 0.11 * f**2 / (1 + f**2) + 44 * f**2 / (4100 + f**2) + 2.75e-4 * f**2 + 0.003
    loss = 15.0 * math.log10(d) + alpha * d / 1000.0
    source = 10.0 * math.log10(power) + sl_const
    snr = source - loss - noise
    exponent = snr / 10.0 if model == "shannon" else snr
    return bandwidth * math.log2(1.0 + 10.0**exponent)


@pytest.mark.parametrize("model", ["shannon", "paper"])
def test_rate_matches_independent_scalar_formulas(model):
    distances = [1.0, 5.0, 17.9, 50.0, 283.0, 2000.0]
    got = link_rate(torch.tensor(distances, dtype=torch.float64), IoUTConfig(rate_model=model))
    assert got.dtype == torch.float64
    for d, rate in zip(distances, got.tolist(), strict=True):
        expected = max(_scalar_rate(d, 19.5, model), _scalar_rate(d, 20.5, model))
        assert rate == pytest.approx(expected, rel=1e-10)


def test_hand_checked_value_at_service_radius():
    # SL = 10 log10(0.09) + 170.77 = 160.3276; at 20.5 kHz NL ~ 53.6, TL(18 m) ~ 18.9 dB
    rate = link_rate(torch.tensor(18.0, dtype=torch.float64), IoUTConfig()).item()
    assert 28_000 < rate < 30_000  # bit/s: log2(1 + 10^8.8) ~ 29.2 bit/s/Hz over 1 kHz


def test_rate_decreases_with_distance_in_both_models():
    d = torch.linspace(1.5, 3000.0, 800, dtype=torch.float64)
    for model in ("shannon", "paper"):
        rate = link_rate(d, IoUTConfig(rate_model=model))
        assert (rate[1:] < rate[:-1]).all()
        assert (rate > 0).all()


def test_paper_rate_is_shannon_with_snr_in_tenths():
    d = torch.tensor([2.0, 18.0, 150.0, 1000.0], dtype=torch.float64)
    shannon = link_rate(d, IoUTConfig())
    paper = link_rate(d, IoUTConfig(rate_model="paper"))
    snr_db = 10.0 * torch.log10(torch.exp2(shannon / 1000.0) - 1.0)  # invert R = B log2(1+10^x/10)
    expected = 1000.0 * torch.log2(1.0 + 10.0**snr_db)
    torch.testing.assert_close(paper, expected, rtol=1e-9, atol=0.0)
    ratio = paper / shannon
    assert ((ratio > 9.9) & (ratio < 10.1)).all()  # high SNR: about tenfold
    paper32 = link_rate(d.float(), IoUTConfig(rate_model="paper"))
    assert paper32.dtype == torch.float32 and torch.isfinite(paper32).all()


def test_config_link_parameters_reach_the_formulas():
    d = torch.tensor([18.0], dtype=torch.float64)
    louder = link_rate(d, IoUTConfig(source_level_offset_db=173.0)).item()
    assert louder == pytest.approx(
        max(_scalar_rate(18.0, f, "shannon", sl_const=173.0) for f in (19.5, 20.5)), rel=1e-10
    )
    stronger = link_rate(d, IoUTConfig(source_power_w=0.9)).item()
    assert stronger == pytest.approx(
        max(_scalar_rate(18.0, f, "shannon", power=0.9) for f in (19.5, 20.5)), rel=1e-10
    )


@pytest.mark.parametrize("model", ["shannon", "paper"])
def test_config_shipping_and_wind_reach_the_noise_model(model):
    d = torch.tensor([5.0, 18.0, 300.0], dtype=torch.float64)
    for s, w in ((1.0, 0.0), (0.0, 15.0), (0.9, 9.0)):
        got = link_rate(d, IoUTConfig(rate_model=model, shipping=s, wind_mps=w))
        for dist, rate in zip(d.tolist(), got.tolist(), strict=True):
            expected = max(_scalar_rate(dist, f, model, s=s, w=w) for f in (19.5, 20.5))
            assert rate == pytest.approx(expected, rel=1e-10), (s, w, dist)


def test_wind_costs_the_hand_estimated_shannon_rate():
    # a 15 m/s wind raises the 20 kHz noise by about 7.5 sqrt(15) = 29 dB (wind dominates):
    # at 18 m the SNR stays high (~88 dB -> ~59 dB), where log2(1 + 10^(SNR/10)) loses
    # 29 / (10 log10 2) = 9.6 bit/s/Hz over the 1 kHz band
    d = torch.tensor(18.0, dtype=torch.float64)
    calm = link_rate(d, IoUTConfig()).item()
    windy = link_rate(d, IoUTConfig(wind_mps=15.0)).item()
    assert (calm - windy) / 1000.0 == pytest.approx(29.0 / (10 * math.log10(2)), abs=0.2)


def test_unknown_rate_model_is_rejected():
    with pytest.raises(ValueError, match="rate_model"):
        IoUTConfig(rate_model="magic")
