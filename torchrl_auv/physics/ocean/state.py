"""The ocean's random state per scene: drawn by :func:`reset_ocean` (current and wave components),
advanced by :func:`step_ocean` (the Gauss-Markov current; :mod:`~torchrl_auv.physics.ocean`,
"Current")."""

from __future__ import annotations

import math

import torch
from tensordict import TensorDict

from torchrl_auv.physics.ocean.sea_states import SeaState, _is_real, get_sea_state
from torchrl_auv.physics.ocean.spectrum import (
    GRAVITY,
    _check_water_depth,
    _inverse_cdf,
    wavenumber,
)


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
