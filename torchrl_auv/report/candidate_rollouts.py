"""The proposer's candidates rolled out through the vehicles (the paper's Fig. 5/6).

From one state of one scene, every candidate chunk of every denoising stage is executed in a
copy of that scene: the env is built with one scene per (stage, candidate), every scene's state
is overwritten with the first scene's, and scene ``(s, k)`` plays chunk ``k`` of stage ``s``
for each AUV (each AUV its own ``k``-th candidate) for the chunk's ``H`` decisions. The true
positions after each decision are returned (the vehicles, current and waves are the scene's;
the sensors' noise and the current's random walk draw anew in each copy).

Examples:
    >>> import torch
    >>> from torchrl_auv.training import make_history_env
    >>> make = lambda n: make_history_env("ideal", seed=0, num_envs=n, history=2, max_steps=20)
    >>> chunks = torch.zeros(2, 3, 2, 4, 3)  # [S, K, N, H, A]: 2 stages, 3 candidates, 2 AUVs
    >>> paths = roll_out_candidates(make, chunks)
    >>> paths.shape  # [S, K, H + 1, N, 3]
    torch.Size([2, 3, 5, 2, 3])
    >>> bool((paths[:, :, 0] == paths[0, 0, 0]).all())  # every copy starts where scene 0 did
    True
"""

from __future__ import annotations

from collections.abc import Callable

import torch
from torchrl.envs.utils import step_mdp

from torchrl_auv.envs import SIM_KEY

__all__ = ["roll_out_candidates"]


def roll_out_candidates(
    make_env: Callable[[int], object],
    chunks: torch.Tensor,
    *,
    agent_action_key=("agents", "action"),
) -> torch.Tensor:
    """True NED positions (m) ``[S, K, H + 1, N, 3]`` of ``chunks`` ``[S, K, N, H, 3]``
    (action units; stage, candidate, AUV, decision) executed from the first state of scene 0
    of ``make_env(num_scenes)`` (module docstring). Decision 0 is the start."""
    if chunks.dim() != 5:
        raise ValueError(f"chunks must be shaped [S, K, N, H, A], got {tuple(chunks.shape)}")
    stages, k, n, horizon, _ = chunks.shape
    env = make_env(stages * k)
    td = env.reset()
    td = td[:1].expand(stages * k).clone()  # every scene a copy of scene 0's state
    actions = chunks.reshape(stages * k, n, horizon, -1)
    positions = [td[SIM_KEY, "truth", "eta"][..., :3]]
    with torch.no_grad():
        for h in range(horizon):
            td.set(agent_action_key, actions[:, :, h])
            td = env.step(td)
            positions.append(td["next", SIM_KEY, "truth", "eta"][..., :3])
            td = step_mdp(td)
    return torch.stack(positions, 1).reshape(stages, k, horizon + 1, n, 3)
