"""Metrics on a scripted toy sequence computed by hand; the cost by hand and its bounds."""

from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict

from torchrl_auv.iout import METRIC_KEYS, CostWeights, IoUTConfig, TaskMetrics, task_cost


def _p_move(v: float) -> float:
    """The spec's EC moving power, in plain python."""
    force = 0.7 * 60.0 * v**2 / 2.0
    eta = -0.081 * v**3 + 0.215 * v**2 - 0.01 * v + 0.541
    return force * v / eta + 15.0


def _events(hovering, rate, completed, collision, violation, overflow, service_time, held):
    return TensorDict(
        {
            "hovering": torch.tensor(hovering),
            "rate": torch.tensor(rate, dtype=torch.float64),
            "service_time": torch.tensor(service_time, dtype=torch.float64),
            "held_distance": torch.tensor(held, dtype=torch.float64),
            "completed": torch.tensor(completed),
            "collision": torch.tensor(collision),
            "violation": torch.tensor(violation),
            "overflow": torch.tensor(overflow, dtype=torch.float64),
        },
        batch_size=[len(hovering)] if isinstance(hovering[0], list) else [],
    )


# three decisions of two AUVs: (events, speed m/s, shaft power W); events are (hovering,
# rate bit/s, completed, collision, violation, overflow, service time s, held distance m)
_TOY = [
    (
        ([False, True], [0.0, 2e5], [False, False], [False, False], [True, False], 3.0,
         [0.0, 1.0], [40.0, 10.0]),
        [2.0, 0.0],
        [100.0, 50.0],
    ),
    (  # AUV 1's service ends 0.4 s into the decision, 12 m from its node
        ([False, True], [7e4, 2e5], [False, True], [True, True], [False, False], 0.0,
         [0.0, 0.4], [30.0, 12.0]),
        [1.5, 0.0],
        [80.0, 50.0],
    ),
    (  # AUV 0's service ends 0.6 s in, 25 m from its node (outside the 18 m radius)
        ([True, False], [3e5, 0.0], [True, False], [False, False], [True, True], 2.0,
         [0.6, 0.0], [25.0, 50.0]),
        [0.0, 2.2],
        [40.0, 120.0],
    ),
]  # fmt: skip


def _expected():
    ec0 = (_p_move(2.0) + _p_move(1.5)) / 2  # AUV 0 moved in decisions 1 and 2
    ec1 = _p_move(2.2)  # AUV 1 moved in decision 3
    return {
        # Mbit delivered: rate x time in service (the 7e4 of a moving AUV is ignored)
        "sdr": 0.2 * 1.0 + 0.2 * 0.4 + 0.3 * 0.6,
        "ssn": 2,
        "services_inside": 1,  # one of the two services ended within 18 m
        "ec": (ec0 + ec1) / 2,
        "ec_with_hover": ((2 * ec0 + 105) / 3 + (ec1 + 2 * 105) / 3) / 2,
        "shaft_power": 440.0 / 6,
        "collisions": 1,  # decisions with a pair closer than 5 m
        "violations": 3,  # (AUV, decision) pairs
        "overflow": 5,
    }


def test_toy_sequence_accumulates_as_defined():
    metrics = TaskMetrics(IoUTConfig())
    acc = metrics.init((), dtype=torch.float64)
    for args, speed, shaft in _TOY:
        new = metrics.update(
            acc,
            _events(*args),
            torch.tensor(speed, dtype=torch.float64),
            torch.tensor(shaft, dtype=torch.float64),
        )
        assert int(new["decisions"]) == int(acc["decisions"]) + 1  # input accumulator untouched
        acc = new
    out = metrics.finalize(acc)
    assert set(METRIC_KEYS) <= set(out.keys())
    for key, value in _expected().items():
        assert out[key].item() == pytest.approx(value, rel=1e-12), key
    assert out["ssn"].dtype == torch.long and out["collisions"].dtype == torch.long


def test_batched_scenes_accumulate_independently():
    metrics = TaskMetrics(IoUTConfig())
    acc = metrics.init((2,), dtype=torch.float64)
    for args, speed, shaft in _TOY:
        # scene 1 is the toy, scene 2 the toy with the AUVs swapped: same metrics
        swapped = tuple(list(reversed(a)) if isinstance(a, list) else a for a in args)
        events = torch.stack([_events(*args), _events(*swapped)])
        speeds = torch.tensor([speed, speed[::-1]], dtype=torch.float64)
        shafts = torch.tensor([shaft, shaft[::-1]], dtype=torch.float64)
        acc = metrics.update(acc, events, speeds, shafts)
    out = metrics.finalize(acc)
    for key, value in _expected().items():
        torch.testing.assert_close(
            out[key].double(), torch.full((2,), float(value), dtype=torch.float64)
        )


