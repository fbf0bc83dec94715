"""VehicleStack: the shared per-decision loop (fleet broadcasting, compiled == eager, against a
hand-written loop of the public pieces); the tracking-error sums."""

from __future__ import annotations

import dataclasses
import math

import pytest
import torch
from tensordict import TensorDict

from torchrl_auv.control import make_controller
from torchrl_auv.envs.vehicles import (
    DECISION_STATS,
    TRACKING_SUMS,
    VehicleStack,
    add_tracking_sums,
    tracking_errors,
)
from torchrl_auv.estimation import Localiser, SensorNoise, compass, depth_sensor, dvl, kf_update
from torchrl_auv.physics import ocean, remus100
from torchrl_auv.physics.energy import shaft_power
from torchrl_auv.physics.limits import depth_limits
from torchrl_auv.physics.remus100 import rotation_matrix


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
        stack.decide(
            vehicles, setpoint, ocean.reset_ocean("ideal", (2,), generator=g), 0.0, generator=g
        )
    with pytest.raises(ValueError, match="prefix"):
        stack.decide(
            vehicles, setpoint, ocean.reset_ocean("ideal", (3,), generator=g), 50.0, generator=g
        )
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


# -- decide against a hand-written loop of the public pieces --------------------------------
def _angle_error(a, b):
    """|a - b| wrapped into [0, pi] (rad)."""
    d = a - b
    return torch.atan2(torch.sin(d), torch.cos(d)).abs()


def _estimate(eta, nu, kf_mean, kf_heading):
    """What the controller must see (module docstring of vehicles.py): position and NED
    velocity from the filter, heading from the compass, roll/pitch/rates from the AHRS (true),
    body velocity = filter NED velocity rotated into the body with that attitude."""
    attitude = torch.stack((eta[..., 3], eta[..., 4], kf_heading), -1)
    rot = rotation_matrix(attitude)
    v_body = torch.einsum("...ji,...j->...i", rot, kf_mean[..., 3:])  # R^T v_ned
    return torch.cat([kf_mean[..., :3], attitude], -1), torch.cat([v_body, nu[..., 3:]], -1)


