"""Metrics on a scripted toy sequence computed by hand; the cost by hand and its bounds."""

from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict

from torchrl_auv.iout import (
    METRIC_KEYS,
    CostWeights,
    IoUTConfig,
    TaskMetrics,
    link_rate,
    stability_cost,
    task_cost,
)


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
        (
            [False, True],
            [0.0, 2e5],
            [False, False],
            [False, False],
            [True, False],
            3.0,
            [0.0, 1.0],
            [40.0, 10.0],
        ),
        [2.0, 0.0],
        [100.0, 50.0],
    ),
    (  # AUV 1's service ends 0.4 s into the decision, 12 m from its node
        (
            [False, True],
            [7e4, 2e5],
            [False, True],
            [True, True],
            [False, False],
            0.0,
            [0.0, 0.4],
            [30.0, 12.0],
        ),
        [1.5, 0.0],
        [80.0, 50.0],
    ),
    (  # AUV 0's service ends 0.6 s in, 25 m from its node (outside the 18 m radius)
        (
            [True, False],
            [3e5, 0.0],
            [True, False],
            [False, False],
            [True, True],
            2.0,
            [0.6, 0.0],
            [25.0, 50.0],
        ),
        [0.0, 2.2],
        [40.0, 120.0],
    ),
]


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


def _random_events(shape, g):
    n = shape[-1]
    return TensorDict(
        {
            "target_distance": 300 * torch.rand(shape, generator=g),
            "progress": 4.0 * (2 * torch.rand(shape, generator=g) - 1),
            "hovering": torch.rand(shape, generator=g) < 0.3,
            "rate": 3e4 * (1 + torch.rand(shape, generator=g)),
            "service_time": torch.rand(shape, generator=g),
            "delivery_age": 1000 * torch.rand(shape, generator=g),
            "collision": torch.rand(shape, generator=g) < 0.1,
            "violation": torch.rand(shape, generator=g) < 0.1,
        },
        batch_size=shape[:1] if n else shape,
    )


def test_cost_is_bounded_by_the_sum_of_the_weights():
    """Every term is clipped to [0, 1] before its weight: 0 <= c_j <= w_m + w_e + w_c + w_v,
    also at the extremes (an age far beyond the scale, 3 m/s, collision and violation)."""
    cfg, w = IoUTConfig(), CostWeights()
    g = torch.Generator().manual_seed(0)
    shape = (256, 2)
    events = _random_events(shape, g)
    events["collision"][:8] = True
    events["violation"][:8] = True
    events["hovering"][:8] = False
    events["delivery_age"][:8] = 1e5
    speed = 3.0 * torch.rand(shape, generator=g)
    speed[:8] = 3.0
    cost, terms = task_cost(events, speed, cfg)
    bound = w.mission + w.energy + w.collision + w.violation
    assert cost.shape == shape and (cost >= 0).all() and (cost <= bound + 1e-6).all()
    assert w.max_cost() == pytest.approx(bound)
    assert cost[:8].max().item() > 0.95 * bound  # the bound is reached by the extremes
    for key in terms.keys():
        assert (terms[key] >= 0).all(), key
    torch.testing.assert_close(sum(terms[k] for k in terms.keys()), cost)


