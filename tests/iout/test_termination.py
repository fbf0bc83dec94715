"""Episode ends (spec v2): who ends it, what ending costs, and the scene's flags."""

from __future__ import annotations

import math

import torch

from torchrl_auv.estimation import follow_fleet
from torchrl_auv.iout import IoUTConfig, ending_auvs, episode_flags, outside_area, with_termination


def test_an_auv_ends_the_episode_beyond_the_margin_or_when_it_diverges():
    cfg = IoUTConfig()
    eta = torch.zeros(4, 1, 6)
    eta[0, 0, 0] = -10.0  # 10 m out, inside a 20 m margin
    eta[1, 0, 1] = cfg.area_m[1] + 20.5  # beyond it
    eta[2, 0, 3] = math.radians(85)  # rolled over: diverged
    eta[3, 0, 2] = float("nan")
    assert outside_area(eta, cfg, 20.0)[:, 0].tolist() == [False, True, False, False]
    ending = ending_auvs(eta, torch.zeros(4, 1, 6), None, cfg, margin_m=20.0)
    assert ending[:, 0].tolist() == [False, True, True, True]


def test_ending_costs_the_terminal_cost_and_nan_becomes_it():
    cost = torch.tensor([[1.0, float("nan")], [2.0, 3.0]])
    ending = torch.tensor([[False, True], [True, False]])
    assert with_termination(cost, ending, 100.0).tolist() == [[1.0, 100.0], [102.0, 3.0]]


def test_terminated_beats_truncated_on_the_last_decision():
    ending = torch.tensor([[True, False], [False, False], [False, False]])
    steps = torch.tensor([[1000], [1000], [10]])
    terminated, truncated, done = episode_flags(ending, steps, max_steps=1000)
    assert terminated[:, 0].tolist() == [True, False, False]
    assert truncated[:, 0].tolist() == [False, True, False]
    assert done[:, 0].tolist() == [True, True, False]


def test_the_asv_moves_at_most_its_reach_toward_the_fleet_and_stays_at_the_surface():
    asv = torch.tensor([[0.0, 0.0, 0.0], [9.0, 0.0, 0.0]])
    auvs = torch.tensor([[[30.0, 40.0, 5.0], [30.0, 40.0, 9.0]], [[10.0, 0.0, 5.0]] * 2])
    moved = follow_fleet(asv, auvs, reach_m=4.0)
    torch.testing.assert_close(moved, torch.tensor([[2.4, 3.2, 0.0], [10.0, 0.0, 0.0]]))
