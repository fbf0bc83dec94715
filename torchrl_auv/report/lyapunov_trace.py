"""The Lyapunov value along evaluation episodes (the paper's Fig. 10-11).

The full framework executes, every decision and for every AUV, the candidate whose Lyapunov
value :math:`L(s, a)` is lowest (:class:`~torchrl_auv.modules.CandidateSelector`, which
writes each candidate's score :math:`-L` and the executed index). :func:`executed_lyapunov`
reads the executed candidate's :math:`L` from a rollout; :func:`lyapunov_trace` summarises it
per decision over the episodes (one per scene and AUV): mean, standard deviation and the
number of episodes still running; :func:`write_lyapunov_trace` plays a run's held-out scenes
and writes ``lyapunov_trace.csv``.

Examples:
    >>> import torch
    >>> from tensordict import TensorDict
    >>> scores = -torch.tensor([[[[1.0, 2.0]], [[3.0, 0.5]]]])  # [B=1, T=2, N=1, K=2]: -L
    >>> index = torch.tensor([[[0], [1]]])
    >>> done = torch.tensor([[[False], [True]]])
    >>> rollout = TensorDict({("agents", "selector", "scores"): scores,
    ...                       ("agents", "selector", "index"): index,
    ...                       ("next", "done"): done}, batch_size=[1, 2])
    >>> executed_lyapunov(rollout).tolist()
    [[1.0, 0.5]]
    >>> trace = lyapunov_trace(rollout)
    >>> trace["mean"].tolist(), trace["episodes"].tolist()
    ([1.0, 0.5], [1, 1])
"""

from __future__ import annotations

import csv
from collections.abc import Mapping
from pathlib import Path

import torch
from tensordict import TensorDictBase
from torchrl.envs.utils import ExplorationType, set_exploration_type

__all__ = ["executed_lyapunov", "lyapunov_trace", "write_lyapunov_trace"]

SCORES = ("agents", "selector", "scores")
INDEX = ("agents", "selector", "index")
#: each candidate's L where the selector ranks by another critic (a LyapunovFilter's)
LYAPUNOV = ("agents", "selector", "lyapunov")


def executed_lyapunov(rollout: TensorDictBase) -> torch.Tensor:
    """``L(s_t, a_t)`` of the executed candidate, ``[B * N, T]`` (scene-major), NaN after the
    scene's first ``done`` (its first episode only): from the selector's ``lyapunov`` entry
    where it has one (a filtered selection), else its scores (:math:`-L`)."""
    missing = [key for key in (SCORES, INDEX) if key not in rollout.keys(True, True)]
    if missing:
        raise KeyError(
            f"the rollout has no {missing}: roll out a policy whose last module is "
            "a CandidateSelector in mode 'lyapunov' (the diffusion_lac policy)"
        )
    index = rollout[INDEX]
    if LYAPUNOV in rollout.keys(True, True):  # a filtered selection ranks by another critic
        value = torch.gather(rollout[LYAPUNOV], -1, index[..., None])[..., 0]  # [B, T, N]
    else:
        value = -torch.gather(rollout[SCORES], -1, index[..., None])[..., 0]
    done = rollout["next", "done"][..., 0]  # [B, T]
    ended_before = (done.cumsum(-1) - done.long()) > 0  # steps after the first done
    value = torch.where(ended_before[..., None], torch.nan, value.double())
    return value.permute(0, 2, 1).reshape(-1, value.shape[1])


def lyapunov_trace(rollout: TensorDictBase) -> dict[str, torch.Tensor]:
    """Per decision: ``mean`` and ``std`` of :func:`executed_lyapunov` over the episodes still
    running and their number ``episodes`` (each ``[T]``; std 0 with one episode)."""
    value = executed_lyapunov(rollout)
    alive = value.isfinite()
    count = alive.sum(0)
    total = torch.where(alive, value, 0.0).sum(0)
    mean = total / count.clamp_min(1)
    square = torch.where(alive, (value - mean).square(), 0.0).sum(0)
    std = (square / (count - 1).clamp_min(1)).sqrt()
    nan = torch.full_like(mean, torch.nan)
    return {
        "mean": torch.where(count > 0, mean, nan),
        "std": torch.where(count > 0, std, nan),
        "episodes": count,
    }


def write_lyapunov_trace(cfg: Mapping, run_dir: str | Path, policy) -> Path:
    """Play ``cfg.eval.num_envs`` held-out scenes of the first evaluation sea state (seed
    ``cfg.eval.seed``, ``cfg.eval.steps`` decisions, deterministic) with ``policy`` and write
    ``run_dir/lyapunov_trace.csv``: ``decision, mean, std, episodes``. The proposer's noise
    draws from torch's generator seeded with ``cfg.eval.seed`` (forked: restored after), as
    the evaluation rows do: the same policy writes the same trace whatever the generator's
    state before (a resumed run's, say).
    Returns its path."""
    from torchrl_auv.training import held_out_env

    ev = cfg["eval"]
    env = held_out_env(cfg, ev["num_envs"], ev["steps"])(ev["sea_states"][0], ev["seed"])
    with (
        set_exploration_type(ExplorationType.DETERMINISTIC),
        torch.no_grad(),
        torch.random.fork_rng(),
    ):
        torch.manual_seed(ev["seed"])
        rollout = env.rollout(ev["steps"], policy, break_when_any_done=False)
    trace = lyapunov_trace(rollout)
    path = Path(run_dir) / "lyapunov_trace.csv"
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["decision", "mean", "std", "episodes"])
        for t, (m, s, n) in enumerate(
            zip(
                trace["mean"].tolist(),
                trace["std"].tolist(),
                trace["episodes"].tolist(),
                strict=True,
            )
        ):
            writer.writerow([t, m, s, n])
    return path
