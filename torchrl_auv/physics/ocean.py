r"""Ocean disturbances: sea-state presets, a Gauss-Markov current and JONSWAP waves, batched.

The paper names three sea states (ideal, extreme, very extreme) without defining them; the values
here are the project's choices recorded in ``shared/spec/data_collection.md`` ("Disturbances").
Everything is batched over scene dims ``[*B]``, follows the requested dtype and device, and
draws randomness only from the ``torch.Generator`` passed in.

Model:

* **Current** (horizontal, NED): speed :math:`V` and direction :math:`\beta` are each a
  first-order Gauss-Markov process around their means, discretised exactly,

  .. math::

      x_{k+1} = \mu + e^{-h/T}(x_k - \mu) + \sigma\sqrt{1 - e^{-2h/T}}\,w_k,\quad
      w_k \sim \mathcal N(0, 1),

  started from the stationary distribution :math:`\mathcal N(\mu, \sigma^2)`. The mean direction
  is drawn uniformly per episode (ours).
* **Waves**: a JONSWAP spectrum :math:`S(\omega)` with :math:`\cos^2` directional spreading about
  the mean current direction (ours), sampled once per episode into ``n_frequencies x
  n_directions`` fixed components of amplitude :math:`a_j`, frequency :math:`\omega_j`, deep-water
  wavenumber :math:`k_j = \omega_j^2 / g`, direction :math:`\theta_j` and random phase
  :math:`\varphi_j`. The orbital velocity at depth :math:`d \ge 0` is

  .. math::

      u_h = \sum_j a_j \omega_j e^{-k_j d} \cos\chi_j\,[\cos\theta_j, \sin\theta_j],\quad
      \chi_j = k_j(x\cos\theta_j + y\sin\theta_j) - \omega_j t + \varphi_j .

  Frequencies are placed in equal-energy bins of the spectrum (one jittered frequency per bin),
  so the components carry the spectrum's energy: :math:`\sum_j a_j^2/2 = m_0 = H_s^2/16`.

:func:`current_at` returns what :func:`torchrl_auv.physics.remus100.step` takes: the total
horizontal water velocity at the vehicle as ``[speed, direction]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from tensordict import TensorDict

__all__ = [
    "SEA_STATES",
    "SeaState",
    "current_at",
    "get_sea_state",
    "jonswap_spectrum",
    "reset_ocean",
    "step_ocean",
    "water_velocity_at",
]

GRAVITY = 9.81


@dataclass(frozen=True)
class SeaState:
    """A sea state: current, waves and the USBL noise level that goes with them.

    Attributes:
        name: label used in logs and tables.
        current_mean: mean current speed (m/s).
        current_sigma: stationary standard deviation of the current speed (m/s).
        current_time_constant: Gauss-Markov time constant of speed and direction (s).
        current_direction_sigma: stationary standard deviation of the direction (rad, ours).
        wave_hs: significant wave height H_s (m); 0 disables waves.
        wave_tp: peak period T_p (s).
        wave_gamma: JONSWAP peak-enhancement factor.
        usbl_noise_fraction: USBL range noise as a fraction of the slant range.
        usbl_bearing_sigma: USBL bearing noise (rad).

    Examples:
        >>> calm = SeaState(name="calm", current_mean=0.2, current_sigma=0.05)
        >>> calm.wave_hs
        0.0
    """

    name: str = "custom"
    current_mean: float = 0.0
    current_sigma: float = 0.0
    current_time_constant: float = 60.0
    current_direction_sigma: float = 0.0
    wave_hs: float = 0.0
    wave_tp: float = 10.0
    wave_gamma: float = 3.3
    usbl_noise_fraction: float = 0.001
    usbl_bearing_sigma: float = math.radians(0.1)

    def __post_init__(self) -> None:
        non_negative = (
            "current_mean",
            "current_sigma",
            "current_direction_sigma",
            "wave_hs",
            "usbl_noise_fraction",
            "usbl_bearing_sigma",
        )
        for name in non_negative:
            if not getattr(self, name) >= 0:
                raise ValueError(f"SeaState.{name} must be >= 0, got {getattr(self, name)}")
        for name in ("current_time_constant", "wave_tp"):
            if not getattr(self, name) > 0:
                raise ValueError(f"SeaState.{name} must be > 0, got {getattr(self, name)}")
        if not self.wave_gamma >= 1:
            raise ValueError(f"SeaState.wave_gamma must be >= 1, got {self.wave_gamma}")


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

    >>> get_sea_state("es").current_mean
    0.5
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
        \gamma^{\exp(-(\omega-\omega_p)^2 / (2\sigma^2\omega_p^2))},\quad
        \sigma = 0.07\ (\omega \le \omega_p),\ 0.09\ (\omega > \omega_p)

    with :math:`\omega_p = 2\pi/T_p` and :math:`A` fixed numerically so that
    :math:`\int_0^\infty S\,d\omega = H_s^2/16`.

    >>> w = torch.linspace(0.05, 5.0, 20000, dtype=torch.float64)
    >>> s = jonswap_spectrum(w, 4.0, 10.0, 3.3)
    >>> round(4 * torch.trapezoid(s, w).sqrt().item(), 3)
    4.0
    """
    shape = _jonswap_shape(omega, tp, gamma)
    return shape * (hs**2 / 16.0) / _jonswap_shape_integral(tp, gamma)


