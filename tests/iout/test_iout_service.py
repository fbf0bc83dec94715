"""Service: a parked AUV holds station Q (b / C_max) / R seconds, then the node is emptied;
the last decision counts its fraction; a node is a target again once refilled above 10 %."""

from __future__ import annotations

import math

import pytest
import torch

from torchrl_auv.iout import IoUTConfig, gather_nodes, link_rate, reset_state, step


def _gen(seed: int) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


def _quiet_scene(cfg, fill: float, seed: int = 0):
    """A one-AUV scene whose nodes receive no data (rate 0) and hold ``fill`` packets."""
    state, pos = reset_state(cfg, (1,), generator=_gen(seed), dtype=torch.float64)
    state = state.clone()
    state["nodes", "rate"] = torch.zeros_like(state["nodes", "rate"])
    state["nodes", "buffer"] = torch.full_like(state["nodes", "buffer"], fill)
    return state, pos


def test_parked_auv_completes_service_after_the_hover_time():
    cfg = IoUTConfig(num_auvs=1, num_sensors=5)
    fill = 2500.0
    state, _ = _quiet_scene(cfg, fill)
    target = state["auvs", "target"].clone()
    node = gather_nodes(state["nodes", "position"], target)
    parked = node - torch.tensor([6.0, 0.0, 8.0], dtype=torch.float64)  # 10 m away (3-D)
    rate = link_rate(torch.tensor(10.0, dtype=torch.float64), cfg).item()
    hover_s = cfg.data_volume_bits * (fill / cfg.buffer_capacity) / rate  # Q (b / C) / R
    assert 20.0 < hover_s < 40.0  # 1 Mbit at about 31 kbit/s
    hover_decisions = math.ceil(hover_s / cfg.decision_dt_s)

    state, events = step(state, parked, cfg, generator=_gen(1))  # arrives: service starts
    assert events["started"].item() and not events["hovering"].item()
    assert state["auvs", "in_service"].item()
    assert abs(state["auvs", "service_remaining"].item() - hover_s) < 1e-9
    assert abs(state["auvs", "service_rate"].item() - rate) < 1e-6

    ssn, rates, times = 0, [], []
    for k in range(hover_decisions):
        state, events = step(state, parked, cfg, generator=_gen(2 + k))
        assert events["hovering"].item()
        rates.append(events["rate"].item())
        times.append(events["service_time"].item())
        ssn += int(events["completed"].sum())
        if k < hover_decisions - 1:
            assert not events["completed"].item() and state["auvs", "in_service"].item()
    assert events["completed"].item() and ssn == 1
    assert rates == [rate] * hover_decisions
    # whole decisions, then the fraction left: the times add up to the hover time exactly,
    # so the data delivered (rate x time) is the buffer's Q b / C_max
    last = hover_s - (hover_decisions - 1) * cfg.decision_dt_s
    assert times[:-1] == [1.0] * (hover_decisions - 1) and times[-1] == pytest.approx(last)
    delivered = sum(r * t for r, t in zip(rates, times, strict=True))
    assert delivered == pytest.approx(cfg.data_volume_bits * fill / cfg.buffer_capacity)
    served_node = target.item()
    assert state["nodes", "buffer"][0, served_node].item() == 0.0
    assert state["nodes", "services"][0, served_node].item() == 1
    assert state["nodes", "services"].sum().item() == 1
    assert not state["auvs", "in_service"].item()
    new_target = state["auvs", "target"].item()
    assert new_target not in (served_node, -1)  # heads for the next node


def test_a_served_node_is_a_target_again_once_refilled_above_the_threshold():
    """One node, one AUV: after its service the node is empty and no target; it becomes the
    target again the decision its buffer reaches refill_fraction * C_max (here 500 packets at
    a fixed 100 per decision: 5 decisions), and a second service counts (SSN 2 > M = 1)."""
    cfg = IoUTConfig(num_auvs=1, num_sensors=1, refill_fraction=0.1)
    state, _ = _quiet_scene(cfg, 2500.0)
    node = gather_nodes(state["nodes", "position"], state["auvs", "target"])
    parked = node - torch.tensor([6.0, 0.0, 8.0], dtype=torch.float64)
    away = parked + torch.tensor([500.0, 0.0, 0.0], dtype=torch.float64)
    services = 0
    for k in range(200):  # serve it
        state, events = step(state, parked, cfg, generator=_gen(10 + k))
        services += int(events["completed"].sum())
        if services:
            break
    assert services == 1 and state["auvs", "target"].item() == -1
    # deterministic refill: 100 packets per decision (a Poisson draw with a huge rate would
    # be random); the threshold is 500 packets
    fills = []
    for k in range(7):
        state["nodes", "buffer"] = state["nodes", "buffer"] + 100.0
        state, _ = step(state, away, cfg, generator=_gen(300 + k))
        fills.append((state["nodes", "buffer"].item(), state["auvs", "target"].item()))
    assert [t for b, t in fills if b < 500.0] == [-1] * sum(b < 500.0 for b, _ in fills)
    assert all(t == 0 for b, t in fills if b >= 500.0) and fills[-1][1] == 0
    for k in range(200):  # and serve it again
        state, events = step(state, parked, cfg, generator=_gen(400 + k))
        services += int(events["completed"].sum())
        if services == 2:
            break
    assert state["nodes", "services"].item() == 2


