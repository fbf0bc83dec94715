"""The JONSWAP spectrum, its equal-energy frequency sampling and the finite-depth dispersion
relation (:mod:`~torchrl_auv.physics.ocean`, "Waves")."""

from __future__ import annotations

import functools
import math

import torch

GRAVITY = 9.81  # m/s^2, as in the REMUS-100 model

# Frequency grid (in units of the peak frequency) on which the spectrum is tabulated and
# normalised: the JONSWAP density is below 1e-300 at the lower end, and the energy above the
# upper end is 1 - exp(-1.25 / 12^4) = 6e-5 of m0.
_GRID_LOW, _GRID_HIGH, _GRID_POINTS = 0.2, 12.0, 40001
# The inverse of the spectrum's cumulative energy is tabulated at this many equally spaced
# quantiles, so drawing a frequency is a table look-up (no search).
_QUANTILE_POINTS = 16385


def jonswap_spectrum(omega: torch.Tensor, hs: float, tp: float, gamma: float) -> torch.Tensor:
    r"""JONSWAP spectral density :math:`S(\omega)` (m^2 s/rad), scaled to :math:`m_0 = H_s^2/16`.

    .. math::

        S(\omega) = A\,\omega^{-5} \exp\!\big(-\tfrac54 (\omega_p/\omega)^4\big)\,
        \gamma^{\exp(-(\omega-\omega_p)^2 / (2\sigma^2\omega_p^2))},\qquad
        \sigma = \begin{cases}0.07 & \omega \le \omega_p\ 0.09 & \omega > \omega_p\end{cases}

    with :math:`\omega_p = 2\pi/T_p` and :math:`A` fixed numerically (trapezoid rule on
    :math:`[0.2\,\omega_p, 12\,\omega_p]`, 40001 points) so that
    :math:`H_s = 4\sqrt{m_0}`, :math:`m_0 = \int_0^\infty S\,d\omega`.

    Args:
        omega: angular frequencies (rad/s), any shape; values are clamped at 1e-6.
        hs: significant wave height (m).
        tp: peak period (s).
        gamma: peak-enhancement factor.

    Returns:
        :math:`S(\omega)`, shaped and typed like ``omega``.

    >>> w = torch.linspace(0.05, 5.0, 20000, dtype=torch.float64)
    >>> s = jonswap_spectrum(w, 4.0, 10.0, 3.3)
    >>> round(4 * torch.trapezoid(s, w).sqrt().item(), 3)
    4.0
    """
    _, cdf_unnormalised = _spectrum_table(float(tp), float(gamma))
    return _jonswap_shape(omega, tp, gamma) * (hs**2 / 16.0 / cdf_unnormalised[-1].item())


def _jonswap_shape(omega: torch.Tensor, tp: float, gamma: float) -> torch.Tensor:
    wp = 2 * math.pi / tp
    omega = omega.clamp_min(1e-6)
    sigma = torch.where(omega <= wp, 0.07, 0.09)
    peak = torch.exp(-((omega - wp) ** 2) / (2 * sigma**2 * wp**2))
    return omega.pow(-5) * torch.exp(-1.25 * (wp / omega) ** 4) * gamma**peak