def _random_events(shape, g, *, progress=2.0, overflow=100.0):
    return TensorDict(
        {
            "target_distance": 300 * torch.rand(shape, generator=g),
            "progress": progress * (2 * torch.rand(shape, generator=g) - 1),
            "hovering": torch.rand(shape, generator=g) < 0.3,
            "collision": torch.rand(shape, generator=g) < 0.1,
            "violation": torch.rand(shape, generator=g) < 0.1,
            "overflow": overflow * torch.rand(shape[0], generator=g),
        },
        batch_size=shape[:1],
    )


def test_cost_is_bounded_by_the_sum_of_the_weights():
    """Every term is clipped to [0, 1] before its weight, the scene terms are shared by the N
    AUVs: 0 <= c_j <= w_d + w_p + w_e + w_c + w_v + (w_b + w_o) / N, also for extreme events
    (moving away at 20 m/s, 100x the expected overflow, full buffers, 3 m/s)."""
    cfg, w = IoUTConfig(), CostWeights()
    g = torch.Generator().manual_seed(0)
    shape = (256, 2)
    events = _random_events(shape, g, progress=40.0, overflow=1e4)
    events["collision"][:8] = True
    events["violation"][:8] = True
    events["target_distance"][:8] = 1e4
    events["progress"][:8] = -40.0
    events["hovering"][:8] = False
    speed = 3.0 * torch.rand(shape, generator=g)
    speed[:8] = 3.0
    buffer = cfg.buffer_capacity * torch.rand(256, 60, generator=g)
    buffer[:8] = cfg.buffer_capacity
    cost, terms = task_cost(events, speed, buffer, torch.full((256, 60), 7.75), cfg)
    bound = w.distance + w.regress + w.energy + w.collision + w.violation
    bound += (w.waiting + w.overflow) / 2
    assert cost.shape == shape and (cost >= 0).all() and (cost <= bound + 1e-6).all()
    assert w.max_cost(2) == pytest.approx(bound)
    assert cost[:8].max().item() > 0.95 * bound  # the bound is reached by the extremes
    for key in terms.keys():
        assert (terms[key] >= 0).all(), key
    torch.testing.assert_close(sum(terms[k] for k in terms.keys()), cost)


def test_the_scene_terms_count_once_for_the_scene():
    """Summed over the AUVs (the flat layout's cost), the waiting and overflow terms equal the
    scene's w_b * fill and w_o * overflow fraction, whatever the number of AUVs."""
    g = torch.Generator().manual_seed(1)
    for n in (1, 2, 4):
        cfg = IoUTConfig(num_auvs=n)
        events = _random_events((8, n), g)
        buffer = cfg.buffer_capacity * torch.rand(8, 60, generator=g)
        rates = torch.full((8, 60), 7.75)
        _, terms = task_cost(events, torch.ones(8, n), buffer, rates, cfg)
        fill = buffer.sum(-1) / (60 * cfg.buffer_capacity)
        torch.testing.assert_close(terms["waiting"].sum(-1), CostWeights().waiting * fill)
        overflow = (events["overflow"] / (60 * 7.75)).clamp(max=1.0)
        torch.testing.assert_close(terms["overflow"].sum(-1), CostWeights().overflow * overflow)


def test_cost_terms_by_hand():
    cfg = IoUTConfig(num_sensors=12)
    w = CostWeights()
    events = TensorDict(
        {
            "target_distance": torch.tensor([[141.42135623730951, 0.0]], dtype=torch.float64),
            "progress": torch.tensor([[-1.5, 0.0]], dtype=torch.float64),
            "hovering": torch.tensor([[False, True]]),
            "collision": torch.tensor([[True, True]]),
            "violation": torch.tensor([[False, True]]),
            "overflow": torch.tensor([93.0], dtype=torch.float64),
        },
        batch_size=[1],
    )
    rates = torch.tensor([[4.0, 6.0, 9.0, 12.0] * 3], dtype=torch.float64)  # 93 packets/decision
    buffer = torch.full((1, 12), 1250.0, dtype=torch.float64)  # a quarter of the capacity
    cost, terms = task_cost(
        events, torch.tensor([[2.0, 0.0]], dtype=torch.float64), buffer, rates, cfg
    )
    shared = (w.waiting * 0.25 + w.overflow * 1.0) / 2  # split between the two AUVs
    expected0 = (
        w.distance * 0.5  # 141.42 m of a 282.84 m diagonal
        + w.regress * 1.5 / 2.0  # moved 1.5 m away in one 1 s decision, scale 2 m/s
        + w.energy * _p_move(2.0) / 500.0
        + w.collision
        + shared
    )
    expected1 = w.energy * 105.0 / 500.0 + w.collision + w.violation + shared
    torch.testing.assert_close(cost, torch.tensor([[expected0, expected1]], dtype=torch.float64))
    assert terms["regress"][0, 0].item() == pytest.approx(w.regress * 0.75)
    # moving away faster than the reference speed saturates the term at its weight
    events["progress"][0, 0] = -7.0
    _, terms = task_cost(events, torch.tensor([[2.0, 0.0]], dtype=torch.float64), buffer,
                         rates, cfg)  # fmt: skip
    assert terms["regress"][0, 0].item() == pytest.approx(w.regress)
