"""Dubins paths (``iout.dubins``): closed forms by hand, and every word ending on its goal pose."""

from __future__ import annotations

import math

import torch

from torchrl_auv.iout.dubins import WORDS, dubins_lengths, dubins_points

R = 20.0


def _one(x, y, psi, gx, gy, gpsi):
    t = lambda *v: torch.tensor([v], dtype=torch.float64)  # noqa: E731
    return t(x, y), t(psi)[0], t(gx, gy), t(gpsi)[0]


def test_a_goal_straight_ahead_is_a_straight_line_and_a_u_turn_is_half_a_circle():
    start, psi, goal, gpsi = _one(0.0, 0.0, 0.0, 80.0, 0.0, 0.0)
    lengths, _ = dubins_lengths(start, psi, goal, gpsi, R)
    lsl, rsr = lengths[0, 0].tolist(), lengths[0, 1].tolist()
    assert lsl == [0.0, 80.0, 0.0] and rsr == [0.0, 80.0, 0.0]
    # turning toward +psi (L) by pi on a circle of radius R: the goal 2R to the side, reversed
    start, psi, goal, gpsi = _one(0.0, 0.0, 0.0, 0.0, 2 * R, math.pi)
    lengths, _ = dubins_lengths(start, psi, goal, gpsi, R)
    torch.testing.assert_close(
        lengths[0, 0], torch.tensor([math.pi * R, 0.0, 0.0], dtype=torch.float64)
    )
    assert lengths[0].sum(-1).min().item() == math.pi * R


def test_every_word_ends_on_its_goal_pose_along_a_continuous_path():
    g = torch.Generator().manual_seed(0)
    n = 500
    start = 200.0 * torch.rand(n, 2, generator=g, dtype=torch.float64)
    goal = 200.0 * torch.rand(n, 2, generator=g, dtype=torch.float64)
    psi = math.pi * (2 * torch.rand(n, generator=g, dtype=torch.float64) - 1)
    gpsi = math.pi * (2 * torch.rand(n, generator=g, dtype=torch.float64) - 1)
    lengths, straight = dubins_lengths(start, psi, goal, gpsi, R)
    total = lengths.sum(-1)
    ok = total.isfinite()
    assert ok[:, :2].all()  # LSL and RSR always exist
    lengths = torch.where(ok[..., None], lengths, 0.0)
    span = torch.where(ok, total, 0.0)
    along = span[..., None] * torch.linspace(0.0, 1.0, 2001, dtype=torch.float64)
    points, headings = dubins_points(start, psi, lengths, straight, R, along)
    end = points[..., -1, :] - goal[:, None]
    turned = torch.remainder(headings[..., -1] - gpsi[:, None] + math.pi, 2 * math.pi) - math.pi
    assert end.norm(dim=-1)[ok].max() < 1e-9 and turned.abs()[ok].max() < 1e-9
    first = points[..., 0, :] - start[:, None].expand(n, len(WORDS), 2)
    assert first.norm(dim=-1)[ok].max() < 1e-9
    # consecutive points are one step of arc length apart (no jumps between segments)
    steps = (points[..., 1:, :] - points[..., :-1, :]).norm(dim=-1)
    assert (steps - span[..., None] / 2000)[ok].abs().max() < 1e-4
    # no path is shorter than the straight line between the positions
    assert (total.amin(-1) >= (goal - start).norm(dim=-1) - 1e-9).all()
