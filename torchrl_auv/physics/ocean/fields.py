"""What the ocean does at a point: water velocity (current plus finite-depth orbital velocity),
surface elevation and the current the vehicle model takes (:mod:`~torchrl_auv.physics.ocean`)."""

from __future__ import annotations

from collections.abc import Mapping

import torch
from tensordict import TensorDict

from torchrl_auv.physics._ops import small_matmul
from torchrl_auv.physics.ocean.spectrum import _water_depth_tensor


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

    >>> import math
    >>> from torchrl_auv.physics.ocean import reset_ocean
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

    >>> from torchrl_auv.physics.ocean import reset_ocean
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

    >>> from torchrl_auv.physics.ocean import reset_ocean
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

    >>> from torchrl_auv.physics.ocean import reset_ocean
    >>> g = torch.Generator().manual_seed(0)
    >>> state = reset_ocean("es", (4,), generator=g)
    >>> current_at(state, torch.tensor([[0.0, 0.0, 30.0]] * 4)).shape
    torch.Size([4, 3])
    >>> current_at(reset_ocean("ideal", (2,), generator=g), torch.zeros(2, 3)).tolist()
    [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]
    """
    _check_position(state, position_ned, water_depth)
    return _current(*_velocity(state, position_ned, water_depth))
