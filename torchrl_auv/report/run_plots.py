"""The plots a training run leaves in its folder: its learning curve and one held-out episode.

Examples:
    >>> plot_run  # doctest: +ELLIPSIS
    <function plot_run at ...>
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import torch
from torchrl.envs.utils import ExplorationType, set_exploration_type

from torchrl_auv.report.curves import plot_learning_curve
from torchrl_auv.report.episode import plot_episode
from torchrl_auv.training import (
    demonstration_frames,
    first_stage_frames,
    first_stage_values,
    held_out_env,
)

__all__ = ["plot_run"]


def plot_run(cfg: Mapping, run_dir: str | Path, policy) -> list[Path]:
    """``learning_curve.png`` (from ``train_curve.csv``, its axis starting after the offline
    frames: the first stage's, or SAC's demonstrations) and ``eval_episode.png``: the first
    held-out scene of ``cfg.eval`` (first sea state, seed ``cfg.eval.seed``) played by
    ``policy`` with deterministic actions until its first episode ends. Returns both paths."""
    run_dir, ev = Path(run_dir), cfg["eval"]
    env = held_out_env(cfg, 1, ev["steps"])(ev["sea_states"][0], ev["seed"])
    with set_exploration_type(ExplorationType.DETERMINISTIC), torch.no_grad():
        episode = env.rollout(ev["steps"], policy, break_when_any_done=False)
    done = episode["next", "done"][0, :, 0]
    end = int(done.nonzero()[0, 0]) + 1 if done.any() else done.numel()  # its first episode
    offline = (
        first_stage_frames(first_stage_values(cfg))
        if "proposer" in cfg
        else demonstration_frames(cfg)
    )
    return [
        plot_learning_curve(
            run_dir / "train_curve.csv", run_dir / "learning_curve.png", offline_frames=offline
        ),
        plot_episode(episode[:, :end], run_dir / "eval_episode.png"),
    ]