def test_service_starts_only_inside_the_radius_and_empties_arrivals_too():
    cfg = IoUTConfig(num_auvs=1, num_sensors=3)
    state, _ = reset_state(cfg, (1,), generator=_gen(3), dtype=torch.float64)
    node = gather_nodes(state["nodes", "position"], state["auvs", "target"])
    far = node - torch.tensor([0.0, 0.0, 18.0], dtype=torch.float64)  # exactly 18 m: not < 18
    state, events = step(state, far, cfg, generator=_gen(4))
    assert not events["started"].item()
    near = node - torch.tensor([0.0, 0.0, 17.9], dtype=torch.float64)
    state, events = step(state, near, cfg, generator=_gen(5))
    assert events["started"].item()
    target = state["auvs", "target"].item()
    completed = False
    for k in range(200):
        state, events = step(state, near, cfg, generator=_gen(6 + k))
        if events["completed"].item():
            completed = True
            break
        assert state["nodes", "buffer"][0, target] > 0  # arrivals keep coming while hovering
    assert completed
    assert state["nodes", "buffer"][0, target].item() == 0.0


def test_empty_buffer_service_takes_one_decision():
    cfg = IoUTConfig(num_auvs=1, num_sensors=4)
    state, _ = _quiet_scene(cfg, 0.0)
    node = gather_nodes(state["nodes", "position"], state["auvs", "target"])
    state, events = step(state, node, cfg, generator=_gen(7))
    assert events["started"].item() and state["auvs", "service_remaining"].item() == 0.0
    state, events = step(state, node, cfg, generator=_gen(8))
    assert events["hovering"].item() and events["completed"].item()


def test_step_leaves_its_input_state_unchanged_and_progress_is_measured():
    cfg = IoUTConfig()
    state, pos = reset_state(cfg, (4,), generator=_gen(9), dtype=torch.float64)
    snapshot = state.clone()
    node = gather_nodes(state["nodes", "position"], state["auvs", "target"])
    closer = pos + 0.1 * (node - pos)
    new_state, events = step(state, closer, cfg, generator=_gen(10))
    assert (state == snapshot).all()
    expected = state["auvs", "target_distance"] - (node - closer).norm(dim=-1)
    torch.testing.assert_close(events["progress"], expected)
    assert (events["progress"] > 0).all()
    assert (new_state["decision"] == 1).all()


def test_sticky_targets_option_keeps_the_target():
    cfg = IoUTConfig(retarget_every_decision=False)
    state, pos = reset_state(cfg, (8,), generator=_gen(11))
    first = state["auvs", "target"]
    g = _gen(12)
    for _ in range(5):  # drift sideways, far above the seabed nodes: no service starts
        pos = pos + torch.tensor([3.0, -2.0, 0.1])
        state, events = step(state, pos, cfg, generator=g)
        assert not events["started"].any()
    assert torch.equal(state["auvs", "target"], first)


def test_the_delivery_age_starts_full_resets_while_delivering_and_grows_otherwise():
    """Task v3: the age of an AUV's last delivery is the age scale at reset (nothing
    delivered yet), 0 after every decision with time in service, one more otherwise."""
    cfg = IoUTConfig(num_auvs=1, num_sensors=5)
    state, far = _quiet_scene(cfg, 2500.0)
    assert state["auvs", "delivery_age"].item() == pytest.approx(cfg.age_scale)
    node = gather_nodes(state["nodes", "position"], state["auvs", "target"])
    parked = node - torch.tensor([6.0, 0.0, 8.0], dtype=torch.float64)
    ages = []
    for k in range(3):  # away from the node: no delivery
        state, events = step(state, far, cfg, generator=_gen(10 + k))
        ages.append(events["delivery_age"].item())
    assert ages == pytest.approx([cfg.age_scale + 1, cfg.age_scale + 2, cfg.age_scale + 3])
    state, events = step(state, parked, cfg, generator=_gen(20))  # service starts: moving
    assert events["started"].item() and events["delivery_age"].item() > cfg.age_scale
    while not events["completed"].item():
        state, events = step(state, parked, cfg, generator=_gen(30))
        assert events["hovering"].item() and events["delivery_age"].item() == 0.0
    state, events = step(state, parked, cfg, generator=_gen(40))  # the next leg begins
    assert not events["hovering"].item() and events["delivery_age"].item() == 1.0
    assert torch.equal(state["auvs", "delivery_age"], events["delivery_age"])