@functools.lru_cache(maxsize=32)
def _spectrum_table(tp: float, gamma: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Frequency grid (rad/s) and the unnormalised cumulative spectrum on it, float64, CPU."""
    wp = 2 * math.pi / tp
    omega = torch.linspace(_GRID_LOW * wp, _GRID_HIGH * wp, _GRID_POINTS, dtype=torch.float64)
    density = _jonswap_shape(omega, tp, gamma)
    cumulative = torch.cat(
        [torch.zeros(1, dtype=torch.float64), torch.cumulative_trapezoid(density, omega)]
    )
    return omega, cumulative


@functools.lru_cache(maxsize=32)
def _quantile_table(tp: float, gamma: float) -> torch.Tensor:
    """Frequencies (rad/s) at ``_QUANTILE_POINTS`` equally spaced energy quantiles, float64, CPU."""
    omega, cumulative = _spectrum_table(tp, gamma)
    cdf = cumulative / cumulative[-1]
    quantiles = torch.linspace(0.0, 1.0, _QUANTILE_POINTS, dtype=torch.float64)
    index = torch.searchsorted(cdf, quantiles).clamp(1, omega.numel() - 1)
    lo, hi = cdf[index - 1], cdf[index]
    frac = ((quantiles - lo) / (hi - lo).clamp_min(1e-300)).clamp(0, 1)
    return omega[index - 1] + frac * (omega[index] - omega[index - 1])


def _inverse_cdf(quantile: torch.Tensor, tp: float, gamma: float) -> torch.Tensor:
    r"""Frequencies (rad/s) at spectral-energy quantiles in [0, 1]: the inverse of
    :math:`F(\omega) = \int_0^\omega S / m_0`, interpolated linearly in a cached table."""
    table = _quantile_table(float(tp), float(gamma)).to(quantile.device, quantile.dtype)
    position = quantile * (_QUANTILE_POINTS - 1)
    index = position.floor().clamp(0, _QUANTILE_POINTS - 2)
    frac = position - index
    index = index.long()
    lo = table[index]
    return lo + frac * (table[index + 1] - lo)


def wavenumber(
    omega: torch.Tensor, water_depth: float | torch.Tensor | None = None
) -> torch.Tensor:
    r"""Wavenumber :math:`k` (rad/m) of linear waves of frequency :math:`\omega` in depth :math:`h`.

    Solves the dispersion relation :math:`\omega^2 = g k \tanh(k h)` (:math:`g` =
    :data:`GRAVITY`) by Newton's method in float64 on :math:`x = kh`,
    :math:`F(x) = x\tanh x - \omega^2 h/g`, from Eckart's approximation
    :math:`x_0 = y/\sqrt{\tanh y}`, :math:`y = \omega^2 h/g` (within 5 % everywhere; Newton then
    converges to rounding in a few steps). The limits: :math:`k \to \omega^2/g` in deep water
    (:math:`kh \gg 1`; ``water_depth`` ``None`` or ``inf`` gives exactly that) and
    :math:`k \to \omega/\sqrt{gh}` in shallow water (:math:`kh \ll 1`).

    Args:
        omega: angular frequencies (rad/s, > 0), any shape.
        water_depth: depth :math:`h` (m, > 0, ``inf`` allowed), broadcasting against
            ``omega``; ``None`` is deep water.

    Returns:
        :math:`k`, shaped like the broadcast of the inputs, in ``omega``'s dtype and device.

    >>> w = torch.tensor([2 * math.pi / 10], dtype=torch.float64)
    >>> k = wavenumber(w, 45.0)
    >>> round(k.item(), 5), round(k.item() * 45.0, 3)  # intermediate depth at Tp 10 s, 45 m
    (0.0421, 1.895)
    >>> bool(((GRAVITY * k * torch.tanh(k * 45.0) - w**2).abs() < 1e-14).all())
    True
    """
    deep = omega**2 / GRAVITY
    if water_depth is None:
        return deep
    omega64 = omega.to(torch.float64)
    depth = torch.as_tensor(water_depth, dtype=torch.float64, device=omega.device)
    finite = torch.isfinite(depth)
    depth = torch.where(finite, depth, 1.0)
    y = omega64**2 * depth / GRAVITY
    x = y / torch.sqrt(torch.tanh(y))
    for _ in range(50):
        tanh_x = torch.tanh(x)
        step = (x * tanh_x - y) / (tanh_x + x * (1.0 - tanh_x * tanh_x))
        x = x - step
        if bool((step.abs() <= 4e-16 * x).all()):
            break
    return torch.where(finite, (x / depth).to(omega.dtype), deep)


def _water_depth_tensor(water_depth, **kwargs) -> torch.Tensor:
    """``water_depth`` as a tensor; ValueError unless it is a number or tensor whose every
    value is > 0 (``inf`` allowed)."""
    if isinstance(water_depth, bool) or not isinstance(water_depth, (int, float, torch.Tensor)):
        raise ValueError(
            f"water_depth must be None, a number or a tensor (m), got {type(water_depth).__name__}"
        )
    depth = torch.as_tensor(water_depth, **kwargs)
    if not bool((depth > 0).all()):  # also rejects NaN
        raise ValueError(f"water_depth must be > 0 (m), got {water_depth!r}")
    return depth


def _check_water_depth(water_depth, batch_shape, dtype, device) -> torch.Tensor:
    """``water_depth`` as a ``[*B]`` tensor; ValueError unless every value is > 0 (inf ok)."""
    depth = _water_depth_tensor(water_depth, dtype=dtype, device=device)
    try:
        return depth.expand(batch_shape).clone()
    except RuntimeError as err:
        raise ValueError(
            f"water_depth must be a number or broadcast to the batch {tuple(batch_shape)}, "
            f"got shape {tuple(depth.shape)}"
        ) from err
