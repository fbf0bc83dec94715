"""The bookkeeping every recipe repeats: start a run, per-batch metrics, the final evaluation.

The training loop itself stays in each ``recipes/<name>/train.py`` (readable top to bottom);
these helpers keep the scripts to what differs between the recipes.

Examples:
    >>> from tensordict import TensorDict
    >>> data = TensorDict({("next", "agents", "cost"): torch.ones(2, 3, 2, 1),
    ...                    ("next", "done"): torch.zeros(2, 3, 1, dtype=torch.bool)}, [2, 3])
    >>> batch_metrics(data)
    {'train/cost_mean': 1.0}
"""

from __future__ import annotations

import csv
import logging
import resource
import sys
import time
from collections.abc import Callable, Mapping
from functools import partial
from pathlib import Path

import torch
import tqdm
from omegaconf import DictConfig, OmegaConf
from tensordict import TensorDictBase
from torchrl.checkpoint import Checkpoint, CheckpointRotation

from torchrl_auv.training.checkpointing import make_checkpoint, resume_latest
from torchrl_auv.training.collectors import make_collector
from torchrl_auv.training.config import check_config, resolve_config
from torchrl_auv.training.diffusion import make_history_env
from torchrl_auv.training.evaluation import evaluate
from torchrl_auv.training.factories import make_env, make_logger, make_replay_buffer
from torchrl_auv.training.seeding import configure_threads, seed_everything
from torchrl_auv.training.summary import SUMMARY_COLUMNS, write_eval, write_summary

__all__ = [
    "EPISODE_METRICS",
    "RunTracker",
    "batch_metrics",
    "buffer_from_config",
    "close_logger",
    "collector_from_config",
    "env_from_config",
    "finish_run",
    "gradient_step",
    "log_metrics",
    "logger_from_config",
    "peak_rss_mb",
    "prepare_resume",
    "progress_postfix",
    "sac_optimisers",
    "start_run",
]

log = logging.getLogger(__name__)
#: The env's episode metrics logged as ``train/episode_<name>`` when episodes end in a batch.
EPISODE_METRICS = ("sdr", "ssn", "collisions", "violations")


def start_run(cfg: DictConfig) -> Path:
    """Check the config's values (before any work), pin threads, seed torch, create and return
    the run folder (``resume`` when set, else ``run_dir``). A ``run_dir`` that already holds
    checkpoints is refused without ``resume`` (its checkpoints would be overwritten), and a
    ``resume`` folder without checkpoints is refused too."""
    check_config(resolve_config(cfg))
    configure_threads(int(cfg.threads))
    seed_everything(int(cfg.seed))
    run_dir = Path(cfg.resume or cfg.run_dir)
    checkpoints = run_dir / "checkpoints"
    if not cfg.resume and checkpoints.is_dir() and any(checkpoints.iterdir()):
        raise ValueError(f"run_dir {run_dir} already holds a run's checkpoints; pass "
                         f"resume={run_dir} to continue it, or choose a new run_dir")  # fmt: skip
    if cfg.resume and not checkpoints.is_dir():
        raise ValueError(f"resume={run_dir} holds no checkpoints/ to continue from")
    run_dir.mkdir(parents=True, exist_ok=True)
    return run_dir


def prepare_resume(
    cfg: DictConfig, run_dir: Path, modules: dict, progress: dict, buffer=None
) -> tuple[Checkpoint, CheckpointRotation, int]:
    """The run's checkpoint: ``modules``, the ``progress`` counters, the RNG states, the
    resolved config (JSON) and, with ``cfg.checkpoint.replay_buffer``, the replay buffer. With
    ``cfg.resume`` the newest checkpoint is loaded into them; a warning names the config groups
    that differ from the stored ones. Returns ``(checkpoint, rotation, frames still to go)``."""
    if buffer is not None and cfg.checkpoint.get("replay_buffer", False):
        modules = {**modules, "replay_buffer": buffer}
    config = OmegaConf.to_container(cfg, resolve=True)
    checkpoint, rotation = make_checkpoint(run_dir, modules={**modules, "config": config},
                                           progress=progress,
                                           keep_last=cfg.checkpoint.keep_last)  # fmt: skip
    if cfg.resume:
        frames, values = resume_latest(run_dir, checkpoint, progress)
        log.info("resumed %s at %d frames", run_dir, frames)
        stored = values.get("config", {})
        changed = sorted(k for k in config if k not in ("resume", "run_dir")
                         and k in stored and stored[k] != config[k])  # fmt: skip
        if changed:
            log.warning("resumed with a config that differs from the checkpoint's in %s", changed)
    return checkpoint, rotation, cfg.collector.total_frames - progress["frames"]