def _jonswap_shape(omega: torch.Tensor, tp: float, gamma: float) -> torch.Tensor:
    wp = 2 * math.pi / tp
    omega = omega.clamp_min(1e-6)
    sigma = torch.where(omega <= wp, 0.07, 0.09)
    peak = torch.exp(-((omega - wp) ** 2) / (2 * sigma**2 * wp**2))
    return omega.pow(-5) * torch.exp(-1.25 * (wp / omega) ** 4) * gamma**peak


def _jonswap_shape_integral(tp: float, gamma: float) -> float:
    wp = 2 * math.pi / tp
    omega = torch.linspace(0.2 * wp, 12.0 * wp, 40001, dtype=torch.float64)
    return torch.trapezoid(_jonswap_shape(omega, tp, gamma), omega).item()


def _equal_energy_bins(sea: SeaState, n_frequencies: int) -> torch.Tensor:
    """Edges of ``n_frequencies`` bins of equal spectral energy (rad/s), float64."""
    wp = 2 * math.pi / sea.wave_tp
    omega = torch.linspace(0.2 * wp, 12.0 * wp, 40001, dtype=torch.float64)
    density = _jonswap_shape(omega, sea.wave_tp, sea.wave_gamma)
    cumulative = torch.cat(
        [torch.zeros(1, dtype=torch.float64), torch.cumulative_trapezoid(density, omega)]
    )
    cumulative = cumulative / cumulative[-1]
    targets = torch.linspace(0.0, 1.0, n_frequencies + 1, dtype=torch.float64)
    index = torch.searchsorted(cumulative, targets).clamp(1, omega.numel() - 1)
    lo, hi = cumulative[index - 1], cumulative[index]
    frac = ((targets - lo) / (hi - lo).clamp_min(1e-300)).clamp(0, 1)
    return omega[index - 1] + frac * (omega[index] - omega[index - 1])


def _draw_normal(shape, generator, dtype, device) -> torch.Tensor:
    return torch.randn(shape, generator=generator, dtype=dtype, device=device)


