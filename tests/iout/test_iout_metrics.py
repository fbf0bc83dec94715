"""Metrics on a scripted toy sequence computed by hand; cost and reward."""

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


def _events(hovering, rate, completed, collision, violation, overflow):
    return TensorDict(
        {
            "hovering": torch.tensor(hovering),
            "rate": torch.tensor(rate, dtype=torch.float64),
            "completed": torch.tensor(completed),
            "collision": torch.tensor(collision),
            "violation": torch.tensor(violation),
            "overflow": torch.tensor(overflow, dtype=torch.float64),
        },
        batch_size=[len(hovering)] if isinstance(hovering[0], list) else [],
    )


# three decisions of two AUVs: (events, speed m/s, shaft power W)
_TOY = [
    (
        ([False, True], [0.0, 2e5], [False, False], [False, False], [True, False], 3.0),
        [2.0, 0.0],
        [100.0, 50.0],
    ),
    (
        ([False, True], [7e4, 2e5], [False, True], [True, True], [False, False], 0.0),
        [1.5, 0.0],
        [80.0, 50.0],
    ),
    (
        ([True, False], [3e5, 0.0], [True, False], [False, False], [True, True], 2.0),
        [0.0, 2.2],
        [40.0, 120.0],
    ),
]


def _expected():
    ec0 = (_p_move(2.0) + _p_move(1.5)) / 2  # AUV 0 moved in decisions 1 and 2
    ec1 = _p_move(2.2)  # AUV 1 moved in decision 3
    return {
        "sdr": 0.2 + 0.2 + 0.3,  # Mbit/s while hovering (the 7e4 of a moving AUV is ignored)
        "ssn": 2,
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


def test_cost_is_non_negative_and_reward_adds_the_bonus():
    cfg = IoUTConfig()
    g = torch.Generator().manual_seed(0)
    shape = (64, 2)
    events = TensorDict(
        {
            "target_distance": 300 * torch.rand(shape, generator=g),
            "progress": 4 * torch.rand(shape, generator=g) - 2,
            "hovering": torch.rand(shape, generator=g) < 0.3,
            "completed": torch.rand(shape, generator=g) < 0.2,
            "collision": torch.rand(shape, generator=g) < 0.1,
            "violation": torch.rand(shape, generator=g) < 0.1,
            "overflow": 100 * torch.rand(64, generator=g),
        },
        batch_size=[64],
    )
    speed = 2.5 * torch.rand(shape, generator=g)
    rates = torch.full((64, 60), 7.75)
    cost, reward, terms = task_cost(events, speed, rates, cfg)
    assert cost.shape == shape and (cost >= 0).all()
    for key in ("distance", "regress", "energy", "collision", "violation", "overflow"):
        assert (terms[key] >= 0).all(), key
    torch.testing.assert_close(reward, 5.0 * events["completed"].float() - cost)


def test_cost_terms_by_hand():
    cfg = IoUTConfig()
    w = CostWeights()
    events = TensorDict(
        {
            "target_distance": torch.tensor([[141.42135623730951, 0.0]], dtype=torch.float64),
            "progress": torch.tensor([[-3.0, 0.0]], dtype=torch.float64),
            "hovering": torch.tensor([[False, True]]),
            "completed": torch.tensor([[False, True]]),
            "collision": torch.tensor([[True, True]]),
            "violation": torch.tensor([[False, True]]),
            "overflow": torch.tensor([93.0], dtype=torch.float64),
        },
        batch_size=[1],
    )
    rates = torch.tensor([[4.0, 6.0, 9.0, 12.0] * 3], dtype=torch.float64)  # 93 packets/decision
    cost, reward, terms = task_cost(
        events, torch.tensor([[2.0, 0.0]], dtype=torch.float64), rates, cfg
    )
    assert terms["service_bonus"].tolist() == [[0.0, w.service_bonus]]
    assert terms["regress"][0, 0].item() == pytest.approx(w.regress * 1.5)
    expected0 = (
        w.distance * 0.5  # 141.42 m of a 282.84 m diagonal
        + w.regress * 3.0 / 2.0  # moved 3 m away in one 1 s decision, scale 2 m/s
        + w.energy * _p_move(2.0) / 500.0
        + w.collision
        + w.overflow * 1.0  # a whole decision's worth of packets overflowed
    )
    expected1 = w.energy * 105.0 / 500.0 + w.collision + w.violation + w.overflow
    torch.testing.assert_close(cost, torch.tensor([[expected0, expected1]], dtype=torch.float64))
    torch.testing.assert_close(
        reward, torch.tensor([[-expected0, w.service_bonus - expected1]], dtype=torch.float64)
    )