def _reference_decision(stack, vehicles, setpoint, sea_td, seabed, seed):
    """One decision as a plain loop of the public pieces, with decide's noise: two draws up
    front from a generator seeded like decide's, ocean ``[steps, 2, *S]`` then sensors
    ``[steps, *V, 5]`` (DVL xyz, depth, compass). The DVL has bottom lock at altitudes up to
    30 m (SensorNoise.dvl_range); above, the filter takes the depth reading alone (a joint
    Kalman update with H selecting the depth), the DVL's draw unused."""
    g = torch.Generator().manual_seed(seed)
    shape, scene = vehicles.batch_size, sea_td.batch_size
    steps, dt, dtype = stack.decision_steps, stack.dt, setpoint.dtype
    sea_noise = torch.randn((steps, 2, *scene), generator=g, dtype=dtype)
    sensor_noise = torch.randn((steps, *shape, 5), generator=g, dtype=dtype)
    noise, loc = SensorNoise(), Localiser(SensorNoise())
    eta, nu, act = (vehicles["truth", k] for k in ("eta", "nu", "actuators"))
    mean, cov, heading = (vehicles["kf", k] for k in ("mean", "cov", "heading"))
    memory = vehicles["controller"]
    sums = dict.fromkeys(DECISION_STATS[1:], torch.zeros(shape, dtype=dtype))
    touched = torch.zeros(shape, dtype=torch.bool)
    locked_seen = torch.zeros(shape, dtype=torch.bool)
    unlocked_seen = torch.zeros(shape, dtype=torch.bool)
    depth_h = torch.zeros(1, 6, dtype=dtype)
    depth_h[0, 2] = 1.0
    for k in range(steps):
        eta_hat, nu_hat = _estimate(eta, nu, mean, heading)
        command, memory = stack.controller(setpoint, eta_hat, nu_hat, memory, dt)
        sea_td = ocean.step_ocean(
            sea_td, stack.sea, dt, generator=None, standard_normal=sea_noise[k]
        )
        fleet_sea = sea_td  # every vehicle of a scene sees the scene's ocean
        if len(shape) > len(scene):
            fleet_sea = sea_td.unsqueeze(-1).expand(shape)
        # finite-depth scene: orbital profiles at the seabed under each vehicle (decide's doc);
        # current = [speed, direction, w_down], the vertical orbital velocity included
        local = seabed if "water_depth" in sea_td.keys() else None
        current = ocean.current_at(fleet_sea, eta[..., :3], water_depth=local)
        eta, nu, act = remus100.step(eta, nu, act, command, current, dt)
        eta, nu, surface, bed = depth_limits(eta, nu, seabed)
        touched |= surface | bed
        mean, cov = loc.predict(mean, cov, dt)
        draw = sensor_noise[k]
        heading = compass(eta[..., 5], noise.compass, None, standard_normal=draw[..., 4])
        attitude = torch.stack((eta[..., 3], eta[..., 4], heading), -1)
        velocity = dvl(nu, noise.dvl, None, standard_normal=draw[..., :3])
        depth = depth_sensor(eta[..., 2], noise.depth, None, standard_normal=draw[..., 3])
        full = loc.update_onboard(mean, cov, velocity, attitude, depth)
        depth_only = kf_update(
            mean, cov, depth[..., None], depth_h, torch.tensor([[noise.depth**2]], dtype=dtype)
        )
        locked = (seabed - eta[..., 2]) <= 30.0
        locked_seen |= locked
        unlocked_seen |= ~locked
        mean = torch.where(locked[..., None], full[0], depth_only[0])
        cov = torch.where(locked[..., None, None], full[1], depth_only[1])
        # statistics: errors setpoint vs truth; speed relative to the water the step used
        e_h = _angle_error(setpoint[..., 1], eta[..., 5])
        e_d = (setpoint[..., 0] - eta[..., 2]).abs()
        v_ned = (rotation_matrix(eta[..., 3:]) @ nu[..., :3, None])[..., 0]
        water = torch.stack(
            (
                current[..., 0] * torch.cos(current[..., 1]),
                current[..., 0] * torch.sin(current[..., 1]),
                current[..., 2],
            ),
            -1,
        )
        speed = (v_ned - water).norm(dim=-1)
        for name, value in (
            ("heading_error_sum", e_h),
            ("heading_error_sq", e_h**2),
            ("depth_error_sum", e_d),
            ("depth_error_sq", e_d**2),
            ("speed_sum", speed),
            ("shaft_power_sum", shaft_power(act[..., 2], speed)),
        ):
            sums[name] = sums[name] + value
    out = {
        ("truth", "eta"): eta,
        ("truth", "nu"): nu,
        ("truth", "actuators"): act,
        ("kf", "mean"): mean,
        ("kf", "cov"): cov,
        ("kf", "heading"): heading,
    }
    out.update({("controller", k): v for k, v in memory.items()})
    stats = {"steps": torch.full(shape, float(steps), dtype=dtype), **sums}
    return out, sea_td, stats, touched, (locked_seen, unlocked_seen)


def _scenario(shape, dtype=torch.float64):
    """Vehicles ``shape`` = [V] or [S, n] (per scene): vehicle 0 breaching the surface,
    vehicle 1 hitting a 10 m seabed, the rest cruising; all with heading and depth errors."""
    eta = torch.zeros(*shape, 6, dtype=dtype)
    eta[..., 0] = torch.arange(shape[-1], dtype=dtype) * 40.0
    eta[..., 1] = 7.0 * torch.arange(math.prod(shape), dtype=dtype).reshape(shape)
    eta[..., 2] = 10.0
    eta[..., 5] = torch.linspace(-2.0, 2.5, math.prod(shape), dtype=dtype).reshape(shape)
    eta[..., 0, 2], eta[..., 0, 4] = 0.02, 0.3  # near the surface, nose up
    eta[..., 1, 2], eta[..., 1, 4] = 9.9, -0.3  # just above a 10 m seabed, nose down
    nu = torch.zeros(*shape, 6, dtype=dtype)
    nu[..., 0] = 1.5
    act = torch.zeros(*shape, 3, dtype=dtype)
    act[..., 2] = 1200.0
    seabed = torch.full(shape, 50.0, dtype=dtype)
    seabed[..., 1] = 10.0
    setpoint = torch.stack(
        (
            torch.full(shape, 15.0, dtype=dtype),
            eta[..., 5] + 0.4,
            torch.full(shape, 1300.0, dtype=dtype),
        ),
        -1,
    )
    setpoint[..., 0, 0] = 0.0
    return eta, nu, act, seabed, setpoint


