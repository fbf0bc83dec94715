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
* wavenumber :math:`k_j` from the linear dispersion relation in water of depth :math:`h`
  (:func:`wavenumber`), :math:`\omega_j^2 = g k_j \tanh(k_j h)`, solved once per episode; deep
  water (``water_depth=None``, the default, or :math:`h = \infty`) gives :math:`k_j =
  \omega_j^2/g`; and a uniform random phase :math:`\varphi_j`.

The mean wave direction :math:`\bar\theta` equals the mean current direction :math:`\bar\beta`
(ours: wind sea and wind-driven current run together). With the phase
:math:`\chi_j = k_j(x\cos\theta_j + y\sin\theta_j) - \omega_j t + \varphi_j`, the water depth
:math:`h` (m) and :math:`d = \min(\max(z, 0), h)` the depth of the point (NED :math:`z`, positive
down; points above the surface get the surface value, points below the seabed the seabed
value), linear finite-depth (Airy) theory gives (spec v2, "Disturbances")

.. math::

    \eta = \sum_j a_j\cos\chi_j,\qquad
    \begin{bmatrix}u_N \ u_E\end{bmatrix} = V\begin{bmatrix}\cos\beta \ \sin\beta\end{bmatrix}
    + \sum_j a_j\omega_j\,\frac{\cosh k_j(h - d)}{\sinh k_j h}\,\cos\chi_j
    \begin{bmatrix}\cos\theta_j \ \sin\theta_j\end{bmatrix},\qquad
    u_D = -\sum_j a_j\omega_j\,\frac{\sinh k_j(h - d)}{\sinh k_j h}\,\sin\chi_j .

The depth profiles are evaluated with decaying exponentials only (no overflow, and exactly the
deep-water :math:`e^{-k_j d}` for :math:`h = \infty`):

.. math::

    \frac{\cosh k(h - d)}{\sinh kh} = \frac{e^{-kd} + e^{-k(2h - d)}}{1 - e^{-2kh}},\qquad
    \frac{\sinh k(h - d)}{\sinh kh} = \frac{e^{-kd} - e^{-k(2h - d)}}{1 - e^{-2kh}},\qquad
    e^{-k(2h - d)} = \frac{e^{-2kh}}{e^{-kd}} ;

the depth-only factors :math:`e^{-2kh}` and :math:`1/(1 - e^{-2kh})` can be computed once for a
fixed depth (:func:`seabed_factors`), leaving one exponential per component per evaluation.
At the seabed (:math:`d = h`) the vertical velocity is zero (to rounding) and the horizontal
one is :math:`a\omega/\sinh kh`; in deep water both decay as :math:`e^{-kd}` and the orbits are
circles. At the project's depths (39-58 m, :math:`T_p` 10-12 s, :math:`kh \approx 1.3`-2.4 at
the peak) deep-water theory underestimates the near-bed horizontal orbital velocity: at the
``ves`` peak (12 s) in 45 m of water by 37 % 5 m above the bed and 45 % at the bed.

