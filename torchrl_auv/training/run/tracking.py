"""The bookkeeping around a recipe's loop: per-batch metrics, the progress bar, the learning
curve from held-out evaluations, checkpoints on a cadence (:class:`RunTracker`).

Examples:
    >>> import torch
    >>> from tensordict import TensorDict
    >>> data = TensorDict({("next", "agents", "cost"): torch.ones(2, 3, 2, 1),
    ...                    ("next", "done"): torch.zeros(2, 3, 1, dtype=torch.bool)}, [2, 3])
    >>> batch_metrics(data)
    {'train/cost_mean': 1.0}
"""

from __future__ import annotations

import resource
import sys
import time
from collections.abc import Mapping
from pathlib import Path

import torch
import tqdm
from omegaconf import DictConfig, OmegaConf
from tensordict import TensorDictBase

from torchrl_auv.evaluation import RowWorker, evaluate
from torchrl_auv.training.env import held_out_env
from torchrl_auv.training.run.loggers import log_metrics, truncate_curve
from torchrl_auv.training.run.summary import SUMMARY_COLUMNS

__all__ = ["EPISODE_METRICS", "RunTracker", "batch_metrics", "peak_rss_mb", "progress_postfix"]


#: The env's episode metrics logged as ``train/episode_<name>`` when episodes end in a batch.
EPISODE_METRICS = ("sdr", "ssn", "collisions", "violations")


def batch_metrics(data: TensorDictBase) -> dict[str, float]:
    """``train/cost_mean`` (mean per AUV and decision of the collected batch); when
    episodes ended in it, ``train/episode_<metric>`` averaged over those episodes; with a
    candidate selector's choices in the batch (``("agents", "selector", "index")``),
    ``train/selected_rank_<i>``: the share of AUV-decisions that executed slot ``i`` of the
    selection set (``0 .. K-1`` the proposer's candidates, ``K`` the actor's own action when
    it competes); with the proposer's candidates (``("agents", "proposer", "first_actions")``),
    ``train/selected_side_<d>``: per action dimension ``d``, the mean over AUV-decisions of +1
    where the executed action is the largest of the candidates' first actions, -1 where it is
    the smallest, 0 between. A pick that does not depend on the candidates' order averages
    out near 0 (the candidates are exchangeable draws, so the slot shares cannot show this); a
    selection that consistently turns one way reads near +1 or -1 (an untrained critic's
    argmax at the start of the RL stage: 0.39-0.70 away from 0 in the heading, dimension 1,
    over four initialisations in VES); and ``train/selected_extreme_<d>``, the share of
    AUV-decisions whose executed action is the largest or the smallest of the candidates in
    dimension ``d``: ``2 / K`` for an order-blind pick, more for a selection that favours the
    candidates' extremes in whichever direction. With an anchored selection rule
    (``("agents", "selector", "anchor")``), ``train/deviation_rate``: the share of
    AUV-decisions that did not execute the anchor (the medoid)."""
    out = {"train/cost_mean": data["next", "agents", "cost"].mean().item()}
    index = data.get(("agents", "selector", "index"), None)
    if index is not None:
        slots = data["agents", "selector", "scores"].shape[-1]
        shares = torch.bincount(index.flatten(), minlength=slots).float() / index.numel()
        out.update({f"train/selected_rank_{i}": v for i, v in enumerate(shares.tolist())})
        anchor = data.get(("agents", "selector", "anchor"), None)
        if anchor is not None:  # an anchored rule: how often the critic overruled the medoid
            out["train/deviation_rate"] = (index != anchor).float().mean().item()
    first = data.get(("agents", "proposer", "first_actions"), None)
    if first is not None:
        executed = data["agents", "action"].unsqueeze(-2)
        side = (executed >= first.amax(-2, keepdim=True)).float() - (
            executed <= first.amin(-2, keepdim=True)
        ).float()
        side = side.reshape(-1, side.shape[-1])
        out.update({f"train/selected_side_{d}": v for d, v in enumerate(side.mean(0).tolist())})
        extreme = side.abs().mean(0).tolist()
        out.update({f"train/selected_extreme_{d}": v for d, v in enumerate(extreme)})
    ended = data["next", "done"][..., 0]
    if ended.any():
        for name in EPISODE_METRICS:
            value = data["next", "metrics", name][ended].float().mean().item()
            out[f"train/episode_{name}"] = value
    return out


