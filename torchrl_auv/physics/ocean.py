r"""Ocean disturbances: sea-state presets, a Gauss-Markov current and JONSWAP waves, batched.

The paper names three sea states (ideal, extreme, very extreme) without defining them; the values
here are the project's choices recorded in ``shared/spec/data_collection.md`` ("Disturbances").
Everything is batched over scene dims ``[*B]``, follows the requested dtype and device, and draws
randomness only from the ``torch.Generator`` passed in (never from the global RNG).

**Current** (horizontal, NED). Speed :math:`V` and direction :math:`\beta` (rad, the direction
the water flows *towards*, clockwise from north, as :func:`torchrl_auv.physics.remus100.step`
reads it) are each a first-order Gauss-Markov process around their means, discretised exactly,

.. math::

    x_{k+1} = \mu + e^{-h/T}(x_k - \mu) + \sigma\sqrt{1 - e^{-2h/T}}\,w_k,\qquad
    w_k \sim \mathcal N(0, 1),

and started from the stationary distribution :math:`\mathcal N(\mu, \sigma^2)`, so the process is
stationary from the first step. Both share the time constant :math:`T`. The mean direction
:math:`\bar\beta` is drawn uniformly in :math:`[-\pi, \pi)` per scene unless
:attr:`SeaState.current_direction_mean` fixes it. The direction's spread (0.2 rad in ``es``,
0.3 rad in ``ves``) is ours. ``current_time_constant=math.inf`` gives a current that is constant
within an episode but drawn per episode.

**Waves.** A JONSWAP spectrum :math:`S(\omega)` (:func:`jonswap_spectrum`) with
:math:`\cos^2` spreading :math:`D(\theta) = \tfrac{2}{\pi}\cos^2(\theta - \bar\theta)` over
:math:`|\theta - \bar\theta| < \pi/2`, sampled once per episode into
``n_frequencies x n_directions`` components :math:`j = (i, l)`:

* frequency: the spectrum is cut into ``n_frequencies`` bins of equal energy
  :math:`m_0/N_f`; every component draws its own frequency from the spectral density inside its
  bin (stratified inverse-CDF sampling, :math:`\omega_{il} = F^{-1}((i + U_{il})/N_f)`,
  :math:`U_{il} \sim \mathcal U(0, 1)`). Distinct frequencies keep the sea ergodic (time
  averages at a point equal the spectral moments), and :math:`\mathbb E[\sum_j a_j^2\omega_j^2/2]
  = m_2` exactly;
* direction: bin centres :math:`\theta_l = \bar\theta - \pi/2 + (l + \tfrac12)\pi/N_d` with
  weights :math:`D(\theta_l)\Delta\theta` normalised to sum to one (for :math:`N_d \ge 2` the
  normalisation is already exact);
* amplitude :math:`a_j = \sqrt{2\,S(\omega)\Delta\omega\,D(\theta_l)\Delta\theta}
  = \sqrt{2\,(m_0/N_f)\,D(\theta_l)\Delta\theta}`, hence :math:`\sum_j a_j^2/2 = m_0 = H_s^2/16`
  exactly in every scene;
* deep-water wavenumber :math:`k_j = \omega_j^2/g` and a uniform random phase :math:`\varphi_j`.

The mean wave direction :math:`\bar\theta` equals the mean current direction :math:`\bar\beta`
(ours: wind sea and wind-driven current run together). With :math:`d = \max(z, 0)` the depth
(NED :math:`z`, positive down; points above the surface get the surface value), the phase
:math:`\chi_j = k_j(x\cos\theta_j + y\sin\theta_j) - \omega_j t + \varphi_j` and linear deep-water
theory,

.. math::

    \eta = \sum_j a_j\cos\chi_j,\qquad
    \begin{bmatrix}u_N \ u_E\end{bmatrix} = V\begin{bmatrix}\cos\beta \ \sin\beta\end{bmatrix}
    + \sum_j a_j\omega_j e^{-k_j d}\cos\chi_j\begin{bmatrix}\cos\theta_j \ \sin\theta_j
    \end{bmatrix},\qquad
    u_D = -\sum_j a_j\omega_j e^{-k_j d}\sin\chi_j .

**Ideal.** ``ideal`` has zero current (mean and spread) and :math:`H_s = 0`: every velocity is
exactly zero, :func:`current_at` returns exactly ``[0, 0]``, and the state keeps its full batched
shape (the same keys and random draws as the other sea states).

**Common random numbers.** :func:`reset_ocean` and :func:`step_ocean` draw the same random
numbers in the same order for every sea state, so one seed gives matching scenes across
``ideal``, ``es`` and ``ves`` (same phases, frequency quantiles and normalised current anomaly).

:func:`current_at` returns what :func:`torchrl_auv.physics.remus100.step` takes: the total
horizontal water velocity at the vehicle as ``[speed, direction]``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass

import torch
from tensordict import TensorDict

__all__ = [
    "GRAVITY",
    "SEA_STATES",
    "SeaState",
    "advance_current",
    "current_at",
    "current_from_state",
    "get_sea_state",
    "jonswap_spectrum",
    "reset_ocean",
    "step_ocean",
    "surface_elevation_at",
    "water_velocity_at",
]

GRAVITY = 9.81  # m/s^2, as in the REMUS-100 model

# Frequency grid (in units of the peak frequency) on which the spectrum is tabulated and
# normalised: the JONSWAP density is below 1e-300 at the lower end, and the energy above the
# upper end is 1 - exp(-1.25 / 12^4) = 6e-5 of m0.
_GRID_LOW, _GRID_HIGH, _GRID_POINTS = 0.2, 12.0, 40001
# The inverse of the spectrum's cumulative energy is tabulated at this many equally spaced
# quantiles, so drawing a frequency is a table look-up (no search).
_QUANTILE_POINTS = 16385


@dataclass(frozen=True)
class SeaState:
    r"""A sea state: current, waves and the USBL noise level that goes with them.

    Attributes:
        name: label used in logs and tables.
        current_mean: mean current speed :math:`\mu_V` (m/s).
        current_sigma: stationary standard deviation of the current speed (m/s).
        current_time_constant: Gauss-Markov time constant :math:`T` of speed and direction (s);
            ``math.inf`` freezes the current within an episode.
        current_direction_mean: mean direction the current flows towards (rad, clockwise from
            north); ``None`` (default) draws it uniformly in :math:`[-\pi, \pi)` per scene.
        current_direction_sigma: stationary standard deviation of the direction (rad, ours).
        wave_hs: significant wave height :math:`H_s` (m); 0 disables waves.
        wave_tp: peak period :math:`T_p` (s).
        wave_gamma: JONSWAP peak-enhancement factor :math:`\gamma \ge 1`.
        usbl_noise_fraction: USBL range noise as a fraction of the slant range.
        usbl_bearing_sigma: USBL bearing noise (rad; default 0.1 deg).

    Raises:
        ValueError: naming the field, for a negative spread, height or noise level, a
            non-positive time constant or period, :math:`\gamma < 1`, or a non-finite value.

    Examples:
        >>> calm = SeaState(name="calm", current_mean=0.2, current_sigma=0.05)
        >>> calm.wave_hs, calm.current_direction_mean
        (0.0, None)
        >>> SeaState(current_sigma=-0.1)
        Traceback (most recent call last):
        ...
        ValueError: SeaState.current_sigma must be a finite number >= 0, got -0.1
    """

    name: str = "custom"
    current_mean: float = 0.0
    current_sigma: float = 0.0
    current_time_constant: float = 60.0
    current_direction_mean: float | None = None
    current_direction_sigma: float = 0.0
    wave_hs: float = 0.0
    wave_tp: float = 10.0
    wave_gamma: float = 3.3
    usbl_noise_fraction: float = 0.001
    usbl_bearing_sigma: float = math.radians(0.1)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str):
            raise ValueError(f"SeaState.name must be a str, got {type(self.name).__name__}")
        non_negative = (
            "current_mean",
            "current_sigma",
            "current_direction_sigma",
            "wave_hs",
            "usbl_noise_fraction",
            "usbl_bearing_sigma",
        )
        for field in non_negative:
            value = getattr(self, field)
            if not (_is_real(value) and math.isfinite(value) and value >= 0):
                raise ValueError(f"SeaState.{field} must be a finite number >= 0, got {value!r}")
        for field in ("current_time_constant", "wave_tp"):
            value = getattr(self, field)
            if not (_is_real(value) and value > 0):  # inf allowed: a frozen current
                raise ValueError(f"SeaState.{field} must be a number > 0, got {value!r}")
        if not (_is_real(self.wave_gamma) and math.isfinite(self.wave_gamma)) or (
            self.wave_gamma < 1
        ):
            raise ValueError(
                f"SeaState.wave_gamma must be a finite number >= 1, got {self.wave_gamma!r}"
            )
        direction = self.current_direction_mean
        if direction is not None and not (_is_real(direction) and math.isfinite(direction)):
            raise ValueError(
                f"SeaState.current_direction_mean must be None or a finite angle (rad), "
                f"got {direction!r}"
            )


def _is_real(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


SEA_STATES: dict[str, SeaState] = {
    "ideal": SeaState(name="ideal", usbl_noise_fraction=0.001),
    "es": SeaState(
        name="es", current_mean=0.5, current_sigma=0.1, current_time_constant=60.0,
        current_direction_sigma=0.2, wave_hs=4.0, wave_tp=10.0, wave_gamma=3.3,
        usbl_noise_fraction=0.005,
    ),
    "ves": SeaState(
        name="ves", current_mean=1.0, current_sigma=0.2, current_time_constant=60.0,
        current_direction_sigma=0.3, wave_hs=6.0, wave_tp=12.0, wave_gamma=3.3,
        usbl_noise_fraction=0.01,
    ),
}  # fmt: skip


def get_sea_state(sea_state: str | SeaState) -> SeaState:
    """Return a preset by name (``ideal``, ``es``, ``ves``) or pass a :class:`SeaState` through.

    Args:
        sea_state: a preset name or a :class:`SeaState`.

    Raises:
        ValueError: for an unknown name, listing the valid ones.

    >>> get_sea_state("es").current_mean
    0.5
    >>> get_sea_state("stormy")
    Traceback (most recent call last):
    ...
    ValueError: sea_state must be one of ['es', 'ideal', 'ves'] or a SeaState, got 'stormy'
    """
    if isinstance(sea_state, SeaState):
        return sea_state
    if isinstance(sea_state, str) and sea_state in SEA_STATES:
        return SEA_STATES[sea_state]
    raise ValueError(
        f"sea_state must be one of {sorted(SEA_STATES)} or a SeaState, got {sea_state!r}"
    )


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


def _check_generator(generator: object) -> None:
    if not isinstance(generator, torch.Generator):
        raise ValueError(f"generator must be a torch.Generator, got {type(generator).__name__}")


def reset_ocean(
    sea_state: str | SeaState,
    batch_shape: torch.Size | tuple[int, ...] | list[int],
    *,
    generator: torch.Generator,
    dtype: torch.dtype = torch.float32,
    device: torch.device | str | None = None,
    n_frequencies: int = 10,
    n_directions: int = 10,
) -> TensorDict:
    r"""Draw a new ocean for each scene: a stationary current and fixed wave components.

    See the module docstring for the model and the choices behind it.

    Args:
        sea_state: a preset name (``ideal``, ``es``, ``ves``) or a :class:`SeaState`.
        batch_shape: scene dims ``[*B]``.
        generator: the only source of randomness (on ``device``).
        dtype: floating dtype of every entry except ``time`` (always float64, so that 20000
            steps of 0.05 s add up to 1000 s; float32 would drift by 0.17 s).
        device: device of the state (default: CPU).
        n_frequencies: number of equal-energy frequency bins :math:`N_f`.
        n_directions: number of directions :math:`N_d` within :math:`\pm\pi/2` of the mean.

    Returns:
        A :class:`~tensordict.TensorDict` with ``batch_size=batch_shape`` holding, shaped ``[*B]``:
        ``current_speed`` (m/s), ``current_direction`` (rad), ``current_direction_mean`` (rad),
        ``time`` (s); and shaped ``[*B, N_f * N_d]`` (frequency-major): ``wave_amplitude`` (m),
        ``wave_frequency`` (rad/s), ``wave_number`` (rad/m), ``wave_direction`` (rad),
        ``wave_phase`` (rad), plus the precomputed products ``wave_kx``, ``wave_ky`` (rad/m,
        :math:`k\cos\theta, k\sin\theta`) and ``wave_un``, ``wave_ue`` (m/s,
        :math:`a\omega\cos\theta, a\omega\sin\theta`).

    Raises:
        ValueError: for an unknown sea state, a missing generator, a non-floating dtype or
            fewer than one frequency or direction.

    >>> g = torch.Generator().manual_seed(0)
    >>> state = reset_ocean("es", (2,), generator=g)
    >>> state["wave_amplitude"].shape
    torch.Size([2, 100])
    >>> hs = 4 * (state["wave_amplitude"] ** 2 / 2).sum(-1).sqrt()
    >>> [round(h, 4) for h in hs.tolist()]
    [4.0, 4.0]
    """
    sea = get_sea_state(sea_state)
    _check_generator(generator)
    if not dtype.is_floating_point:
        raise ValueError(f"dtype must be a floating dtype, got {dtype}")
    for arg, value in (("n_frequencies", n_frequencies), ("n_directions", n_directions)):
        if not (isinstance(value, int) and value >= 1):
            raise ValueError(f"{arg} must be an int >= 1, got {value!r}")
    batch_shape = torch.Size(batch_shape)
    kw = {"dtype": dtype, "device": device}
    n_comp = n_frequencies * n_directions

    # random draws, in a fixed order whatever the sea state (common random numbers)
    uniform_direction = torch.rand(batch_shape, generator=generator, **kw)
    anomaly = torch.randn((2, *batch_shape), generator=generator, **kw)
    jitter = torch.rand((*batch_shape, n_frequencies, n_directions), generator=generator, **kw)
    phase = torch.rand((*batch_shape, n_comp), generator=generator, **kw) * (2 * math.pi)

    if sea.current_direction_mean is None:
        direction_mean = (uniform_direction * 2 - 1) * math.pi
    else:
        direction_mean = torch.full(batch_shape, sea.current_direction_mean, **kw)
    speed = sea.current_mean + sea.current_sigma * anomaly[0]
    direction = direction_mean + sea.current_direction_sigma * anomaly[1]

    # frequencies: stratified inverse-CDF draws, one equal-energy bin per row
    bins = torch.arange(n_frequencies, **kw).unsqueeze(-1)
    omega = _inverse_cdf((bins + jitter) / n_frequencies, sea.wave_tp, sea.wave_gamma)
    # directions: cos^2 spreading at bin centres within +-pi/2 of the mean, weights sum to 1
    offsets = (torch.arange(n_directions, **kw) + 0.5) * (math.pi / n_directions) - math.pi / 2
    weights = torch.cos(offsets) ** 2
    weights = weights / weights.sum()
    m0 = sea.wave_hs**2 / 16.0
    amplitude = torch.sqrt(2 * (m0 / n_frequencies) * weights).expand_as(omega)
    theta = (direction_mean[..., None, None] + offsets).expand_as(omega)

    omega = omega.reshape(*batch_shape, n_comp)
    theta = theta.reshape(*batch_shape, n_comp)
    amplitude = amplitude.reshape(*batch_shape, n_comp)
    wavenumber = omega**2 / GRAVITY
    cos_t, sin_t = torch.cos(theta), torch.sin(theta)
    return TensorDict(
        {
            "current_speed": speed,
            "current_direction": direction,
            "current_direction_mean": direction_mean,
            "time": torch.zeros(batch_shape, dtype=torch.float64, device=device),
            "wave_amplitude": amplitude,
            "wave_frequency": omega,
            "wave_number": wavenumber,
            "wave_direction": theta,
            "wave_phase": phase,
            # precomputed per episode so a physics step is a handful of fused ops
            "wave_kx": wavenumber * cos_t,
            "wave_ky": wavenumber * sin_t,
            "wave_un": amplitude * omega * cos_t,
            "wave_ue": amplitude * omega * sin_t,
        },
        batch_size=batch_shape,
        device=device,
    )


def step_ocean(
    state: TensorDict,
    sea_state: str | SeaState,
    dt: float,
    *,
    generator: torch.Generator | None,
    standard_normal: torch.Tensor | None = None,
) -> TensorDict:
    r"""Advance the current's Gauss-Markov processes and the clock by ``dt`` seconds, exactly.

    .. math::

        V_{k+1} = \mu_V + e^{-h/T}(V_k - \mu_V) + \sigma_V\sqrt{1 - e^{-2h/T}}\,w_k,\qquad
        \beta_{k+1} = \bar\beta + e^{-h/T}(\beta_k - \bar\beta)
        + \sigma_\beta\sqrt{1 - e^{-2h/T}}\,w'_k

    with independent standard normals :math:`w_k, w'_k` and :math:`t_{k+1} = t_k + h`. The wave
    components are fixed for the episode; they move through ``time``. The speed is a Gaussian
    process and may, very rarely (:math:`5\sigma` in the presets), go negative: the velocity
    vector then points against :math:`\beta`, which :func:`current_at` reports as a positive
    speed in the opposite direction.

    Args:
        state: from :func:`reset_ocean` or a previous :func:`step_ocean`, batch ``[*B]``.
        sea_state: the sea state the state was drawn for (a name or a :class:`SeaState`).
        dt: time step :math:`h > 0` (s).
        generator: the only source of randomness.
        standard_normal: ``[2, *B]`` standard normals :math:`(w_k, w'_k)` to use instead of a
            draw from ``generator`` (for callers that draw many steps' noise at once).

    Returns:
        A new TensorDict (``state`` is left unchanged; the fixed wave entries are shared).

    Raises:
        ValueError: for an unknown sea state, a missing generator or ``dt <= 0``.

    >>> g = torch.Generator().manual_seed(0)
    >>> s0 = reset_ocean("ves", (3,), generator=g)
    >>> s1 = step_ocean(s0, "ves", 0.05, generator=g)
    >>> s1["time"].tolist()
    [0.05, 0.05, 0.05]
    """
    sea = get_sea_state(sea_state)
    if standard_normal is None:
        _check_generator(generator)
    if not (_is_real(dt) and math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a finite number > 0 (seconds), got {dt!r}")
    speed = state["current_speed"]
    if standard_normal is None:
        noise = torch.randn(
            (2, *speed.shape), generator=generator, dtype=speed.dtype, device=speed.device
        )
    elif standard_normal.shape != (2, *speed.shape):
        raise ValueError(
            f"standard_normal must be shaped {(2, *speed.shape)}, "
            f"got {tuple(standard_normal.shape)}"
        )
    else:
        noise = standard_normal
    new_speed, new_direction = advance_current(
        speed, state["current_direction"], state["current_direction_mean"], sea, dt, noise
    )
    out = state.copy()
    out["current_speed"] = new_speed
    out["current_direction"] = new_direction
    out["time"] = state["time"] + dt
    return out


def advance_current(
    speed: torch.Tensor,
    direction: torch.Tensor,
    direction_mean: torch.Tensor,
    sea: SeaState,
    dt: float,
    standard_normal: torch.Tensor,
) -> tuple[torch.Tensor, torch.Tensor]:
    """The Gauss-Markov update of :func:`step_ocean` on plain tensors, without input checks.

    Args:
        speed, direction, direction_mean: ``[*B]`` current speed (m/s), direction and mean
            direction (rad).
        sea: the sea state.
        dt: step (s, > 0).
        standard_normal: ``[2, *B]`` standard normals.

    Returns:
        ``(speed, direction)`` after ``dt``.
    """
    decay = math.exp(-dt / sea.current_time_constant)
    scale = math.sqrt(-math.expm1(-2 * dt / sea.current_time_constant))  # sqrt(1 - decay^2)
    new_speed = (
        sea.current_mean
        + decay * (speed - sea.current_mean)
        + (sea.current_sigma * scale) * standard_normal[0]
    )
    new_direction = (
        direction_mean
        + decay * (direction - direction_mean)
        + (sea.current_direction_sigma * scale) * standard_normal[1]
    )
    return new_speed, new_direction


def _check_position(state: TensorDict, position_ned: torch.Tensor) -> None:
    if not isinstance(position_ned, torch.Tensor):
        raise ValueError(
            f"position_ned must be a tensor shaped [*B, 3], got {type(position_ned).__name__}"
        )
    if position_ned.shape[-1:] != (3,) or position_ned.shape[:-1] != state.batch_size:
        raise ValueError(
            f"position_ned must be shaped [*B, 3] with B = {tuple(state.batch_size)}, "
            f"got {tuple(position_ned.shape)}"
        )


def _phase_and_decay(
    state: TensorDict, position_ned: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    r"""Wave phases :math:`\chi_j` and depth decays :math:`e^{-k_j d}`, ``[*B, N]`` each."""
    frequency = state["wave_frequency"]
    x, y = position_ned[..., 0:1], position_ned[..., 1:2]
    depth = position_ned[..., 2:3].clamp_min(0.0)
    time = state["time"].to(frequency.dtype).unsqueeze(-1)
    # fused multiply-adds: one pass over [*B, N] per term
    chi = torch.addcmul(state["wave_phase"], state["wave_kx"], x)
    chi = torch.addcmul(chi, state["wave_ky"], y)
    chi = torch.addcmul(chi, frequency, time, value=-1.0)
    return chi, torch.exp(state["wave_number"] * -depth)


def _dot(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Batched dot product over the last dim (a matmul: faster than ``(a * b).sum(-1)``)."""
    return (a.unsqueeze(-2) @ b.unsqueeze(-1))[..., 0, 0]


def _horizontal(state: TensorDict, position_ned: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """North and east water velocity (m/s), ``[*B]`` each; no input checks (compile-friendly)."""
    chi, decay = _phase_and_decay(state, position_ned)
    weight = decay * torch.cos(chi)
    speed, direction = state["current_speed"], state["current_direction"]
    north = speed * torch.cos(direction) + _dot(weight, state["wave_un"])
    east = speed * torch.sin(direction) + _dot(weight, state["wave_ue"])
    return north, east


def _speed_and_direction(north: torch.Tensor, east: torch.Tensor) -> torch.Tensor:
    """``[speed, direction]`` of a horizontal vector; exactly ``[0, 0]`` for a zero vector."""
    speed = torch.sqrt(north * north + east * east)
    direction = torch.where(speed > 0, torch.atan2(east, north), torch.zeros_like(speed))
    return torch.stack((speed, direction), -1)


def water_velocity_at(state: TensorDict, position_ned: torch.Tensor) -> torch.Tensor:
    r"""Total water velocity (current plus wave orbital) at ``position_ned``, NED, ``[*B, 3]`` m/s.

    Args:
        state: ocean state, batch ``[*B]``.
        position_ned: positions :math:`(x, y, z)` (m, NED, :math:`z` = depth, positive down),
            ``[*B, 3]``; above the surface (:math:`z < 0`) the surface velocity applies.

    Returns:
        :math:`(u_N, u_E, u_D)` (m/s, NED; :math:`u_D` positive down), ``[*B, 3]``.

    Raises:
        ValueError: if ``position_ned`` is not shaped ``[*B, 3]``.

    >>> g = torch.Generator().manual_seed(0)
    >>> water_velocity_at(reset_ocean("ideal", (), generator=g), torch.zeros(3)).tolist()
    [0.0, 0.0, 0.0]
    >>> state = reset_ocean("es", (), generator=g)
    >>> deep = water_velocity_at(state, torch.tensor([0.0, 0.0, 500.0]))  # waves die out
    >>> bool((deep[:2].norm() - state["current_speed"]).abs() < 1e-4), bool(deep[2].abs() < 1e-4)
    (True, True)
    """
    _check_position(state, position_ned)
    north, east = _horizontal(state, position_ned)
    chi, decay = _phase_and_decay(state, position_ned)
    amp_omega = state["wave_amplitude"] * state["wave_frequency"]
    down = -_dot(decay * torch.sin(chi), amp_omega)
    return torch.stack((north, east, down), -1)


def surface_elevation_at(state: TensorDict, position_ned: torch.Tensor) -> torch.Tensor:
    r"""Sea-surface elevation :math:`\eta = \sum_j a_j \cos\chi_j` (m, positive up), ``[*B]``.

    Only the horizontal position enters; ``position_ned[..., 2]`` is ignored.

    Args:
        state: ocean state, batch ``[*B]``.
        position_ned: positions (m, NED), ``[*B, 3]``.

    Raises:
        ValueError: if ``position_ned`` is not shaped ``[*B, 3]``.

    >>> g = torch.Generator().manual_seed(0)
    >>> surface_elevation_at(reset_ocean("ideal", (2,), generator=g), torch.zeros(2, 3))
    tensor([0., 0.])
    """
    _check_position(state, position_ned)
    chi, _ = _phase_and_decay(state, position_ned)
    return _dot(torch.cos(chi), state["wave_amplitude"])


def current_from_state(
    state: Mapping[str, torch.Tensor], position_ned: torch.Tensor
) -> torch.Tensor:
    """:func:`current_at` without input checks, for compiled inner loops.

    ``state`` may be any mapping with the entries of :func:`reset_ocean` whose shapes
    broadcast against ``position_ned`` (e.g. scene entries with a singleton vehicle dim for a
    fleet ``[*B, N, 3]``).
    """
    return _speed_and_direction(*_horizontal(state, position_ned))


def current_at(state: TensorDict, position_ned: torch.Tensor) -> torch.Tensor:
    r"""Horizontal water velocity at the vehicle as ``[speed (m/s), direction (rad)]``, ``[*B, 2]``.

    This is the ``current`` argument of :func:`torchrl_auv.physics.remus100.step`: the
    Gauss-Markov current plus the horizontal wave orbital velocity at the vehicle's position and
    depth (the vertical orbital part is not an input of the vehicle model). The direction is
    the one the water flows towards, in :math:`(-\pi, \pi]`, and exactly 0 when the water is
    still (``ideal``).

    Args:
        state: ocean state, batch ``[*B]``.
        position_ned: vehicle positions :math:`(x, y, z)` (m, NED, :math:`z` = depth), ``[*B, 3]``.

    Raises:
        ValueError: if ``position_ned`` is not shaped ``[*B, 3]``.

    >>> g = torch.Generator().manual_seed(0)
    >>> state = reset_ocean("es", (4,), generator=g)
    >>> current_at(state, torch.tensor([[0.0, 0.0, 30.0]] * 4)).shape
    torch.Size([4, 2])
    >>> current_at(reset_ocean("ideal", (2,), generator=g), torch.zeros(2, 3)).tolist()
    [[0.0, 0.0], [0.0, 0.0]]
    """
    _check_position(state, position_ned)
    return _speed_and_direction(*_horizontal(state, position_ned))