def _check_generator(generator) -> None:
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
    """Draw a new ocean for each scene: stationary current and fixed wave components.

    Returns:
        A :class:`~tensordict.TensorDict` with ``batch_size=batch_shape`` holding
        ``current_speed``, ``current_direction``, ``current_direction_mean``, ``time`` (``[*B]``)
        and ``wave_amplitude`` (m), ``wave_frequency`` (rad/s), ``wave_number`` (rad/m),
        ``wave_direction`` (rad) and ``wave_phase`` (rad), each ``[*B, n_frequencies *
        n_directions]``.

    >>> g = torch.Generator().manual_seed(0)
    >>> state = reset_ocean("es", (2,), generator=g)
    >>> state["wave_amplitude"].shape
    torch.Size([2, 100])
    """
    sea = get_sea_state(sea_state)
    _check_generator(generator)
    if n_frequencies < 1 or n_directions < 1:
        raise ValueError(
            f"n_frequencies and n_directions must be >= 1, got {n_frequencies}, {n_directions}"
        )
    batch_shape = torch.Size(batch_shape)
    kw = {"dtype": dtype, "device": device}
    n_comp = n_frequencies * n_directions

    direction_mean = (torch.rand(batch_shape, generator=generator, **kw) * 2 - 1) * math.pi
    speed = sea.current_mean + sea.current_sigma * _draw_normal(batch_shape, generator, **kw)
    direction = direction_mean + sea.current_direction_sigma * _draw_normal(
        batch_shape, generator, **kw
    )

    if sea.wave_hs > 0:
        edges = _equal_energy_bins(sea, n_frequencies).to(**kw)
        jitter = torch.rand((*batch_shape, n_frequencies), generator=generator, **kw)
        omega = edges[:-1] + jitter * (edges[1:] - edges[:-1])  # one frequency per bin
        # cos^2 spreading: directions at bin centres within +-pi/2 of the mean, weights sum to 1
        offsets = (torch.arange(n_directions, **kw) + 0.5) / n_directions * math.pi - math.pi / 2
        weights = torch.cos(offsets) ** 2
        weights = weights / weights.sum()
        m0 = sea.wave_hs**2 / 16.0
        energy = m0 / n_frequencies * weights  # per component, [n_directions]
        amplitude = torch.sqrt(2 * energy).expand(*batch_shape, n_frequencies, n_directions)
        omega = omega.unsqueeze(-1).expand(*batch_shape, n_frequencies, n_directions)
        theta = direction_mean[..., None, None] + offsets
        theta = theta.expand(*batch_shape, n_frequencies, n_directions)
    else:
        amplitude = torch.zeros((*batch_shape, n_frequencies, n_directions), **kw)
        omega = torch.ones_like(amplitude)
        theta = torch.zeros_like(amplitude)
    phase = torch.rand((*batch_shape, n_comp), generator=generator, **kw) * (2 * math.pi)
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
            "time": torch.zeros(batch_shape, **kw),
            "wave_amplitude": amplitude.contiguous(),
            "wave_frequency": omega.contiguous(),
            "wave_number": wavenumber.contiguous(),
            "wave_direction": theta.contiguous(),
            "wave_phase": phase,
            # precomputed per episode so a physics step is a handful of fused ops
            "wave_kx": (wavenumber * cos_t).contiguous(),
            "wave_ky": (wavenumber * sin_t).contiguous(),
            "wave_un": (amplitude * omega * cos_t).contiguous(),
            "wave_ue": (amplitude * omega * sin_t).contiguous(),
        },
        batch_size=batch_shape,
    )