@pytest.mark.parametrize(
    ("shape", "scene", "controller", "water_depth"),
    [((3,), (3,), "pid", None), ((2, 3), (2,), "s_surface", 45.0), ((2, 3), (2,), "smc", 45.0)],
)
def test_decide_equals_a_hand_written_loop_of_the_public_pieces(
    shape, scene, controller, water_depth
):
    """float64, "es" sea, deep or finite-depth (45 m scene, local seabed 50 m / 10 m); the
    filter is offset from the truth so that a controller fed the truth instead of the
    estimate shows, and the depth clamp acts at surface and seabed."""
    stack = VehicleStack(ocean.get_sea_state("es"), make_controller(controller))
    eta, nu, act, seabed, setpoint = _scenario(shape)
    vehicles = stack.init(eta, nu, act)
    vehicles["kf", "mean"][..., :3] += torch.tensor([0.8, -0.6, 0.5], dtype=torch.float64)
    vehicles["kf", "mean"][..., 3] += 0.2
    vehicles["kf", "heading"] += 0.1
    vehicles["controller"].apply_(lambda m: m + 0.05)  # non-zero controller memory
    sea = ocean.reset_ocean(
        stack.sea,
        scene,
        generator=torch.Generator().manual_seed(1),
        dtype=torch.float64,
        water_depth=water_depth,
    )
    before = vehicles.clone()
    got, got_sea, got_stats = stack.decide(
        vehicles, setpoint, sea, seabed, generator=torch.Generator().manual_seed(7)
    )
    want, want_sea, want_stats, touched, (locked, unlocked) = _reference_decision(
        stack, before, setpoint, sea, seabed, seed=7
    )
    assert touched[..., 0].all() and touched[..., 1].all()  # the depth clamp is exercised
    # the DVL gate is exercised: bottom lock over the 10 m seabed, none 40 m above the 50 m one
    assert locked[..., 1].all() and unlocked[..., 2:].all()
    assert (vehicles == before).all()  # input left unchanged
    assert set(got.keys(True, True)) == set(want)
    for key, value in want.items():
        torch.testing.assert_close(got[key], value, rtol=1e-6, atol=1e-6, msg=str(key))
    for key in ("current_speed", "current_direction", "time"):
        torch.testing.assert_close(got_sea[key], want_sea[key], rtol=1e-6, atol=1e-6)
    assert set(got_stats.keys()) == set(DECISION_STATS) == set(want_stats)
    for key, value in want_stats.items():
        torch.testing.assert_close(got_stats[key], value, rtol=1e-6, atol=1e-6, msg=key)


def test_compiled_decide_matches_eager_at_a_small_size():
    """The compiled path (``compile=True``) on one physics step per call, two decisions of
    two steps, one vehicle breaching the surface: the same state and statistics as eager."""
    sea = ocean.get_sea_state("es")

    def run(stack):
        eta, nu, act, seabed, setpoint = (x[:1] for x in _scenario((2,), dtype=torch.float32))
        vehicles = stack.init(eta, nu, act)
        g = torch.Generator().manual_seed(3)
        sea_td = ocean.reset_ocean(sea, (1,), generator=g)
        out = []
        for _ in range(2):
            vehicles, sea_td, stats = stack.decide(vehicles, setpoint, sea_td, seabed, generator=g)
            out.append((vehicles, sea_td, stats))
        return out

    controller = make_controller("s_surface")
    graphs = torch._dynamo.utils.counters["stats"]["unique_graphs"]
    compiled = run(VehicleStack(sea, controller, decision_steps=2, compile=True, unroll=1))
    # "one compilation per batch shape, sea state and controller" (VehicleStack's docstring):
    # four calls, one graph (a recompile on the second call used to triple the compile time)
    assert torch._dynamo.utils.counters["stats"]["unique_graphs"] - graphs <= 1
    eager = run(VehicleStack(sea, controller, decision_steps=2, unroll=1))
    for a_all, b_all in zip(eager, compiled, strict=True):
        for a, b in zip(a_all, b_all, strict=True):
            assert set(a.keys(True, True)) == set(b.keys(True, True))
            for key in a.keys(True, True):
                torch.testing.assert_close(a[key], b[key], rtol=1e-5, atol=1e-5, msg=str(key))


# -- running tracking sums and their mean / std ------------------------------------------------
def _sums(heading_errors, depth_errors):
    """TRACKING_SUMS of per-step errors ``[V, steps]`` written out by hand."""
    h, d = torch.tensor(heading_errors), torch.tensor(depth_errors)
    return TensorDict(
        {
            "steps": torch.full((h.shape[0],), float(h.shape[1])),
            "heading_error_sum": h.sum(-1),
            "heading_error_sq": (h * h).sum(-1),
            "depth_error_sum": d.sum(-1),
            "depth_error_sq": (d * d).sum(-1),
            "speed_sum": torch.ones(h.shape[0]),
        },
        batch_size=[h.shape[0]],
    )