def _env_factory(cfg: DictConfig, history: int) -> partial:
    """A picklable factory of the training env of ``cfg.env``, called with ``seed=``."""
    return partial(_scene_env, cfg.env.sea_state, history, num_envs=cfg.env.num_envs,
                   controller=cfg.env.controller, rate_model=cfg.env.rate_model,
                   max_steps=cfg.env.max_steps, device=cfg.device,
                   compile_physics=bool(cfg.env.get("compile_physics", False)))  # fmt: skip


def env_from_config(cfg: DictConfig, *, history: int = 0):
    """The training env of ``cfg.env`` (seed ``cfg.seed``, ``cfg.device``), with a
    ``history``-long state-action history when > 0 (the diffusion recipes)."""
    return _env_factory(cfg, history)(seed=cfg.seed)


def collector_from_config(
    cfg: DictConfig,
    policy,
    *,
    env=None,
    history: int = 0,
    total_frames: int | None = None,
    init_random_frames: int = 0,
):
    """The collector of ``cfg.collector`` (:func:`~torchrl_auv.training.make_collector`):
    ``env`` itself with one local worker, else fresh envs of ``cfg.env`` in every worker
    (worker ``i`` seeded ``cfg.seed + i``). ``total_frames`` defaults to
    ``cfg.collector.total_frames``; ``init_random_frames`` are the random frames still to go."""
    col = cfg.collector
    single = col.backend == "local" and col.num_workers == 1
    create = env if single and env is not None else _env_factory(cfg, history)
    return make_collector(
        create, policy, seed=cfg.seed, frames_per_batch=col.frames_per_batch,
        total_frames=col.total_frames if total_frames is None else total_frames,
        init_random_frames=init_random_frames, device=cfg.device,
        num_workers=col.num_workers, backend=col.backend, ray_address=col.get("ray_address"),
    )  # fmt: skip


def _scene_env(sea_state: str, history: int, **kwargs):
    """:func:`make_env`, wrapped with a ``history``-long state-action history when > 0."""
    if history:
        return make_history_env(sea_state, history=history, **kwargs)
    return make_env(sea_state, **kwargs)


def held_out_env(cfg: DictConfig, history: int, num_envs: int, steps: int) -> Callable:
    """``(sea_state, seed) -> env`` for :func:`evaluate`: ``num_envs`` scenes of ``steps``
    decisions with the run's controller, rate model and ``env.compile_physics`` (the same
    numbers as eager, about 3x faster once compiled), and a ``history``-long state-action
    history when > 0."""
    compiled = bool(cfg.env.get("compile_physics", False))

    def make(sea: str, seed: int):
        return _scene_env(sea, history, seed=seed, num_envs=num_envs, max_steps=steps,
                          controller=cfg.env.controller, rate_model=cfg.env.rate_model,
                          compile_physics=compiled)  # fmt: skip

    return make


def buffer_from_config(cfg: DictConfig, run_dir: Path):
    """The replay buffer of ``cfg.replay_buffer`` (memmap under ``run_dir/replay``)."""
    rb = cfg.replay_buffer
    return make_replay_buffer(rb.size, batch_size=rb.batch_size, storage=rb.storage,
                              scratch_dir=run_dir / "replay")  # fmt: skip


def logger_from_config(cfg: DictConfig, run_dir: Path):
    """The logger of ``cfg.logger`` (``None`` when its backend is empty); a wandb run stores
    the resolved config and joins the group ``logger.group`` (a sweep's name)."""
    lg = cfg.logger
    config = OmegaConf.to_container(cfg, resolve=True)
    return make_logger(lg.backend, run_dir, exp_name=lg.exp_name, project=lg.project,
                       offline=lg.offline, config=config, group=lg.get("group"))  # fmt: skip


def sac_optimisers(loss, optim: DictConfig) -> dict[str, torch.optim.Optimizer]:
    """Adam for a ``SACLoss``'s actor, Q ensemble and temperature (``optim.*_lr``)."""
    return {
        "actor_optim": torch.optim.Adam(loss.actor_network_params.parameters(), lr=optim.actor_lr),
        "critic_optim": torch.optim.Adam(loss.qvalue_network_params.parameters(),
                                         lr=optim.critic_lr),
        "alpha_optim": torch.optim.Adam([loss.log_alpha], lr=optim.alpha_lr),
    }  # fmt: skip