def test_cost_terms_by_hand():
    """AUV 0 delivers for the whole decision at the rate 18 m from its node, AUV 1 is on its
    way, 322.58 decisions after its last delivery (half the age scale), at 2 m/s, colliding
    and in violation."""
    cfg, w = IoUTConfig(num_sensors=12), CostWeights()
    r18 = link_rate(torch.tensor(18.0, dtype=torch.float64), cfg).item()
    r8 = link_rate(torch.tensor(8.0, dtype=torch.float64), cfg).item()
    events = TensorDict(
        {
            "hovering": torch.tensor([[True, False]]),
            "rate": torch.tensor([[r18, 0.0]], dtype=torch.float64),
            "service_time": torch.tensor([[1.0, 0.0]], dtype=torch.float64),
            "delivery_age": torch.tensor([[0.0, cfg.age_scale / 2]], dtype=torch.float64),
            "collision": torch.tensor([[False, True]]),
            "violation": torch.tensor([[False, True]]),
        },
        batch_size=[1],
    )
    cost, terms = task_cost(events, torch.tensor([[0.0, 2.0]], dtype=torch.float64), cfg)
    expected0 = w.mission * (1 - r18 / r8) + w.energy * 105.0 / 500.0
    expected1 = w.mission * 0.5 + w.energy * _p_move(2.0) / 500.0 + w.collision + w.violation
    torch.testing.assert_close(cost, torch.tensor([[expected0, expected1]], dtype=torch.float64))
    assert terms["delivery_age"][0, 0] == 0.0 and terms["undelivered"][0, 1] == 0.0
    # the last decision of a service delivers 0.4 s of it: 0.6 of the decision is undelivered
    events["service_time"][0, 0] = 0.4
    events["rate"][0, 0] = r8
    _, terms = task_cost(events, torch.tensor([[0.0, 2.0]], dtype=torch.float64), cfg)
    assert terms["undelivered"][0, 0].item() == pytest.approx(0.6 * w.mission)


def test_an_auv_that_does_not_deliver_pays_more_with_every_decision_until_the_whole_weight():
    cfg = IoUTConfig(num_auvs=1, num_sensors=1)
    ages = torch.tensor([[1.0], [100.0], [cfg.age_scale], [10 * cfg.age_scale]])
    events = TensorDict(
        {
            "hovering": torch.zeros(4, 1, dtype=torch.bool),
            "rate": torch.zeros(4, 1),
            "service_time": torch.zeros(4, 1),
            "delivery_age": ages,
            "collision": torch.zeros(4, 1, dtype=torch.bool),
            "violation": torch.zeros(4, 1, dtype=torch.bool),
        },
        batch_size=[4],
    )
    _, terms = task_cost(events, torch.zeros(4, 1), cfg)
    age = terms["delivery_age"][:, 0]
    assert (age[1:] >= age[:-1]).all() and age[0] > 0
    assert age[2].item() == pytest.approx(1.0) and age[3].item() == pytest.approx(1.0)


def test_each_auvs_cost_is_its_own():
    """What one AUV does (its delivery, speed, violation) moves no other AUV's cost."""
    cfg = IoUTConfig()
    g = torch.Generator().manual_seed(3)
    events = _random_events((64, 2), g)
    events["collision"][:] = False
    speed = 3.0 * torch.rand(64, 2, generator=g)
    cost, _ = task_cost(events, speed, cfg)
    other = events.clone()
    for key in ("hovering", "violation"):
        other[key][:, 1] = ~other[key][:, 1]
    for key in ("rate", "service_time", "delivery_age"):
        other[key][:, 1] = other[key][:, 1].flip(0)
    other_speed = speed.clone()
    other_speed[:, 1] = speed[:, 1].flip(0)
    changed, _ = task_cost(other, other_speed, cfg)
    torch.testing.assert_close(changed[:, 0], cost[:, 0])
    assert not torch.allclose(changed[:, 1], cost[:, 1])


def test_stability_cost_by_hand():
    cfg, w = IoUTConfig(), CostWeights()
    events = TensorDict(
        {
            "target_distance": torch.tensor([[0.0, cfg.area_diagonal_m / 4]]),
            "progress": torch.tensor([[0.0, -7.0]]),
            "collision": torch.tensor([[False, True]]),
            "violation": torch.tensor([[False, True]]),
        },
        batch_size=[1],
    )
    stability = stability_cost(events, cfg)
    expected = w.distance * 0.25 + w.regress * 1.0 + w.collision + w.violation
    torch.testing.assert_close(stability, torch.tensor([[0.0, expected]]))
    assert expected == pytest.approx(w.max_stability_cost() - 0.75 * w.distance)