def test_tracking_errors_are_the_mean_and_std_of_the_summed_errors():
    # two decisions of two vehicles; the episode's errors are their concatenation
    first = ([[0.1, 0.2, 0.3], [0.0, 0.0, 0.0]], [[1.0, 2.0, 3.0], [0.5, 0.5, 0.5]])
    second = ([[0.6, 0.6, 0.4], [0.2, 0.0, 0.1]], [[0.0, 4.0, 2.0], [0.5, 0.5, 0.5]])
    running = add_tracking_sums(_sums(*first), _sums(*second))
    assert set(running.keys()) == set(TRACKING_SUMS)  # speed and power are not tracked
    torch.testing.assert_close(running["steps"], torch.tensor([6.0, 6.0]))
    out = tracking_errors(running)
    for name, index in (("heading", 0), ("depth", 1)):
        errors = torch.cat([torch.tensor(first[index]), torch.tensor(second[index])], -1)
        mean = errors.mean(-1)
        std = ((errors - mean[:, None]) ** 2).mean(-1).sqrt()  # population std
        torch.testing.assert_close(out[f"{name}_error_mean"], mean)
        torch.testing.assert_close(out[f"{name}_error_std"], std, atol=1e-4, rtol=1e-4)
    # hand values: heading of vehicle 0 = [.1 .2 .3 .6 .6 .4]: mean 2.2/6, E[x^2] 1.02/6
    torch.testing.assert_close(out["heading_error_mean"][0], torch.tensor(2.2 / 6))
    want = math.sqrt(1.02 / 6 - (2.2 / 6) ** 2)
    torch.testing.assert_close(out["heading_error_std"][0], torch.tensor(want), atol=1e-4, rtol=0)
    assert out["depth_error_std"][1].item() == pytest.approx(0.0, abs=1e-3)  # constant errors
    # float32 sums of a constant 2.9 give E[x^2] - mean^2 slightly below 0: std 0, not NaN
    out = tracking_errors(_sums([[2.9] * 3], [[3.7] * 3]))
    for name in ("heading_error_std", "depth_error_std"):
        assert out[name].item() == pytest.approx(0.0, abs=1e-3), name


def test_tracking_errors_are_zero_before_the_first_step():
    zero = TensorDict({k: torch.zeros(3) for k in TRACKING_SUMS}, batch_size=[3])
    for value in tracking_errors(zero).values():
        assert torch.equal(value, torch.zeros(3))


# -- waves act on the vehicle (finite-depth orbital velocity, vertical included) -------------------
def _rms_depth_error(sea, depth, decisions=8, settle=3, n=4):
    """rms |depth setpoint - depth| (m) per vehicle over decisions ``settle..decisions`` of
    vehicles holding ``depth`` on a straight course in a 45 m deep scene."""
    stack = VehicleStack(sea, make_controller("pid"))
    g = torch.Generator().manual_seed(0)
    eta = torch.zeros(n, 6)
    eta[:, 0], eta[:, 2] = torch.arange(n) * 50.0, depth
    nu = torch.zeros(n, 6)
    nu[:, 0] = 1.5
    act = torch.zeros(n, 3)
    act[:, 2] = 1200.0
    vehicles = stack.init(eta, nu, act)
    sea_td = ocean.reset_ocean(sea, (n,), generator=g, water_depth=45.0)
    setpoint = torch.tensor([depth, 0.0, 1200.0]).expand(n, 3)
    total = torch.zeros(n)
    for k in range(decisions):
        vehicles, sea_td, stats = stack.decide(vehicles, setpoint, sea_td, 45.0, generator=g)
        if k >= settle:
            total += stats["depth_error_sq"] / stats["steps"]
    return (total / (decisions - settle)).sqrt()


def test_waves_without_current_move_a_vehicle_near_the_surface():
    """Issue [9/13] finding 7 ("waves change nothing"): ves waves and no current make a vehicle
    holding 5 m depth oscillate by about a metre (the vertical orbital velocity enters its
    relative velocity: angle of attack, hull lift, heave damping); in still water it holds
    its depth to centimetres; at 20 m the orbital flow, and the error, are smaller."""
    ves = ocean.get_sea_state("ves")
    waves = dataclasses.replace(
        ves, name="ves waves", current_mean=0.0, current_sigma=0.0, current_direction_sigma=0.0
    )
    still = dataclasses.replace(waves, name="still", wave_hs=0.0)
    calm = _rms_depth_error(still, 5.0)
    rough = _rms_depth_error(waves, 5.0)
    assert (calm < 0.05).all(), calm
    assert (rough > 0.3).all() and (rough > 10 * calm).all(), (rough, calm)
    assert rough.mean() > 1.2 * _rms_depth_error(waves, 20.0).mean()