def progress_postfix(metrics: Mapping[str, float], spec=None) -> dict[str, str]:
    """What a recipe's tqdm bar shows after each batch: the batch's cost per AUV-decision
    (reward = -cost), the SDR (Mbit) and SSN of the episodes that ended last (left out until
    one has ended), and with a Lyapunov loss lambda and the form in force.

    Examples:
        >>> progress_postfix({"train/cost_mean": 1.25})
        {'cost': '1.250'}
        >>> progress_postfix({"train/cost_mean": 1.0, "train/episode_sdr": 7.5,
        ...                   "train/episode_ssn": 4.0})
        {'cost': '1.000', 'sdr': '7.5', 'ssn': '4.0'}
    """
    out = {"cost": f"{metrics['train/cost_mean']:.3f}"}
    for name in ("sdr", "ssn"):
        if f"train/episode_{name}" in metrics:
            out[name] = f"{metrics[f'train/episode_{name}']:.1f}"
    if "train/lambda" in metrics:
        out["lambda"] = f"{metrics['train/lambda']:.2f}"
    if spec is not None:
        out["form"] = spec.form
    return out


def peak_rss_mb() -> float:
    """This process's peak resident memory so far (MB; Linux reports kB, macOS bytes)."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (1024 * 1024 if sys.platform == "darwin" else 1024)


class RunTracker:
    """The bookkeeping around a recipe's loop: a tqdm bar (frames, cost, SDR, SSN, lambda,
    form), ``time/`` metrics, logging (and ``train_curve.csv``), a checkpoint every
    ``cfg.checkpoint.every_frames`` frames and one at the end.

    ``progress`` is the run's :class:`~torchrl_auv.training.Progress` (``frames``, ``updates``);
    :meth:`~torchrl_auv.training.Run.collect` counts a batch's frames before the loop's body and
    calls :meth:`step` after it; :meth:`finish` after the loop. The evaluations use the run's envs
    (``cfg.env``, its ``history`` included).

    **Learning curves from evaluation.** With ``eval_policy`` and ``cfg.eval.every_frames``
    set, the policy is evaluated at the start (frame 0) and each time the frame count passes
    a multiple of ``every_frames``: ``cfg.eval.curve_envs`` held-out scenes of the training
    sea (seed ``cfg.eval.seed``, the same scenes every time) for ``cfg.eval.curve_steps``
    decisions, deterministic actions (:func:`evaluate`). Each metric of the summary table is
    logged as ``eval/<metric>`` and written to ``eval_curve.csv`` (``step,key,value``); the
    time it takes is logged as ``time/eval_s`` and left out of the frames/s. With
    ``cfg.eval.curve_background`` the points are evaluated in a worker process while training
    goes on (the policy pickled at the point's frame: the same numbers) and logged at their
    frame once back; a checkpoint due while one is out waits for it (a checkpoint at F holds
    every point <= F), and :meth:`finish` waits for the last.
    """

    def __init__(
        self,
        cfg: DictConfig,
        run_dir: Path,
        logger,
        progress,
        checkpoint,
        rotation,
        *,
        eval_policy=None,
    ) -> None:
        self.cfg, self.logger, self.progress = cfg, logger, progress
        self.checkpoint, self.rotation = checkpoint, rotation
        self.curve = Path(run_dir) / "train_curve.csv"
        self.eval_curve = Path(run_dir) / "eval_curve.csv"
        for curve in (self.curve, self.eval_curve):  # resumed: from the checkpoint's frames on;
            truncate_curve(curve, progress.frames or -1)  # from frame 0: a stopped start's rows
        self.bar = tqdm.tqdm(
            total=cfg.collector.total_frames, initial=progress.frames, unit="frame"
        )
        self.start = time.perf_counter()
        self.frames_at_start = self.last_saved = progress.frames
        self.eval_policy, self.eval_seconds = eval_policy, 0.0
        self.last_episode: dict[str, float] = {}  # the bar's SDR/SSN: the last ended episodes
        self.every = OmegaConf.select(cfg, "eval.every_frames", default=None) or 0
        self.worker = None  # eval.curve_background: the curve's points in a worker process
        if eval_policy is not None and self.every:
            self.evaluated_block = progress.frames // self.every
            if OmegaConf.select(cfg, "eval.curve_background", default=False):
                self.worker = RowWorker(
                    self._curve_env(),
                    cfg.env.sea_state,
                    seed=cfg.eval.seed,
                    steps=cfg.eval.curve_steps,
                )
            if progress.frames == 0:
                self.evaluate_curve()

    def rate(self) -> float:
        """Frames per second of this session (collection and updates together; the learning
        curve's evaluations left out)."""
        elapsed = max(time.perf_counter() - self.start - self.eval_seconds, 1e-9)
        return (self.progress.frames - self.frames_at_start) / elapsed

    def _curve_env(self):
        return held_out_env(self.cfg, self.cfg.eval.curve_envs, self.cfg.eval.curve_steps)

    def evaluate_curve(self) -> dict[str, float] | None:
        """One point of the learning curve (class docstring); returns its metrics, or
        ``None`` when it went to the background worker (logged once it is back)."""
        cfg, began = self.cfg, time.perf_counter()
        if self.worker is not None:
            self.worker.submit(self.progress.frames, self.eval_policy)
            self.eval_seconds += time.perf_counter() - began  # pickling the policy
            return None
        row = evaluate(
            self._curve_env(),
            {"policy": self.eval_policy},
            [cfg.env.sea_state],
            seed=cfg.eval.seed,
            steps=cfg.eval.curve_steps,
        )[0]
        seconds = time.perf_counter() - began
        self.eval_seconds += seconds
        return self._log_curve(self.progress.frames, row, seconds)

    def _log_curve(self, frames: int, row: dict, seconds: float) -> dict[str, float]:
        metrics = {f"eval/{key}": row[key] for key in SUMMARY_COLUMNS}
        metrics["time/eval_s"] = seconds
        log_metrics(self.logger, metrics, frames, curve=self.eval_curve)
        return metrics

    def _collect_curve(self, wait: bool = False) -> None:
        """Log the background points that are back (``wait``: all of them; the time spent
        waiting is left out of the frames/s)."""
        if self.worker is None:
            return
        began = time.perf_counter()
        for frames, row, seconds in self.worker.results(wait=wait):
            self._log_curve(frames, row, seconds)
        if wait:
            self.eval_seconds += time.perf_counter() - began

    def step(self, data: TensorDictBase, metrics: dict[str, float], spec=None) -> None:
        """After a batch: add the batch's metrics and the rate, log, advance the bar, save a
        checkpoint when due."""
        metrics.update(batch_metrics(data))
        metrics["time/frames_per_s"] = self.rate()
        metrics["time/elapsed_s"] = time.perf_counter() - self.start
        frames = self.progress.frames
        log_metrics(self.logger, metrics, frames, curve=self.curve)
        self.bar.update(data.numel())
        self.last_episode.update(
            {k: v for k, v in metrics.items() if k.startswith("train/episode_")}
        )
        self.bar.set_postfix(progress_postfix({**metrics, **self.last_episode}, spec))
        self._collect_curve()
        if self.eval_policy is not None and self.every:
            block = frames // self.every
            if block > self.evaluated_block:
                self.evaluated_block = block
                self.evaluate_curve()
        # a checkpoint at F holds every curve point <= F: with one still in the background
        # the save waits for the first batch after it is back
        pending = self.worker is not None and self.worker.pending
        if frames - self.last_saved >= self.cfg.checkpoint.every_frames and not pending:
            self.rotation.save(self.checkpoint, step=frames)
            self.last_saved = frames

    def finish(self, collector) -> dict[str, object]:
        """Shut the collector down, save the final checkpoint; returns the session's facts
        (frames in all and in this session, wall time, training frames/s, peak memory) for
        the summary."""
        collector.shutdown()
        self._collect_curve(wait=True)
        if self.worker is not None:
            self.worker.close()
        self.bar.close()
        self.rotation.save(self.checkpoint, step=self.progress.frames)
        return {
            "frames": self.progress.frames,
            "frames this session": self.progress.frames - self.frames_at_start,
            "wall time this session (s)": time.perf_counter() - self.start,
            "training frames/s": self.rate()
            if self.progress.frames > self.frames_at_start
            else "none trained in this session (resumed at its last frame)",
            "peak RSS (MB)": peak_rss_mb(),
        }
