"""Station keeping over a node and the approach geometry: the guidance laws by hand, and the
keeper holding a REMUS-100 over its node in a current in closed loop."""

from __future__ import annotations

import math

import pytest
import torch

from torchrl_auv import iout
from torchrl_auv.control import make_controller
from torchrl_auv.envs.vehicles import VehicleStack
from torchrl_auv.iout.approach import approach_direction
from torchrl_auv.physics import ocean

CFG = iout.StationKeepingConfig()
RPM_PER_MPS = 1525.0 / 2.5536  # the model's steady rpm per m/s of surge
NAN = float("nan")


def _keep(position, heading, node, current, altitude):
    t = lambda v: torch.tensor([v], dtype=torch.float64)  # noqa: E731
    out = iout.station_keeping_setpoints(
        t(position), t(heading)[0], t(node), t(current), t(altitude)[0]
    )
    return tuple(v.item() for v in out)


def test_on_station_in_still_water_the_propeller_stops_and_the_altitude_is_held():
    depth, heading, rpm = _keep([5.0, 0.0, 30.0], 0.4, [0.0, 0.0, 45.0], [0.0, 0.0], 6.0)
    # 5 m from the node (inside the 12 m dead band): nothing to do but hold 8 m altitude
    assert (depth, heading, rpm) == (pytest.approx(30.0 + 6.0 - 8.0), pytest.approx(0.4), 0.0)
    # no altimeter reading: 8 m above the node's depth
    assert _keep([5.0, 0.0, 30.0], 0.4, [0.0, 0.0, 45.0], [0.0, 0.0], NAN)[0] == 37.0


def test_in_a_current_on_station_the_bow_faces_the_flow_and_the_surge_matches_it():
    # 0.6 m/s flowing toward the south-west; on station the water velocity wanted is -c
    c = [-0.6 / math.sqrt(2), -0.6 / math.sqrt(2)]
    into = math.atan2(-c[1], -c[0])  # north-east
    depth, heading, rpm = _keep([2.0, 1.0, 37.0], into, [0.0, 0.0, 45.0], c, 8.0)
    assert depth == pytest.approx(37.0)  # 8 m above the seabed the altimeter sees
    # held still over ground, the propeller needs fewer rpm than 0.6 m/s in still water
    assert heading == pytest.approx(into) and 0.0 < rpm < RPM_PER_MPS * 0.6


@pytest.mark.parametrize("speed", [0.5, 0.65, 1.0])
def test_on_station_the_propeller_holds_the_model_still_against_the_current(speed):
    """The REMUS-100 model itself, bow into the current at the keeper's rpm, stays put; at the
    still-water rule's rpm (597 rpm per m/s) it runs upstream (its propeller sees the speed
    over ground, :func:`~torchrl_auv.physics.remus100.rpm_for_thrust`)."""
    from torchrl_auv.physics import remus100

    flow = [0.0, -speed]  # toward the west: bow east
    _, heading, rpm = _keep([1.0, 0.0, 37.0], math.pi / 2, [0.0, 0.0, 45.0], flow, 8.0)
    rpms = torch.tensor([rpm, RPM_PER_MPS * speed], dtype=torch.float64)
    eta = torch.zeros(2, 6, dtype=torch.float64)
    eta[:, 2], eta[:, 5] = 30.0, heading
    nu, act = torch.zeros(2, 6, dtype=torch.float64), torch.zeros(2, 3, dtype=torch.float64)
    act[:, 2] = rpms
    current = torch.tensor([[speed, -math.pi / 2]] * 2, dtype=torch.float64)
    for _ in range(4000):  # 200 s
        eta, nu, act = remus100.step(eta, nu, act, act, current, 0.05)
    assert abs(nu[0, 0].item()) < 0.1  # the keeper's rpm: (nearly) still over ground
    assert nu[1, 0].item() > 0.15  # the still-water rule: creeping upstream


