r"""Underwater acoustic link between a sensor node and an AUV (``docs/spec/data_collection.md``).

With the frequency :math:`f` in kHz, the ambient-noise power spectral densities (dB re
:math:`\mu\mathrm{Pa}` per Hz) are

.. math::

    N_t = 17 - 30\log_{10} f,\qquad
    N_s = 40 + 20(s - 0.5) + 26\log_{10} f - 60\log_{10}(f + 0.03),

    N_w = 50 + 7.5\sqrt{w} + 20\log_{10} f - 40\log_{10}(f + 0.4),\qquad
    N_{th} = -15 + 20\log_{10} f,

and the noise level over the bandwidth :math:`B` (Hz) is
:math:`NL = 10\log_{10}\big(B \sum_k 10^{N_k/10}\big)`. Thorp's absorption (dB/km) is
:math:`\alpha = 0.11 f^2/(1 + f^2) + 44 f^2/(4100 + f^2) + 2.75\cdot10^{-4} f^2 + 0.003`, the
transmission loss over :math:`d` metres :math:`TL = 15\log_{10} d + \alpha d / 1000`, the source
level :math:`SL = 10\log_{10} P + 170.77` (P in W), and :math:`SNR = SL - TL - NL` (dB). The
rate is evaluated at :math:`f \pm B/2` and the better one is used:

* ``rate_model="shannon"`` (default): :math:`R = B\log_2(1 + 10^{SNR/10})` bit/s;
* ``rate_model="paper"``: :math:`R = B\log_2(1 + 10^{SNR})`, the data-collection group's formula
  (it omits the /10, inflating rates about tenfold; the paper's SDR magnitudes come from it).
"""

from __future__ import annotations

import math

import torch

__all__ = [
    "RATE_MODELS",
    "link_rate",
    "noise_level_db",
    "snr_db",
    "source_level_db",
    "thorp_absorption_db_per_km",
    "transmission_loss_db",
]

RATE_MODELS = ("shannon", "paper")


def noise_level_db(
    f_khz: float, bandwidth_hz: float, shipping: float = 0.5, wind: float = 0.0
) -> float:
    """Ambient noise level over the band (dB re uPa), see the module docstring.

    >>> round(noise_level_db(20.0, 1000.0), 2)
    53.87
    """
    if f_khz <= 0 or bandwidth_hz <= 0:
        raise ValueError(f"f_khz and bandwidth_hz must be > 0, got {f_khz}, {bandwidth_hz}")
    if not 0 <= shipping <= 1 or wind < 0:
        raise ValueError(f"shipping must be in [0, 1] and wind >= 0, got {shipping}, {wind}")
    log_f = math.log10(f_khz)
    turbulence = 17 - 30 * log_f
    ship = 40 + 20 * (shipping - 0.5) + 26 * log_f - 60 * math.log10(f_khz + 0.03)
    wind_db = 50 + 7.5 * math.sqrt(wind) + 20 * log_f - 40 * math.log10(f_khz + 0.4)
    thermal = -15 + 20 * log_f
    psd = sum(10 ** (n / 10) for n in (turbulence, ship, wind_db, thermal))
    return 10 * math.log10(bandwidth_hz * psd)


def thorp_absorption_db_per_km(f_khz: float) -> float:
    """Thorp's absorption coefficient (dB/km) at ``f_khz``.

    >>> round(thorp_absorption_db_per_km(20.0), 3)
    4.134
    """
    f2 = f_khz * f_khz
    return 0.11 * f2 / (1 + f2) + 44 * f2 / (4100 + f2) + 2.75e-4 * f2 + 0.003


def source_level_db(power_w: float) -> float:
    """Source level :math:`10\\log_{10} P + 170.77` (dB re uPa at 1 m)."""
    if power_w <= 0:
        raise ValueError(f"power_w must be > 0, got {power_w}")
    return 10 * math.log10(power_w) + 170.77


def transmission_loss_db(distance_m: torch.Tensor, f_khz: float) -> torch.Tensor:
    """Spreading (k = 1.5) plus absorption loss (dB) over ``distance_m`` (m, clamped >= 1)."""
    d = torch.as_tensor(distance_m).clamp_min(1.0)
    return 15 * torch.log10(d) + thorp_absorption_db_per_km(f_khz) * d / 1000


def snr_db(
    distance_m: torch.Tensor,
    f_khz: float = 20.0,
    *,
    bandwidth_hz: float = 1000.0,
    power_w: float = 0.09,
    shipping: float = 0.5,
    wind: float = 0.0,
) -> torch.Tensor:
    """Signal-to-noise ratio (dB) at ``distance_m``."""
    return (
        source_level_db(power_w)
        - transmission_loss_db(distance_m, f_khz)
        - noise_level_db(f_khz, bandwidth_hz, shipping, wind)
    )


def link_rate(
    distance_m: torch.Tensor,
    *,
    rate_model: str = "shannon",
    f_khz: float = 20.0,
    bandwidth_hz: float = 1000.0,
    power_w: float = 0.09,
    shipping: float = 0.5,
    wind: float = 0.0,
) -> torch.Tensor:
    """Link rate (bit/s) over ``distance_m`` (m, any shape), the better of ``f -+ B/2``.

    >>> rate = link_rate(torch.tensor([10.0, 100.0]))
    >>> bool(rate[0] > rate[1] > 0)
    True
    >>> paper = link_rate(torch.tensor([18.0]), rate_model="paper")  # no overflow in float32
    >>> round((paper / link_rate(torch.tensor([18.0]))).item(), 1)  # about tenfold
    10.0
    """
    if rate_model not in RATE_MODELS:
        raise ValueError(f"rate_model must be one of {RATE_MODELS}, got {rate_model!r}")
    half = bandwidth_hz / 2000.0  # kHz
    rates = []
    for f in (f_khz - half, f_khz + half):
        snr = snr_db(
            distance_m, f, bandwidth_hz=bandwidth_hz, power_w=power_w, shipping=shipping, wind=wind
        )
        exponent = snr / 10 if rate_model == "shannon" else snr
        # log2(1 + 10^x) = softplus(x ln 10) / ln 2, stable where 10^x overflows (paper model)
        bits = torch.nn.functional.softplus(exponent * math.log(10.0)) / math.log(2.0)
        rates.append(bandwidth_hz * bits)
    return torch.maximum(*rates)