def gradient_step(loss, optimisers: Mapping[str, torch.optim.Optimizer], updater, batch):
    """One update: the sum of ``loss(batch)``'s ``loss_*`` terms backpropagated, every
    optimiser stepped, the target networks updated. Returns the loss output (detached)."""
    out = loss(batch)
    total = sum(value for key, value in out.items() if key.startswith("loss_"))
    for opt in optimisers.values():
        opt.zero_grad()
    total.backward()
    for opt in optimisers.values():
        opt.step()
    updater.step()
    return out.detach()


def batch_metrics(data: TensorDictBase) -> dict[str, float]:
    """``train/cost_mean`` (mean per AUV and decision of the collected batch); when
    episodes ended in it, ``train/episode_<metric>`` averaged over those episodes; with a
    candidate selector's choices in the batch (``("agents", "selector", "index")``),
    ``train/selected_rank_<i>``: the share of AUV-decisions that executed slot ``i`` of the
    selection set (``0 .. K-1`` the proposer's candidates, ``K`` the actor's own action when
    it competes)."""
    out = {"train/cost_mean": data["next", "agents", "cost"].mean().item()}
    index = data.get(("agents", "selector", "index"), None)
    if index is not None:
        slots = data["agents", "selector", "scores"].shape[-1]
        shares = torch.bincount(index.flatten(), minlength=slots).float() / index.numel()
        out.update({f"train/selected_rank_{i}": v for i, v in enumerate(shares.tolist())})
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


def log_metrics(
    logger, metrics: Mapping[str, float], step: int, *, curve: Path | None = None
) -> None:
    """Every metric to a TorchRL logger (none when ``logger`` is ``None``) and, with ``curve``,
    appended to that CSV (long format ``step,key,value``: the learning curve survives a resume
    and needs no logger)."""
    if logger is not None:
        for key, value in metrics.items():
            logger.log_scalar(key, value, step=step)
    if curve is not None:
        new = not Path(curve).exists()
        with open(curve, "a", newline="") as handle:
            writer = csv.writer(handle)
            if new:
                writer.writerow(("step", "key", "value"))
            writer.writerows((step, key, value) for key, value in metrics.items())