*Slowly varying depth.* :func:`reset_ocean` takes one depth per scene (``water_depth``, e.g.
the scene's mean seabed depth) and solves the dispersion relation with it; the velocity
functions take an optional *local* depth (the seabed under the vehicle) for the profiles
only, while the phases keep the scene's wavenumbers. This is the slowly-varying-depth
approximation without refraction or shoaling (no change of :math:`k`, direction or amplitude
over the terrain): fine for seabeds that vary by 39-58 m over 80-400 m wavelengths, not for
steep slopes.

**Ideal.** ``ideal`` has zero current (mean and spread) and :math:`H_s = 0`: every velocity is
exactly zero, :func:`current_at` returns exactly ``[0, 0, 0]`` (all ``+0``), and the state keeps
its full batched shape (the same keys and random draws as the other sea states).

**Common random numbers.** :func:`reset_ocean` and :func:`step_ocean` draw the same random
numbers in the same order for every sea state, so one seed gives matching scenes across
``ideal``, ``es`` and ``ves`` (same phases, frequency quantiles and normalised current anomaly).

:func:`current_at` returns what :func:`torchrl_auv.physics.remus100.step` takes: the total
water velocity at the vehicle as ``[speed, direction, w_down]`` (the horizontal part as speed
and direction, plus the vertical orbital velocity, m/s positive down).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass

import torch
from tensordict import TensorDict

from torchrl_auv.physics._ops import small_matmul

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
    "seabed_factors",
    "step_ocean",
    "surface_elevation_at",
    "water_velocity_at",
    "wavenumber",
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
        usbl_dropout: probability that a USBL fix is lost (acoustic loss; 0 to 1).
        usbl_attitude_sigma: residual error of the ASV's wave-driven roll/pitch after motion
            compensation (rad); it tilts the transducer, so it adds in quadrature to
            ``usbl_bearing_sigma`` on both bearing angles (per fix, independent).
        gnss_sigma: stationary standard deviation of the ASV's GNSS position error per
            horizontal axis (m); the USBL fix is computed from the believed ASV position, so
            this error becomes a bias of the fix.
        gnss_time_constant: Gauss-Markov time constant of the GNSS error (s); ``math.inf``
            freezes it within an episode.

    The localisation errors of the presets (``shared/spec/data_collection.md``, "Localisation"
    v2; values ours):

    ===============================  =====  =====  =====  ==========================================
    field                            ideal  es     ves    why
    ===============================  =====  =====  =====  ==========================================
    ``usbl_dropout``                 0      0.05   0.20   the spec's 0 / ~5 / ~20 % of fixes lost
    ``usbl_attitude_sigma`` (deg)    0      0.5    0.75   ASV roll/pitch ~2.5 deg rms per m of
                                                          :math:`H_s`, ~5 % left after compensation
    ``gnss_sigma`` (m)               1.0    1.5    2.0    a standalone/SBAS receiver (1.4 m DRMS)
                                                          on a calm ASV; a small ASV rolling and
                                                          pitching in a 4-6 m sea adds antenna
                                                          motion and multipath (the spec's 1-2 m)
    ``gnss_time_constant`` (s)       60     60     60     the spec's 60 s correlation
    ===============================  =====  =====  =====  ==========================================

    A :class:`SeaState` built by hand has none of these errors unless it sets them.

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
    usbl_dropout: float = 0.0
    usbl_attitude_sigma: float = 0.0
    gnss_sigma: float = 0.0
    gnss_time_constant: float = 60.0

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
            "usbl_attitude_sigma",
            "gnss_sigma",
        )
        for field in non_negative:
            value = getattr(self, field)
            if not (_is_real(value) and math.isfinite(value) and value >= 0):
                raise ValueError(f"SeaState.{field} must be a finite number >= 0, got {value!r}")
        if not (_is_real(self.usbl_dropout) and 0.0 <= self.usbl_dropout <= 1.0):
            raise ValueError(
                f"SeaState.usbl_dropout must be a probability in [0, 1], got {self.usbl_dropout!r}"
            )
        for field in ("current_time_constant", "wave_tp", "gnss_time_constant"):
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
    "ideal": SeaState(
        name="ideal", usbl_noise_fraction=0.001, usbl_dropout=0.0, usbl_attitude_sigma=0.0,
        gnss_sigma=1.0, gnss_time_constant=60.0,
    ),
    "es": SeaState(
        name="es", current_mean=0.5, current_sigma=0.1, current_time_constant=60.0,
        current_direction_sigma=0.2, wave_hs=4.0, wave_tp=10.0, wave_gamma=3.3,
        usbl_noise_fraction=0.005, usbl_dropout=0.05, usbl_attitude_sigma=math.radians(0.5),
        gnss_sigma=1.5, gnss_time_constant=60.0,
    ),
    "ves": SeaState(
        name="ves", current_mean=1.0, current_sigma=0.2, current_time_constant=60.0,
        current_direction_sigma=0.3, wave_hs=6.0, wave_tp=12.0, wave_gamma=3.3,
        usbl_noise_fraction=0.01, usbl_dropout=0.20, usbl_attitude_sigma=math.radians(0.75),
        gnss_sigma=2.0, gnss_time_constant=60.0,
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
    water_depth: float | torch.Tensor | None = None,
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
        water_depth: water depth :math:`h` (m, > 0) of each scene for the dispersion relation
            (:func:`wavenumber`) and the default depth profile of the velocity functions: a
            float or a ``[*B]`` tensor, ``math.inf`` allowed (deep water for that scene).
            ``None`` (default) is deep water everywhere: :math:`k = \omega^2/g` and the
            :math:`e^{-kd}` decay, exactly as before finite depth was added. The random draws
            do not depend on it (common random numbers across depths too).

    Returns:
        A :class:`~tensordict.TensorDict` with ``batch_size=batch_shape`` holding, shaped ``[*B]``:
        ``current_speed`` (m/s), ``current_direction`` (rad), ``current_direction_mean`` (rad),
        ``time`` (s), ``water_depth`` (m; only if ``water_depth`` was given: deep water has no
        entry, so that every entry is finite); and shaped ``[*B, N_f * N_d]``
        (frequency-major): ``wave_amplitude`` (m), ``wave_frequency`` (rad/s), ``wave_number``
        (rad/m, from the dispersion relation at ``water_depth``), ``wave_direction`` (rad),
        ``wave_phase`` (rad), plus the precomputed products ``wave_kx``, ``wave_ky`` (rad/m,
        :math:`k\cos\theta, k\sin\theta`) and ``wave_un``, ``wave_ue``, ``wave_ud`` (m/s,
        :math:`a\omega\cos\theta, a\omega\sin\theta, a\omega`).

    Raises:
        ValueError: for an unknown sea state, a missing generator, a non-floating dtype,
            fewer than one frequency or direction, or a water depth that is not > 0 (or
            does not broadcast to ``[*B]``).

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
    if water_depth is None:  # deep water: no water_depth entry (every entry stays finite)
        k, depth = omega**2 / GRAVITY, {}
    else:
        h = _check_water_depth(water_depth, batch_shape, dtype, device)
        k, depth = wavenumber(omega, h.unsqueeze(-1)), {"water_depth": h}
    cos_t, sin_t = torch.cos(theta), torch.sin(theta)
    return TensorDict(
        {
            **depth,
            "current_speed": speed,
            "current_direction": direction,
            "current_direction_mean": direction_mean,
            "time": torch.zeros(batch_shape, dtype=torch.float64, device=device),
            "wave_amplitude": amplitude,
            "wave_frequency": omega,
            "wave_number": k,
            "wave_direction": theta,
            "wave_phase": phase,
            # precomputed per episode so a physics step is a handful of fused ops
            "wave_kx": k * cos_t,
            "wave_ky": k * sin_t,
            "wave_un": amplitude * omega * cos_t,
            "wave_ue": amplitude * omega * sin_t,
            "wave_ud": amplitude * omega,
        },
        batch_size=batch_shape,
        device=device,
    )


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


def _check_position(
    state: TensorDict, position_ned: torch.Tensor, water_depth: float | torch.Tensor | None = None
) -> None:
    if not isinstance(position_ned, torch.Tensor):
        raise ValueError(
            f"position_ned must be a tensor shaped [*B, 3], got {type(position_ned).__name__}"
        )
    if position_ned.shape[-1:] != (3,) or position_ned.shape[:-1] != state.batch_size:
        raise ValueError(
            f"position_ned must be shaped [*B, 3] with B = {tuple(state.batch_size)}, "
            f"got {tuple(position_ned.shape)}"
        )
    if water_depth is None:
        return
    depth = _water_depth_tensor(water_depth)
    try:
        torch.broadcast_shapes(depth.shape, state.batch_size)
    except RuntimeError as err:
        raise ValueError(
            f"water_depth must broadcast to the batch {tuple(state.batch_size)}, "
            f"got shape {tuple(depth.shape)}"
        ) from err


def _phase(state: Mapping[str, torch.Tensor], position_ned: torch.Tensor) -> torch.Tensor:
    r"""Wave phases :math:`\chi_j = k_j(x\cos\theta_j + y\sin\theta_j) - \omega_j t + \varphi_j`,
    ``[*B, N]``."""
    frequency = state["wave_frequency"]
    x, y = position_ned[..., 0:1], position_ned[..., 1:2]
    time = state["time"].to(frequency.dtype).unsqueeze(-1)
    # fused multiply-adds: one pass over [*B, N] per term
    chi = torch.addcmul(state["wave_phase"], state["wave_kx"], x)
    chi = torch.addcmul(chi, state["wave_ky"], y)
    return torch.addcmul(chi, frequency, time, value=-1.0)


def seabed_factors(
    state: Mapping[str, torch.Tensor], water_depth: float | torch.Tensor | None = None
) -> dict[str, torch.Tensor]:
    r"""The depth-only factors of the orbital profiles, for a water depth held fixed.

    .. math::

        m = e^{-2kh},\qquad s = \frac{1}{1 - e^{-2kh}}\qquad\text{so that}\qquad
        \frac{\cosh k(h - d)}{\sinh kh} = s\,\Big(e^{-kd} + \frac{m}{e^{-kd}}\Big),\quad
        \frac{\sinh k(h - d)}{\sinh kh} = s\,\Big(e^{-kd} - \frac{m}{e^{-kd}}\Big).

    :func:`current_from_state` evaluates them on every call. A caller whose depth stays fixed
    over many calls (:class:`~torchrl_auv.envs.vehicles.VehicleStack`: the seabed under each
    vehicle over one decision) evaluates them once and passes the mapping
    ``{**state, **seabed_factors(state, depth)}``: each call then costs one exponential per
    wave component instead of three. In deep water (:math:`h = \infty`) :math:`m = 0` and
    :math:`s = 1` exactly.

    Args:
        state: a mapping with ``wave_number`` ``[*B, N]`` and, unless ``water_depth`` is
            given, ``water_depth``.
        water_depth: depth :math:`h` (m, > 0, ``inf`` allowed, not checked), broadcasting to
            ``[*B]``; ``None`` uses the state's.

    Returns:
        ``{"water_depth": h, "wave_bed_mirror": m, "wave_bed_scale": s}``, ``h`` shaped like the
        depth given, ``m`` and ``s`` like the broadcast of ``wave_number`` and ``h[..., None]``.

    Raises:
        ValueError: if neither ``water_depth`` nor the state gives a depth (deep water needs
            no factors: pass ``math.inf`` to get them anyway).

    >>> g = torch.Generator().manual_seed(0)
    >>> state = reset_ocean("es", (2,), generator=g, dtype=torch.float64)
    >>> factors = seabed_factors(state, math.inf)  # deep water
    >>> bool((factors["wave_bed_mirror"] == 0).all()), bool((factors["wave_bed_scale"] == 1).all())
    (True, True)
    """
    k = state["wave_number"]
    if water_depth is None and "water_depth" not in state:
        raise ValueError("seabed_factors needs a water_depth: the state has none (deep water)")
    h = state["water_depth"] if water_depth is None else water_depth
    h = torch.as_tensor(h, dtype=k.dtype, device=k.device)
    two_kh = k * (2.0 * h.unsqueeze(-1))
    return {
        "water_depth": h,
        "wave_bed_mirror": torch.exp(-two_kh),  # e^{-2kh}
        "wave_bed_scale": -1.0 / torch.expm1(-two_kh),  # 1 / (1 - e^{-2kh})
    }


def _profiles(
    state: Mapping[str, torch.Tensor],
    position_ned: torch.Tensor,
    water_depth: float | torch.Tensor | None,
) -> tuple[torch.Tensor, torch.Tensor]:
    r"""Depth profiles of the orbital velocity, horizontal and vertical, ``[*B, N]`` each.

    .. math::

        \frac{\cosh k(h - d)}{\sinh kh} = \frac{e^{-kd} + e^{-k(2h - d)}}{1 - e^{-2kh}},\qquad
        \frac{\sinh k(h - d)}{\sinh kh} = \frac{e^{-kd} - e^{-k(2h - d)}}{1 - e^{-2kh}}

    with :math:`d = \min(\max(z, 0), h)` and :math:`e^{-k(2h - d)} = e^{-2kh}/e^{-kd}` from
    :func:`seabed_factors` (taken from ``state`` if it holds them and ``water_depth`` is
    ``None``). :math:`h` is ``water_depth``, else the state's ``water_depth``; a state without
    one (a hand-made mapping) is deep water, both profiles :math:`e^{-kd}`. For
    :math:`h = \infty` the formulas give exactly :math:`e^{-kd}` too. :math:`e^{-kd}` is
    floored at the dtype's smallest normal number before the division: where it is smaller,
    :math:`e^{-2kh} \le e^{-2kd}` is exactly 0.
    """
    k = state["wave_number"]
    depth = position_ned[..., 2:3].clamp_min(0.0)
    if water_depth is None and "wave_bed_mirror" in state:
        bed = state
    elif water_depth is None and "water_depth" not in state:
        decay = torch.exp(k * -depth)
        return decay, decay
    else:
        bed = seabed_factors(state, water_depth)
    depth = torch.minimum(depth, bed["water_depth"].unsqueeze(-1))
    near = torch.exp(k * -depth)  # e^{-kd}
    # e^{-k(2h - d)}, the seabed's mirror image of the surface
    image = bed["wave_bed_mirror"] / near.clamp_min(torch.finfo(near.dtype).tiny)
    scale = bed["wave_bed_scale"]
    return (near + image) * scale, (near - image) * scale


def _dot(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Batched dot product over the last dim (a matmul: faster than ``(a * b).sum(-1)``)."""
    return small_matmul(a.unsqueeze(-2), b.unsqueeze(-1))[..., 0, 0]


def _velocity(
    state: Mapping[str, torch.Tensor],
    position_ned: torch.Tensor,
    water_depth: float | torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """North, east and down water velocity (m/s), ``[*B]`` each; no input checks (compilable).

    ``down`` is ``+0`` (never ``-0``) when there are no waves, so that a vehicle's
    :math:`w_r = w - w_c` keeps the sign of zero of :math:`w` (the hull's angle of attack
    ``atan2(w_r, u_r)`` jumps from :math:`\\pi` to :math:`-\\pi` with it when :math:`u_r < 0`).
    """
    chi = _phase(state, position_ned)
    horizontal, vertical = _profiles(state, position_ned, water_depth)
    weight = horizontal * torch.cos(chi)
    speed, direction = state["current_speed"], state["current_direction"]
    north = speed * torch.cos(direction) + _dot(weight, state["wave_un"])
    east = speed * torch.sin(direction) + _dot(weight, state["wave_ue"])
    down = 0.0 - _dot(vertical * torch.sin(chi), state["wave_ud"])  # 0 - (+-0) = +0
    return north, east, down


def _current(north: torch.Tensor, east: torch.Tensor, down: torch.Tensor) -> torch.Tensor:
    """``[speed, direction, down]``; the direction is exactly 0 for a zero horizontal vector."""
    speed = torch.sqrt(north * north + east * east)
    direction = torch.where(speed > 0, torch.atan2(east, north), torch.zeros_like(speed))
    return torch.stack((speed, direction, down), -1)


def water_velocity_at(
    state: TensorDict,
    position_ned: torch.Tensor,
    water_depth: float | torch.Tensor | None = None,
) -> torch.Tensor:
    r"""Total water velocity (current plus wave orbital) at ``position_ned``, NED, ``[*B, 3]`` m/s.

    Finite-depth linear theory (module docstring): with :math:`h` the water depth and
    :math:`d = \min(\max(z, 0), h)`,

    .. math::

        u_N + i\,u_E = V e^{i\beta} + \sum_j a_j\omega_j
        \frac{\cosh k_j(h - d)}{\sinh k_j h}\cos\chi_j\,e^{i\theta_j},\qquad
        u_D = -\sum_j a_j\omega_j \frac{\sinh k_j(h - d)}{\sinh k_j h}\sin\chi_j ,

    which is :math:`e^{-k_j d}` for both profiles in deep water.

    Args:
        state: ocean state, batch ``[*B]``.
        position_ned: positions :math:`(x, y, z)` (m, NED, :math:`z` = depth, positive down),
            ``[*B, 3]``; above the surface (:math:`z < 0`) the surface velocity applies, below
            the seabed (:math:`z > h`) the seabed velocity.
        water_depth: the *local* water depth :math:`h` (m, > 0, ``inf`` = deep) for the depth
            profiles, a float or a tensor broadcasting to ``[*B]`` (e.g. the seabed depth
            under each point); ``None`` (default) uses the state's ``water_depth`` (the
            scene's, from :func:`reset_ocean`), or deep water if it has none. The phases always
            use the state's wavenumbers (slowly varying depth, see the module docstring).

    Returns:
        :math:`(u_N, u_E, u_D)` (m/s, NED; :math:`u_D` positive down), ``[*B, 3]``.

    Raises:
        ValueError: if ``position_ned`` is not shaped ``[*B, 3]`` or ``water_depth`` is not
            > 0 or does not broadcast to ``[*B]``.

    >>> g = torch.Generator().manual_seed(0)
    >>> water_velocity_at(reset_ocean("ideal", (), generator=g), torch.zeros(3)).tolist()
    [0.0, 0.0, 0.0]
    >>> state = reset_ocean("es", (), generator=g)
    >>> deep = water_velocity_at(state, torch.tensor([0.0, 0.0, 500.0]))  # waves die out
    >>> bool((deep[:2].norm() - state["current_speed"]).abs() < 1e-4), bool(deep[2].abs() < 1e-4)
    (True, True)
    >>> shelf = reset_ocean("es", (), generator=g, water_depth=45.0)
    >>> abs(water_velocity_at(shelf, torch.tensor([0.0, 0.0, 45.0]))[2].item()) < 1e-7  # bed
    True
    """
    _check_position(state, position_ned, water_depth)
    return torch.stack(_velocity(state, position_ned, water_depth), -1)


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
    return _dot(torch.cos(_phase(state, position_ned)), state["wave_amplitude"])


def current_from_state(
    state: Mapping[str, torch.Tensor],
    position_ned: torch.Tensor,
    water_depth: torch.Tensor | None = None,
) -> torch.Tensor:
    """:func:`current_at` without input checks, for compiled inner loops.

    ``state`` may be any mapping with the entries of :func:`reset_ocean` whose shapes
    broadcast against ``position_ned`` (e.g. scene entries with a singleton vehicle dim for a
    fleet ``[*B, N, 3]``); its ``water_depth`` entry, if ``water_depth`` is not given, may
    itself be per vehicle (the local depth, ``[*B, N]``), and it may hold the
    :func:`seabed_factors` of that depth (then used as they are: one exponential per
    component per call instead of three). A mapping without ``water_depth`` is deep water.
    """
    return _current(*_velocity(state, position_ned, water_depth))


def current_at(
    state: TensorDict,
    position_ned: torch.Tensor,
    water_depth: float | torch.Tensor | None = None,
) -> torch.Tensor:
    r"""Water velocity at the vehicle as ``[speed (m/s), direction (rad), w_down (m/s)]``,
    ``[*B, 3]``.

    This is the ``current`` argument of :func:`torchrl_auv.physics.remus100.step`: the
    Gauss-Markov current plus the wave orbital velocity at the vehicle's position and depth
    (:func:`water_velocity_at`), its horizontal part as speed and direction (the one the water
    flows towards, in :math:`(-\pi, \pi]`, exactly 0 when the water is still) and its vertical
    part :math:`u_D` (positive down, ``+0`` without waves). Still water (``ideal``) gives
    exactly ``[0, 0, 0]``, with which the vehicle model is exactly the PVS model.

    Args:
        state: ocean state, batch ``[*B]``.
        position_ned: vehicle positions :math:`(x, y, z)` (m, NED, :math:`z` = depth), ``[*B, 3]``.
        water_depth: local water depth for the orbital profiles (m), as in
            :func:`water_velocity_at`; ``None`` uses the state's.

    Raises:
        ValueError: if ``position_ned`` is not shaped ``[*B, 3]`` or ``water_depth`` is not
            > 0 or does not broadcast to ``[*B]``.

    >>> g = torch.Generator().manual_seed(0)
    >>> state = reset_ocean("es", (4,), generator=g)
    >>> current_at(state, torch.tensor([[0.0, 0.0, 30.0]] * 4)).shape
    torch.Size([4, 3])
    >>> current_at(reset_ocean("ideal", (2,), generator=g), torch.zeros(2, 3)).tolist()
    [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]
    """
    _check_position(state, position_ned, water_depth)
    return _current(*_velocity(state, position_ned, water_depth))
