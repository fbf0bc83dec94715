"""The vehicle in its ocean: one REMUS-100 step driven by the current at the vehicle.

:func:`step_in_ocean` evaluates :func:`torchrl_auv.physics.ocean.current_at` at the vehicle's
position and depth (horizontal current and orbital velocity as speed and direction, plus the
vertical orbital velocity) and passes it to :func:`torchrl_auv.physics.remus100.step`.
:func:`compiled_step_in_ocean` fuses both through ``torch.compile`` (the same numbers, several
times faster after a compile of minutes; ``benchmarks/bench_physics.py`` measures it). Advance
the ocean itself with :func:`torchrl_auv.physics.ocean.step_ocean` (it draws random numbers).
"""

from __future__ import annotations

import torch
from tensordict import TensorDict

from torchrl_auv.physics import ocean, remus100
from torchrl_auv.physics.ocean.fields import _check_position
from torchrl_auv.physics.remus100.dynamics import _check_step_inputs

__all__ = ["compiled_step_in_ocean", "step_in_ocean"]


def _step_in_ocean(eta, nu, actuators, command, ocean_state, dt, params=None, water_depth=None):
    current = ocean.current_at(ocean_state, eta[..., :3], water_depth)
    return remus100.step(eta, nu, actuators, command, current, dt, params)


def step_in_ocean(
    eta: torch.Tensor,
    nu: torch.Tensor,
    actuators: torch.Tensor,
    command: torch.Tensor,
    ocean_state: TensorDict,
    dt: float,
    params: remus100.Remus100Params | None = None,
    water_depth: float | torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """One REMUS-100 step in the current (plus wave orbital velocity) at the vehicle.

    Args:
        eta, nu, actuators, command: as in :func:`torchrl_auv.physics.remus100.step`.
        ocean_state: from :func:`~torchrl_auv.physics.ocean.reset_ocean` /
            :func:`~torchrl_auv.physics.ocean.step_ocean`, batch shape ``[*B]``.
        dt: step in seconds.
        params: vehicle parameters (default REMUS-100).
        water_depth: local water depth under each vehicle (m, float or ``[*B]``) for the
            orbital-velocity profiles; ``None`` uses the ocean state's (see
            :func:`~torchrl_auv.physics.ocean.water_velocity_at`).

    >>> g = torch.Generator().manual_seed(0)
    >>> sea = ocean.reset_ocean("es", (2,), generator=g)
    >>> eta, nu, act = torch.zeros(2, 6), torch.zeros(2, 6), torch.zeros(2, 3)
    >>> cmd = torch.tensor([[0.0, 0.0, 1525.0]] * 2)
    >>> eta, nu, act = step_in_ocean(eta, nu, act, cmd, sea, 0.05)
    >>> act[:, 2].tolist()
    [76.25, 76.25]
    """
    return _step_in_ocean(eta, nu, actuators, command, ocean_state, dt, params, water_depth)


_COMPILED: dict[str, object] = {}


def compiled_step_in_ocean(
    eta: torch.Tensor,
    nu: torch.Tensor,
    actuators: torch.Tensor,
    command: torch.Tensor,
    ocean_state: TensorDict,
    dt: float,
    params: remus100.Remus100Params | None = None,
    water_depth: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """:func:`step_in_ocean` through ``torch.compile`` (inputs validated eagerly first).

    The first call per input shape compiles (a few seconds on a 2-core CPU).
    """
    _check_step_inputs(eta, nu, actuators, command, None, dt)
    if eta.shape[:-1] != ocean_state.batch_size:
        raise ValueError(
            f"ocean_state batch {tuple(ocean_state.batch_size)} must equal eta's "
            f"{tuple(eta.shape[:-1])}"
        )
    _check_position(ocean_state, eta[..., :3], water_depth)
    fn = _COMPILED.get("fn")
    if fn is None:
        fn = _COMPILED["fn"] = torch.compile(_compiled_body, fullgraph=True, dynamic=False)
    return fn(eta, nu, actuators, command, ocean_state, dt, params, water_depth)


def _compiled_body(eta, nu, actuators, command, ocean_state, dt, params=None, water_depth=None):
    current = ocean.current_from_state(ocean_state, eta[..., :3], water_depth)
    return remus100.step_unchecked(eta, nu, actuators, command, current, dt, params)