def test_off_station_the_ground_velocity_wanted_points_at_the_node_capped():
    # still water, node 30 m dead ahead (north): v_d = min(0.1 * 30, 1.0) = 1 m/s north
    _, heading, rpm = _keep([-30.0, 0.0, 37.0], 0.0, [0.0, 0.0, 45.0], [0.0, 0.0], 8.0)
    assert heading == pytest.approx(0.0, abs=1e-12) and rpm == pytest.approx(RPM_PER_MPS)
    # 20 m: v_d = 2 m/s capped at 1; in a 1 m/s current toward the west, w = (1, 0) - (0, -1)
    # = (1, 1) is 45 deg off upstream (east): the crab limit (40 deg) keeps the upstream part 1
    # and cuts the cross-flow part to tan(40 deg) -> w = (tan 40, 1)
    cross = math.tan(math.radians(CFG.max_crab_deg))
    want = math.atan2(1.0, cross)  # 50 deg east of north
    _, heading, rpm = _keep([-20.0, 0.0, 37.0], math.pi / 4, [0.0, 0.0, 45.0], [0.0, -1.0], 8.0)
    surge = math.hypot(1.0, cross) * math.cos(want - math.pi / 4)  # along the bow (45 deg)
    # the current carries part of the way: fewer rpm than that surge in still water
    assert heading == pytest.approx(want) and 0.0 < rpm < RPM_PER_MPS * surge
    # a wider crab limit lets w = (1, 1) through unchanged
    wide = iout.StationKeepingConfig(max_crab_deg=60.0)
    t = lambda v: torch.tensor([v], dtype=torch.float64)  # noqa: E731
    _, heading, rpm = iout.station_keeping_setpoints(
        t([-20.0, 0.0, 37.0]), t(math.pi / 4), t([0.0, 0.0, 45.0]), t([0.0, -1.0]), t(8.0), wide
    )
    assert heading.item() == pytest.approx(math.pi / 4)
    assert 0.0 < rpm.item() < RPM_PER_MPS * 2**0.5
    # the bow 50 deg off the water velocity wanted: turning at turn_rpm
    _, _, rpm = _keep([-20.0, 0.0, 37.0], want + 0.87, [0.0, 0.0, 45.0], [0.0, -1.0], 8.0)
    assert rpm == CFG.turn_rpm


def test_in_a_current_a_node_downstream_is_reached_by_slowing_not_by_turning_round():
    # 0.6 m/s toward the north, bow south (upstream), node 20 m north (downstream): v_d = 1 m/s
    # north, w = v_d - c = 0.4 m/s north would need a U-turn; its upstream part is clamped to
    # 0 -> |w| = 0: the propeller stops, the bow stays upstream and the current carries the
    # vehicle back
    _, heading, rpm = _keep([-20.0, 0.0, 37.0], math.pi, [0.0, 0.0, 45.0], [0.6, 0.0], 8.0)
    assert rpm == 0.0 and heading == pytest.approx(math.pi)
    # the node 30 m west in a 1 m/s northward flow: w = (0, -1) - (1, 0) = (-1, -1), 45 deg
    # off upstream (south); the limit turns it to (-1, -tan 40): 40 deg west of south
    _, heading, rpm = _keep([0.0, 30.0, 37.0], math.pi, [0.0, 0.0, 45.0], [1.0, 0.0], 8.0)
    cross = math.tan(math.radians(CFG.max_crab_deg))
    assert heading == pytest.approx(math.atan2(-cross, -1.0)) and rpm > 0


def test_in_still_water_a_node_behind_the_bow_is_left_behind():
    """Turning round would take the vehicle out on a 20 m circle: it coasts instead."""
    _, heading, rpm = _keep([20.0, 0.0, 37.0], 0.0, [0.0, 0.0, 45.0], [0.0, 0.0], 8.0)
    assert rpm == 0.0 and heading == 0.0


def test_the_approach_comes_from_behind_the_node():
    up = torch.tensor([[-1.0, 0.0]])  # arrive heading south: come from the north
    # in the cone behind the node: straight for it
    d, cone = approach_direction(torch.tensor([[40.0, 10.0]]), up, offset_m=35.0)
    torch.testing.assert_close(d, -torch.tensor([[40.0, 10.0]]) / math.hypot(40.0, 10.0))
    assert cone.item()
    # in front of it (south), far: for the point 35 m behind it (north)
    d, cone = approach_direction(torch.tensor([[-80.0, 60.0]]), up, offset_m=35.0)
    want = torch.tensor([[35.0 + 80.0, -60.0]])
    torch.testing.assert_close(d, want / want.norm())
    assert not cone.item()
    # close, with the node between it and the approach point: round it, never inward
    offset = torch.tensor([[-20.0, 5.0]])
    d, _ = approach_direction(offset, up, offset_m=35.0, avoid_radius_m=45.0)
    assert (d * offset).sum().item() > 0  # moving away from the node while going round
    # a wider cone for a vehicle already facing the arrival direction
    offset = torch.tensor([[30.0, 30.0]])  # 45 deg off the line: outside a 30 deg cone
    _, narrow = approach_direction(offset, up, offset_m=35.0, cone_deg=30.0)
    _, wide = approach_direction(offset, up, offset_m=35.0, cone_deg=30.0, bow=up)
    assert not narrow.item() and wide.item()