def peak_rss_mb() -> float:
    """This process's peak resident memory so far (MB; Linux reports kB, macOS bytes)."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (1024 * 1024 if sys.platform == "darwin" else 1024)


class RunTracker:
    """The bookkeeping around a recipe's loop: a tqdm bar (frames, cost, SDR, SSN, lambda,
    form), ``time/`` metrics, logging (and ``train_curve.csv``), a checkpoint every
    ``cfg.checkpoint.every_frames`` frames and one at the end.

    The recipe counts ``progress["frames"]`` itself (before its updates) and calls
    :meth:`step` once per collected batch and :meth:`finish` after the loop.

    **Learning curves from evaluation.** With ``eval_policy`` and ``cfg.eval.every_frames``
    set, the policy is evaluated at the start (frame 0) and each time the frame count passes
    a multiple of ``every_frames``: ``cfg.eval.curve_envs`` held-out scenes of the training
    sea (seed ``cfg.eval.seed``, the same scenes every time) for ``cfg.eval.curve_steps``
    decisions, deterministic actions (:func:`evaluate`). Each metric of the summary table is
    logged as ``eval/<metric>`` and written to ``eval_curve.csv`` (``step,key,value``); the
    time it takes is logged as ``time/eval_s`` and left out of the frames/s.
    """

    def __init__(self, cfg: DictConfig, run_dir: Path, logger, progress: dict, checkpoint,
                 rotation, *, eval_policy=None, history: int = 0) -> None:  # fmt: skip
        self.cfg, self.logger, self.progress = cfg, logger, progress
        self.checkpoint, self.rotation = checkpoint, rotation
        self.curve = Path(run_dir) / "train_curve.csv"
        self.eval_curve = Path(run_dir) / "eval_curve.csv"
        self.bar = tqdm.tqdm(total=cfg.collector.total_frames, initial=progress["frames"],
                             unit="frame")  # fmt: skip
        self.start = time.perf_counter()
        self.frames_at_start = self.last_saved = progress["frames"]
        self.eval_policy, self.history, self.eval_seconds = eval_policy, history, 0.0
        self.last_episode: dict[str, float] = {}  # the bar's SDR/SSN: the last ended episodes
        self.every = OmegaConf.select(cfg, "eval.every_frames", default=None) or 0
        if eval_policy is not None and self.every:
            self.evaluated_block = progress["frames"] // self.every
            if progress["frames"] == 0:
                self.evaluate_curve()

    def rate(self) -> float:
        """Frames per second of this session (collection and updates together; the learning
        curve's evaluations left out)."""
        elapsed = max(time.perf_counter() - self.start - self.eval_seconds, 1e-9)
        return (self.progress["frames"] - self.frames_at_start) / elapsed

    def evaluate_curve(self) -> dict[str, float]:
        """One point of the learning curve (class docstring); returns its metrics."""
        cfg, began = self.cfg, time.perf_counter()

        curve_env = held_out_env(cfg, self.history, cfg.eval.curve_envs, cfg.eval.curve_steps)
        row = evaluate(curve_env, {"policy": lambda _: self.eval_policy}, [cfg.env.sea_state],
                       seed=cfg.eval.seed, steps=cfg.eval.curve_steps)[0]  # fmt: skip
        seconds = time.perf_counter() - began
        self.eval_seconds += seconds
        metrics = {f"eval/{key}": row[key] for key in SUMMARY_COLUMNS}
        metrics["time/eval_s"] = seconds
        log_metrics(self.logger, metrics, self.progress["frames"], curve=self.eval_curve)
        return metrics

    def step(self, data: TensorDictBase, metrics: dict[str, float], spec=None) -> None:
        """After a batch: add the batch's metrics and the rate, log, advance the bar, save a
        checkpoint when due."""
        metrics.update(batch_metrics(data))
        metrics["time/frames_per_s"] = self.rate()
        metrics["time/elapsed_s"] = time.perf_counter() - self.start
        frames = self.progress["frames"]
        log_metrics(self.logger, metrics, frames, curve=self.curve)
        self.bar.update(data.numel())
        self.last_episode.update({k: v for k, v in metrics.items()
                                  if k.startswith("train/episode_")})  # fmt: skip
        self.bar.set_postfix(progress_postfix({**metrics, **self.last_episode}, spec))
        if self.eval_policy is not None and self.every:
            block = frames // self.every
            if block > self.evaluated_block:
                self.evaluated_block = block
                self.evaluate_curve()
        if frames - self.last_saved >= self.cfg.checkpoint.every_frames:
            self.rotation.save(self.checkpoint, step=frames)
            self.last_saved = frames

    def finish(self, collector) -> dict[str, object]:
        """Shut the collector down, save the final checkpoint; returns the session's facts
        (frames, wall time, training frames/s, peak memory) for the summary."""
        collector.shutdown()
        self.bar.close()
        self.rotation.save(self.checkpoint, step=self.progress["frames"])
        return {"frames": self.progress["frames"],
                "wall time this session (s)": time.perf_counter() - self.start,
                "training frames/s": self.rate(), "peak RSS (MB)": peak_rss_mb()}  # fmt: skip


def close_logger(logger) -> None:
    """Finish a wandb run (its files are complete after this); TorchRL's CSV and TensorBoard
    loggers (no ``finish``) and ``None`` are left as they are."""
    finish = getattr(getattr(logger, "experiment", None), "finish", None)
    if finish is not None:
        finish()


def finish_run(
    cfg: DictConfig,
    run_dir: Path,
    logger,
    policies: Mapping[str, Callable],
    *,
    title: str,
    facts: Mapping[str, object],
    step: int,
    history: int = 0,
) -> Path:
    """Evaluate ``policies`` (and nothing else: pass the reference ones in) on the held-out
    ``cfg.eval`` scenes (with a ``history``-long state-action history when > 0), write
    ``eval.csv`` and ``summary.md``, log ``eval/<sea>/<policy>/<metric>`` and close the
    logger. Returns the summary's path."""

    eval_env = held_out_env(cfg, history, cfg.eval.num_envs, cfg.eval.steps)
    began = time.perf_counter()
    rows = evaluate(eval_env, policies, cfg.eval.sea_states, seed=cfg.eval.seed,
                    steps=cfg.eval.steps, progress=True)  # fmt: skip
    facts = {**facts, "evaluation wall time (s)": time.perf_counter() - began}
    write_eval(rows, run_dir)
    for row in rows:
        log_metrics(logger, {f"eval/{row['sea_state']}/{row['policy']}/{key}": row[key]
                             for key in SUMMARY_COLUMNS}, step)  # fmt: skip
    summary = write_summary(run_dir, title=title, rows=rows, facts=facts)
    close_logger(logger)
    log.info("summary: %s", summary)
    return summary
