"""VehicleStack: the shared per-decision loop (fleet broadcasting, compiled == eager)."""

from __future__ import annotations

import pytest
import torch

from torchrl_auv.control import make_controller
from torchrl_auv.envs.vehicles import VehicleStack
from torchrl_auv.physics import ocean


def _fleet(stack, scenes=2, auvs=3):
    eta = torch.zeros(scenes, auvs, 6)
    eta[..., 0] = torch.arange(auvs) * 40.0  # far apart: different water at each vehicle
    eta[..., 2] = 10.0
    nu = torch.zeros(scenes, auvs, 6)
    nu[..., 0] = 1.5
    act = torch.zeros(scenes, auvs, 3)
    act[..., 2] = 1200.0
    setpoint = torch.tensor([15.0, 0.5, 1300.0]).expand(scenes, auvs, 3)
    return stack.init(eta, nu, act), setpoint


def _run(stack, decisions=3, seed=0):
    g = torch.Generator().manual_seed(seed)
    vehicles, setpoint = _fleet(stack)
    sea = ocean.reset_ocean(stack.sea, (2,), generator=g)
    for _ in range(decisions):
        vehicles, sea, stats = stack.decide(vehicles, setpoint, sea, 50.0, generator=g)
    return vehicles, sea, stats


def test_a_fleet_shares_its_scene_ocean_and_matches_one_vehicle_at_a_time():
    stack = VehicleStack(ocean.get_sea_state("es"), make_controller("pid"))
    g = torch.Generator().manual_seed(0)
    vehicles, _setpoint = _fleet(stack)
    sea = ocean.reset_ocean(stack.sea, (2,), generator=g)
    # the same scene's ocean replicated per vehicle must give the same water velocity
    fleet_sea = sea.unsqueeze(1).expand(2, 3)
    current = ocean.current_from_state(
        {k: sea[k].unsqueeze(1) for k in sea.keys()}, vehicles["truth", "eta"][..., :3]
    )
    expected = ocean.current_at(fleet_sea, vehicles["truth", "eta"][..., :3])
    torch.testing.assert_close(current, expected)
    assert not torch.allclose(current[:, 0], current[:, 2])  # positions matter (waves)


def test_decision_time_and_stats():
    stack = VehicleStack(ocean.get_sea_state("ideal"), make_controller("s_surface"))
    _vehicles, sea, stats = _run(stack, decisions=2)
    torch.testing.assert_close(sea["time"], torch.full((2,), 2.0, dtype=torch.float64))
    assert (stats["steps"] == 20).all()
    assert (stats["speed_sum"] / 20 > 1.0).all() and (stats["shaft_power_sum"] > 0).all()


def test_bad_input():
    stack = VehicleStack(ocean.get_sea_state("ideal"), make_controller("pid"))
    g = torch.Generator().manual_seed(0)
    vehicles, setpoint = _fleet(stack)
    with pytest.raises(ValueError, match="seabed_depth"):
        stack.decide(vehicles, setpoint, ocean.reset_ocean("ideal", (2,), generator=g), 0.0,
                     generator=g)  # fmt: skip
    with pytest.raises(ValueError, match="prefix"):
        stack.decide(vehicles, setpoint, ocean.reset_ocean("ideal", (3,), generator=g), 50.0,
                     generator=g)  # fmt: skip
    with pytest.raises(ValueError, match="unroll"):
        VehicleStack(ocean.get_sea_state("ideal"), make_controller("pid"), unroll=3)


@pytest.mark.slow
def test_compiled_physics_matches_eager():
    sea, controller = ocean.get_sea_state("es"), make_controller("s_surface")
    eager = _run(VehicleStack(sea, controller))
    compiled = _run(VehicleStack(sea, controller, compile=True, unroll=1))
    for a, b in zip(eager, compiled, strict=True):
        for key in a.keys(True, True):
            torch.testing.assert_close(a[key], b[key], rtol=1e-4, atol=1e-4, msg=str(key))