def test_the_expert_comes_from_downstream_and_never_heads_out_near_an_edge():
    cfg = iout.ExpertConfig()
    pose = torch.zeros(1, 2, 6)
    pose[0, :, :2] = torch.tensor([[160.0, 100.0], [60.0, 100.0]])  # north / south of the node
    pose[0, :, 2] = 37.0
    target = torch.tensor([[[100.0, 100.0, 45.0]] * 2])
    current = torch.tensor([[[0.6, 0.0]] * 2])  # flowing north: arrive heading south
    _, heading, _ = iout.expert_setpoints(
        pose, target, torch.full((1, 2, 1, 3), 1e4), cfg, current=current
    )
    # the northern AUV is downstream, in the cone: straight for the node (south)
    assert heading[0, 0].item() == pytest.approx(math.pi)
    # the southern one is upstream, 40 m off, heading at the node: it turns away from it
    assert heading[0, 1].item() == pytest.approx(-cfg.plan_lookahead_m / cfg.plan_radius_m)
    # 10 m from the northern edge, target beyond it to the north-east: no outward heading
    pose[0, 0, :2] = torch.tensor([190.0, 100.0])
    target[0, 0, :2] = torch.tensor([199.0, 140.0])
    edges = torch.tensor([[[190.0, 10.0, 100.0, 100.0]] * 2])
    _, heading, _ = iout.expert_setpoints(
        pose, target, torch.full((1, 2, 1, 3), 1e4), cfg, edges=edges
    )
    assert math.cos(heading[0, 0].item()) <= 1e-6  # no northward (outward) component


@pytest.mark.parametrize("bearing_deg", [0, 45, 90, 135, 180, 225, 270, 315])
def test_the_expert_reaches_the_service_radius_bow_into_the_current(bearing_deg):
    """Kinematic closed loop (2 m/s through the water, turns of 20 m radius, a 0.6 m/s
    current toward the north): from 50 m away in any direction, heading north (the way an
    AUV leaves its previous service), the planned way reaches the 16 m horizontal service
    radius bow within 60 deg of upstream (south), from inside the area."""
    cfg = iout.ExpertConfig()
    node = torch.tensor([100.0, 100.0, 45.0])
    b = math.radians(bearing_deg)
    x, y, psi = 100.0 + 50.0 * math.cos(b), 100.0 + 50.0 * math.sin(b), 0.0
    flow = torch.tensor([[[0.6, 0.0]]])
    for _ in range(400):
        pose = torch.tensor([[[x, y, 37.0, 0.0, 0.0, psi]]])
        edges = torch.tensor([[[x, 200.0 - x, y, 200.0 - y]]])
        _, heading, _ = iout.expert_setpoints(
            pose, node.expand(1, 1, 3), torch.zeros(1, 1, 0, 3), cfg, current=flow, edges=edges
        )
        turn = math.remainder(heading.item() - psi, 2 * math.pi)
        psi += max(-0.1, min(0.1, turn))  # 2 m/s on a 20 m circle: 0.1 rad/s
        x += 2.0 * math.cos(psi) + 0.6
        y += 2.0 * math.sin(psi)
        if math.hypot(x - 100.0, y - 100.0) < 16.0:
            break
    else:
        pytest.fail("never reached the node")
    assert abs(math.remainder(psi - math.pi, 2 * math.pi)) < math.radians(60), math.degrees(psi)
    assert 0.0 < x < 200.0 and 0.0 < y < 200.0


def test_the_keeper_holds_a_vehicle_that_arrives_bow_into_a_current():
    """Closed loop: REMUS-100s arriving at 1.3 m/s bow into the 0.5 m/s ``es`` current, 8 m
    above their node, stay within the 18 m service radius for a 60 s service (the longest a
    shannon-rate service lasts is 69 s)."""
    sea = ocean.get_sea_state("es")
    stack = VehicleStack(sea, make_controller("s_surface"))
    g = torch.Generator().manual_seed(0)
    b, seabed = 6, 45.0
    state = ocean.reset_ocean(sea, (b,), generator=g, water_depth=seabed)
    node = torch.tensor([0.0, 0.0, seabed])
    upstream = state["current_direction"] + math.pi
    lateral = torch.linspace(-6.0, 6.0, b)
    eta = torch.zeros(b, 6)
    eta[:, 0] = -15.0 * torch.cos(upstream) - lateral * torch.sin(upstream)
    eta[:, 1] = -15.0 * torch.sin(upstream) + lateral * torch.cos(upstream)
    eta[:, 2], eta[:, 5] = seabed - 8.0, upstream
    nu = torch.zeros(b, 6)
    nu[:, 0] = 1.3
    vehicles = stack.init(eta, nu, torch.tensor([[0.0, 0.0, 760.0]] * b))
    worst = torch.zeros(b)
    for _ in range(60):
        eta_hat, _ = stack.estimate(vehicles)
        speed, direction = state["current_speed"], state["current_direction"]
        flow = torch.stack((speed * torch.cos(direction), speed * torch.sin(direction)), -1)
        altitude = seabed - vehicles["truth", "eta"][:, 2]
        setpoint = torch.stack(
            iout.station_keeping_setpoints(
                eta_hat[:, :3], eta_hat[:, 5], node.expand(b, 3), flow, altitude
            ),
            -1,
        )
        vehicles, state, _ = stack.decide(vehicles, setpoint, state, seabed, generator=g)
        gap = (vehicles["truth", "eta"][:, :3] - node).norm(dim=-1)
        worst = torch.maximum(worst, gap)
    assert (worst < 18.0).all(), worst
