"""Controllers: closed-loop step responses, boundedness in 'ves', interface and bad input."""

from __future__ import annotations

import math

import pytest
import torch

from torchrl_auv.control import make_controller, wrap_angle
from torchrl_auv.control.scenarios import simulate, tracking_errors, tracking_schedule

NAMES = ("s_surface", "pid", "smc")
# Regression bounds, not specification bounds: neither the paper nor docs/spec/ states
# step-response requirements. 90 deg heading step and 10 m depth step (2 m -> 12 m) at 1200 rpm
# in still water: (heading settling s to 2 deg, heading overshoot deg, depth settling s to
# 0.5 m, depth overshoot m). Each bound is the default gains' own measured value (the table in
# torchrl_auv/control/scenarios.py, re-measured when labelled: the same) plus a margin:
#   s_surface  measured 61 / 4.7 / 64 / 0.73  -> bound +31 % / +70 % / +25 % / +37 %
#   pid        measured 52 / 2.8 / 21 / 0.24  -> bound +35 % / +79 % / +90 % / +108 %
#   smc        measured 37 / 21 / 24 / 0.00   -> bound +35 % / +19 % / +67 % / 0.5 m absolute
# They catch regressions of the tuned controllers; they do not test the controllers' formulas
# (tests/control/test_s_surface.py checks eq. 17 against hand calculations).
BOUNDS = {
    "s_surface": (80.0, 8.0, 80.0, 1.0),
    "pid": (70.0, 5.0, 40.0, 0.5),
    "smc": (50.0, 25.0, 40.0, 0.5),
}


def _settling_time(trace_time, x, target, tol):
    outside = ((x - target).abs() > tol).nonzero()
    return 0.0 if len(outside) == 0 else trace_time[outside[-1] + 1].item()


@pytest.mark.parametrize("name", NAMES)
def test_step_response_settles_with_bounded_overshoot(name):
    schedule = ((0.0, 12.0, math.radians(90.0), 1200.0),)
    trace = simulate(
        make_controller(name),
        schedule,
        150.0,
        generator=torch.Generator().manual_seed(0),
        record_every=2,
    )
    psi, z = trace.eta[:, 0, 5], trace.eta[:, 0, 2]
    t_psi_max, over_psi_max, t_z_max, over_z_max = BOUNDS[name]
    assert _settling_time(trace.time, psi, math.pi / 2, math.radians(2)) < t_psi_max
    assert math.degrees((psi.max() - math.pi / 2).item()) < over_psi_max
    assert _settling_time(trace.time, z, 12.0, 0.5) < t_z_max
    assert (z.max() - 12.0).item() < over_z_max


@pytest.mark.slow  # minutes: kept out of the default suite's 20-minute budget
def test_all_controllers_stay_bounded_for_300_s_in_very_extreme_sea():
    """Sanity / regression bounds, not from the spec or the paper. Measured maxima over the
    three controllers: body speed 3.53 m/s (vehicle plus the 1 m/s 'ves' current and wave
    orbital velocity, its vertical part included since spec v2; was 3.29 with the horizontal
    part only; bound 3.75 = +6 %), |pitch| 20 deg (bound 45 deg), mean |depth error| 2.4 m
    (was 1.9; bound 5 m)."""
    for name in NAMES:
        trace = simulate(
            make_controller(name),
            tracking_schedule(),
            300.0,
            sea_state="ves",
            batch_shape=(4,),
            start_depth=10.0,
            generator=torch.Generator().manual_seed(1),
            record_every=20,
        )
        assert torch.isfinite(trace.eta).all() and torch.isfinite(trace.nu).all()
        assert trace.nu[..., :3].norm(dim=-1).max() < 3.75
        assert trace.eta[..., 4].abs().max() < math.radians(45)
        errors = tracking_errors(trace)
        assert (errors["depth_error_mean"] < 5.0).all(), (name, errors)


def test_commands_respect_limits_and_memory_is_not_modified():
    for name in NAMES:
        ctrl = make_controller(name)
        memory = ctrl.init_memory((8,), dtype=torch.float64)
        before = memory.clone()
        gen = torch.Generator().manual_seed(3)
        setpoint = torch.rand(8, 3, generator=gen, dtype=torch.float64) * torch.tensor(
            [50.0, 6.0, 3000.0], dtype=torch.float64
        )
        eta = torch.randn(8, 6, generator=gen, dtype=torch.float64)
        nu = torch.randn(8, 6, generator=gen, dtype=torch.float64)
        command, new_memory = ctrl(setpoint, eta, nu, memory, 0.05)
        assert (memory == before).all()
        assert command.dtype == torch.float64 and command.shape == (8, 3)
        assert (command[:, :2].abs() <= math.radians(15) + 1e-12).all()
        assert (command[:, 2] >= 0).all() and (command[:, 2] <= 1525).all()
        assert set(new_memory.keys()) == set(memory.keys())


def test_wrap_angle_range():
    angles = torch.linspace(-20, 20, 2001, dtype=torch.float64)
    wrapped = wrap_angle(angles)
    assert (wrapped > -math.pi).all() and (wrapped <= math.pi).all()
    torch.testing.assert_close(torch.sin(wrapped), torch.sin(angles))
    assert wrap_angle(torch.tensor(-math.pi)).item() == pytest.approx(math.pi)


def test_bad_input():
    with pytest.raises(ValueError, match="name"):
        make_controller("lqr")
    with pytest.raises(ValueError, match="kp_heading"):
        make_controller("pid", kp_heading=-1.0)
    with pytest.raises(ValueError, match="zeta1_heading"):
        make_controller("s_surface", zeta1_heading=-2.0)
    ctrl = make_controller("smc")
    with pytest.raises(ValueError, match="setpoint"):
        ctrl(torch.zeros(4, 2), torch.zeros(4, 6), torch.zeros(4, 6), ctrl.init_memory((4,)), 0.05)
    with pytest.raises(ValueError, match="eta"):
        ctrl(torch.zeros(4, 3), torch.zeros(3, 6), torch.zeros(4, 6), ctrl.init_memory((4,)), 0.05)
    with pytest.raises(ValueError, match="not_a_gain"):
        make_controller("pid", not_a_gain=1.0)
