"""Closed-loop scenarios for the low-level controllers: step responses and the tracking table.

* :func:`simulate` runs a controller on the REMUS-100 in a sea state at 20 Hz over a setpoint
  schedule, batched over independent runs, and returns the traces.
* :func:`tracking_schedule` is the fixed 300 s evaluation sequence of depth and heading
  setpoints behind the paper's Table III layout; :data:`TUNING_SCHEDULE` is the different,
  simpler scenario the controllers' default gains were chosen on.
* :func:`tracking_errors` gives mean and standard deviation of the absolute heading error
  (rad) and the absolute depth error (m) between setpoints and the true state over all
  physics steps.

Controllers here see the true state unless an observer is passed; the environments and
:mod:`torchrl_auv.report.tracking` feed them the Kalman-filter estimate.

Documented step responses of the default gains (90 deg heading step and 2 m -> 12 m depth step
at 1200 rpm in still water, 20 Hz; settling to within 2 deg / 0.5 m; overshoot), asserted with
margins in ``tests/control``:

==========  ================  ==================  ==============  ================
controller  heading settling  heading overshoot   depth settling  depth overshoot
==========  ================  ==================  ==============  ================
s_surface   61 s              4.7 deg             64 s            0.73 m
pid         52 s              2.8 deg             21 s            0.24 m
smc         37 s              21 deg              24 s            0.00 m
==========  ================  ==================  ==============  ================
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from torchrl_auv.control.base import Controller, wrap_angle
from torchrl_auv.physics import ocean
from torchrl_auv.physics.limits import depth_limits
from torchrl_auv.physics.simulation import step_in_ocean

__all__ = [
    "TUNING_SCHEDULE",
    "Trace",
    "simulate",
    "tracking_errors",
    "tracking_schedule",
]

# (start time s, depth m, heading rad, rpm): the scenario default gains were tuned on.
TUNING_SCHEDULE = ((0.0, 5.0, math.radians(45.0), 1200.0),)


def tracking_schedule() -> tuple[tuple[float, float, float, float], ...]:
    """The fixed 300 s evaluation sequence: (start time s, depth m, heading rad, rpm) rows.

    >>> len(tracking_schedule())
    6
    """
    deg = math.radians
    return (
        (0.0, 10.0, deg(90.0), 1200.0),
        (50.0, 20.0, deg(90.0), 1200.0),
        (100.0, 20.0, deg(-45.0), 1200.0),
        (150.0, 8.0, deg(-45.0), 1000.0),
        (200.0, 8.0, deg(135.0), 1400.0),
        (250.0, 15.0, deg(0.0), 1200.0),
    )


@dataclass
class Trace:
    """Closed-loop traces, time-major: ``eta``/``nu`` ``[T, *B, 6]``, ``setpoint``/``command``
    ``[T, *B, 3]``, ``time`` ``[T]`` (s)."""

    time: torch.Tensor
    eta: torch.Tensor
    nu: torch.Tensor
    setpoint: torch.Tensor
    command: torch.Tensor


def _setpoints_at(schedule, t: float, batch_shape, dtype) -> torch.Tensor:
    row = [r for r in schedule if r[0] <= t + 1e-9][-1]
    return torch.tensor(row[1:], dtype=dtype).expand(*batch_shape, 3)


def simulate(
    controller: Controller,
    schedule,
    duration: float,
    *,
    sea_state: str | ocean.SeaState = "ideal",
    batch_shape: tuple[int, ...] = (1,),
    generator: torch.Generator,
    dt: float = 0.05,
    start_depth: float = 2.0,
    start_speed: float = 1.5,
    seabed_depth: float = 100.0,
    dtype: torch.dtype = torch.float32,
    record_every: int = 1,
    observer=None,
) -> Trace:
    """Run ``controller`` on the REMUS-100 over ``schedule`` for ``duration`` s.

    The controller sees the true state unless an ``observer`` is given: a callable
    ``observer(eta, nu, step_index) -> (eta_hat, nu_hat)`` called every physics step with the
    true state (e.g. sensors plus a Kalman filter, see :mod:`torchrl_auv.report.tracking`).

    >>> from torchrl_auv.control import make_controller
    >>> trace = simulate(make_controller("pid"), TUNING_SCHEDULE, 2.0,
    ...                  generator=torch.Generator().manual_seed(0))
    >>> trace.eta.shape
    torch.Size([41, 1, 6])
    """
    if duration <= 0:
        raise ValueError(f"duration must be > 0 (s), got {duration}")
    batch_shape = tuple(batch_shape)
    sea = ocean.get_sea_state(sea_state)
    eta = torch.zeros(*batch_shape, 6, dtype=dtype)
    eta[..., 2] = start_depth
    nu = torch.zeros(*batch_shape, 6, dtype=dtype)
    nu[..., 0] = start_speed
    first = _setpoints_at(schedule, 0.0, batch_shape, dtype)
    act = torch.zeros(*batch_shape, 3, dtype=dtype)
    act[..., 2] = first[..., 2]
    sea_td = ocean.reset_ocean(sea, batch_shape, generator=generator, dtype=dtype)
    memory = controller.init_memory(batch_shape, dtype=dtype)
    steps = round(duration / dt)
    times, etas, nus, sps, cmds = [0.0], [eta], [nu], [first], [torch.zeros_like(first)]
    for k in range(steps):
        setpoint = _setpoints_at(schedule, k * dt, batch_shape, dtype)
        seen = (eta, nu) if observer is None else observer(eta, nu, k)
        command, memory = controller(setpoint, *seen, memory, dt)
        sea_td = ocean.step_ocean(sea_td, sea, dt, generator=generator)
        eta, nu, act = step_in_ocean(eta, nu, act, command, sea_td, dt)
        eta, nu, _, _ = depth_limits(eta, nu, seabed_depth)
        if (k + 1) % record_every == 0:
            times.append((k + 1) * dt)
            etas.append(eta)
            nus.append(nu)
            sps.append(setpoint)
            cmds.append(command)
    return Trace(
        torch.tensor(times),
        torch.stack(etas),
        torch.stack(nus),
        torch.stack(sps),
        torch.stack(cmds),
    )


def tracking_errors(trace: Trace) -> dict[str, torch.Tensor]:
    """Mean and std over time of the absolute heading error (rad) and depth error (m), per run
    ``[*B]``.

    The first row (the initial state, before any command) is excluded.
    """
    heading = wrap_angle(trace.setpoint[1:, ..., 1] - trace.eta[1:, ..., 5]).abs()
    depth = (trace.setpoint[1:, ..., 0] - trace.eta[1:, ..., 2]).abs()
    return {
        "heading_error_mean": heading.mean(0),
        "heading_error_std": heading.std(0),
        "depth_error_mean": depth.mean(0),
        "depth_error_std": depth.std(0),
    }