def step_ocean(
    state: TensorDict, sea_state: str | SeaState, dt: float, *, generator: torch.Generator
) -> TensorDict:
    """Advance the current's Gauss-Markov processes and the clock by ``dt`` seconds (exact).

    Returns a new TensorDict; ``state`` is left unchanged.

    >>> g = torch.Generator().manual_seed(0)
    >>> s0 = reset_ocean("ves", (3,), generator=g)
    >>> s1 = step_ocean(s0, "ves", 0.05, generator=g)
    >>> s1["time"].tolist()
    [0.05000000074505806, 0.05000000074505806, 0.05000000074505806]
    """
    sea = get_sea_state(sea_state)
    _check_generator(generator)
    if not dt > 0:
        raise ValueError(f"dt must be > 0 (seconds), got {dt}")
    speed, direction = state["current_speed"], state["current_direction"]
    decay = math.exp(-dt / sea.current_time_constant)
    scale = math.sqrt(1 - decay**2)
    kw = {"dtype": speed.dtype, "device": speed.device}
    noise = _draw_normal((2, *speed.shape), generator, **kw)
    new_speed = (
        sea.current_mean
        + decay * (speed - sea.current_mean)
        + (sea.current_sigma * scale) * noise[0]
    )
    mean_dir = state["current_direction_mean"]
    new_direction = (
        mean_dir + decay * (direction - mean_dir) + (sea.current_direction_sigma * scale) * noise[1]
    )
    out = state.copy()
    out["current_speed"] = new_speed
    out["current_direction"] = new_direction
    out["time"] = state["time"] + dt
    return out


def _check_position(state: TensorDict, position_ned: torch.Tensor) -> None:
    if position_ned.shape[-1] != 3 or position_ned.shape[:-1] != state.batch_size:
        raise ValueError(
            f"position_ned must be shaped [*B, 3] with B = {tuple(state.batch_size)}, "
            f"got {tuple(position_ned.shape)}"
        )


def _phase_and_decay(state: TensorDict, position_ned: torch.Tensor):
    x, y = position_ned[..., 0:1], position_ned[..., 1:2]
    depth = position_ned[..., 2:3].clamp_min(0.0)
    chi = (
        state["wave_kx"] * x
        + state["wave_ky"] * y
        - state["wave_frequency"] * state["time"].unsqueeze(-1)
        + state["wave_phase"]
    )
    return chi, torch.exp(-state["wave_number"] * depth)


def _horizontal(state: TensorDict, position_ned: torch.Tensor) -> tuple[torch.Tensor, ...]:
    chi, decay = _phase_and_decay(state, position_ned)
    weight = decay * torch.cos(chi)
    speed, direction = state["current_speed"], state["current_direction"]
    north = speed * torch.cos(direction) + (weight * state["wave_un"]).sum(-1)
    east = speed * torch.sin(direction) + (weight * state["wave_ue"]).sum(-1)
    return north, east


def water_velocity_at(state: TensorDict, position_ned: torch.Tensor) -> torch.Tensor:
    """Total water velocity (current plus wave orbital) at ``position_ned``, NED, ``[*B, 3]`` m/s.

    >>> g = torch.Generator().manual_seed(0)
    >>> water_velocity_at(reset_ocean("ideal", (), generator=g), torch.zeros(3)).tolist()
    [0.0, 0.0, 0.0]
    """
    _check_position(state, position_ned)
    north, east = _horizontal(state, position_ned)
    chi, decay = _phase_and_decay(state, position_ned)
    amp_omega = state["wave_amplitude"] * state["wave_frequency"]
    down = -(amp_omega * decay * torch.sin(chi)).sum(-1)
    return torch.stack((north, east, down), -1)


def current_at(state: TensorDict, position_ned: torch.Tensor) -> torch.Tensor:
    """Horizontal water velocity at the vehicle as ``[speed (m/s), direction (rad)]``, ``[*B, 2]``.

    This is the ``current`` argument of :func:`torchrl_auv.physics.remus100.step`: the
    Gauss-Markov current plus the horizontal wave orbital velocity at the vehicle's position
    and depth (the vertical orbital part is not an input of the vehicle model).

    >>> g = torch.Generator().manual_seed(0)
    >>> state = reset_ocean("es", (4,), generator=g)
    >>> current_at(state, torch.tensor([[0.0, 0.0, 30.0]] * 4)).shape
    torch.Size([4, 2])
    """
    _check_position(state, position_ned)
    north, east = _horizontal(state, position_ned)
    return torch.stack((torch.sqrt(north * north + east * east), torch.atan2(east, north)), -1)
