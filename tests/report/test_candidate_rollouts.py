"""Fig. 5/6's rollouts: every candidate starts from the same scene state; the chunk decides
where the vehicle goes."""

from __future__ import annotations

import torch

from torchrl_auv.report.candidate_rollouts import roll_out_candidates
from torchrl_auv.training import make_history_env


def _make(n):
    return make_history_env("ideal", seed=3, num_envs=n, history=2, max_steps=50)


def test_the_same_chunk_goes_the_same_way_and_opposite_turns_part():
    h = 8
    chunks = torch.zeros(1, 4, 2, h, 3)  # [S, K, N, H, A]
    chunks[0, 1, :, :, 1] = 1.0  # candidate 1: turn to starboard every decision
    chunks[0, 2, :, :, 1] = -1.0  # candidate 2: to port
    chunks[0, 3, :, : h // 2, 1] = 1.0  # candidate 3: starboard, then port: the chunk's
    chunks[0, 3, :, h // 2 :, 1] = -1.0  # later actions are executed too
    twice = torch.cat([chunks, chunks], 0)  # the same candidates as a second stage
    paths = roll_out_candidates(_make, twice)
    assert paths.shape == (2, 4, h + 1, 2, 3)
    # every copy starts where the scene's vehicles are
    assert torch.equal(paths[:, :, 0], paths[:1, :1, 0].expand(2, 4, 2, 3))
    assert (paths[0, 3, -1] - paths[0, 1, -1]).norm(dim=-1).min() > 0.25  # noise: ~0.06
    # the same chunk from the same state: the same path up to the sensors' noise (cm)
    assert (paths[0] - paths[1]).norm(dim=-1).max() < 0.5
    # the vehicles moved, and opposite turns end metres apart
    assert (paths[0, 0, -1] - paths[0, 0, 0]).norm(dim=-1).min() > 5.0
    assert (paths[0, 1, -1] - paths[0, 2, -1]).norm(dim=-1).min() > 2.0
