"""A training run as one object: its folder, logger, checkpoint, counters and evaluation.

The training loop itself stays in each ``recipes/<name>/train.py`` (readable top to bottom, as
TorchRL's sota-implementations); :class:`Run` keeps the scripts to what differs between them,
and owns the counters (:class:`~torchrl_auv.training.Progress`)::

    run = training.Run(cfg)                    # checks the config, seeds, folder, logger
    remaining = run.restore(learner, buffer)   # resume: the newest; the learner counts updates
    for data in run.collect(collector, eval_policy=policy):   # counts the batch's frames
        ...                                    # out = learner.step(batch)
        run.log(learner.metrics(out))          # logged after the body, with the curve, checkpoints
    facts = run.finish(collector)
    run.evaluate(policies, title="SAC", facts=facts)   # eval.csv, summary.md

Examples:
    >>> import tempfile
    >>> from omegaconf import OmegaConf
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     cfg = OmegaConf.create({"seed": 0, "threads": 1, "run_dir": folder, "resume": None,
    ...                             "logger": {"backend": None, "exp_name": "x", "project": "p",
    ...                                        "offline": True},
    ...                             "checkpoint": {"keep_last": 1}})
    ...     run = Run(cfg)
    ...     run.restore(), run.progress
    (None, Progress(frames=0, updates=0))
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from omegaconf import DictConfig, OmegaConf
from torchrl.checkpoint import Checkpoint

from torchrl_auv.evaluation import LyapunovCertificate, evaluate
from torchrl_auv.training.config import check_config, resolve_config
from torchrl_auv.training.env import held_out_env
from torchrl_auv.training.run.checkpointing import make_checkpoint, resume_latest
from torchrl_auv.training.run.episode_video import episode_frames, write_episode_video
from torchrl_auv.training.run.folder import hydra_folder, remove_if_unused, write_hydra_files
from torchrl_auv.training.run.lock import LOCK_FILE, acquire_run_folder, release_run_folder
from torchrl_auv.training.run.loggers import close_logger, log_metrics, logger_from_config
from torchrl_auv.training.run.progress import Progress
from torchrl_auv.training.run.seeding import configure_threads, seed_everything
from torchrl_auv.training.run.summary import (
    SUMMARY_COLUMNS,
    write_certificate,
    write_eval,
    write_summary,
)
from torchrl_auv.training.run.tracking import RunTracker
from torchrl_auv.training.run.verified_rotation import VerifiedRotation

if TYPE_CHECKING:  # a type only: learner.py imports this package (Progress)
    from torchrl_auv.training.learner import Learner

__all__ = ["Run"]

log = logging.getLogger(__name__)


def _start_run(cfg: DictConfig) -> Path:
    """Check the config's values (before any work), pin threads, seed every RNG, create and
    return the run folder (``resume`` when set, else ``run_dir``) with Hydra's ``.hydra/``
    files. The folder's lock is taken first (:mod:`~torchrl_auv.training.run.lock`): a folder
    another running process holds is refused naming it (:class:`RunFolderInUse`), and the lock
    is held until :func:`_finish_run`. A ``run_dir`` that already holds checkpoints is refused
    without ``resume`` (its checkpoints would be overwritten), and a ``resume`` folder without
    checkpoints is refused too; a refused start writes nothing and removes the empty folder
    Hydra made for it (:mod:`~torchrl_auv.training.run.folder`)."""
    try:
        check_config(resolve_config(cfg))
        run_dir = Path(cfg.resume or cfg.run_dir)
    except Exception:
        remove_if_unused(hydra_folder())
        raise
    had_lock = (run_dir / LOCK_FILE).exists()
    acquire_run_folder(run_dir)  # refused, naming the holder, while another run holds it
    try:
        checkpoints = run_dir / "checkpoints"
        if not cfg.resume and checkpoints.is_dir() and any(checkpoints.iterdir()):
            published = any(p.name.startswith("checkpoint-") for p in checkpoints.iterdir())
            raise ValueError(
                f"run_dir {run_dir} already holds a run's checkpoints; pass "
                f"resume={run_dir} to continue it, or choose a new run_dir"
                if published
                else f"run_dir {run_dir} holds a run stopped before its first checkpoint was "
                f"complete; pass resume={run_dir} to start it again from frame 0 in that "
                "folder, or choose a new run_dir"
            )
        if cfg.resume and not checkpoints.is_dir():
            raise ValueError(f"resume={run_dir} holds no checkpoints/ to continue from")
    except Exception:
        release_run_folder(run_dir, remove=not had_lock)
        remove_if_unused(hydra_folder())
        raise
    configure_threads(int(cfg.threads))
    seed_everything(int(cfg.seed))
    run_dir.mkdir(parents=True, exist_ok=True)
    write_hydra_files(run_dir, cfg)
    return run_dir


def _prepare_resume(
    cfg: DictConfig, run_dir: Path, modules: dict, progress, buffer=None
) -> tuple[Checkpoint, VerifiedRotation, int]:
    """The run's checkpoint: ``modules``, the ``progress`` counters, the RNG states, the
    resolved config (JSON) and, with ``cfg.checkpoint.replay_buffer``, the replay buffer. With
    ``cfg.resume`` the newest checkpoint is loaded into them; a warning names the config groups
    that differ from the stored ones. Returns ``(checkpoint, rotation, frames still to go)``."""
    if buffer is not None and cfg.checkpoint.get("replay_buffer", False):
        modules = {**modules, "replay_buffer": buffer}
    config = OmegaConf.to_container(cfg, resolve=True)
    checkpoint, rotation = make_checkpoint(
        run_dir,
        modules={**modules, "config": config},
        progress=progress,
        keep_last=cfg.checkpoint.keep_last,
    )
    frames = 0
    if cfg.resume:
        frames, values = resume_latest(run_dir, checkpoint, progress)
        if values:
            log.info("resumed %s at %d frames", run_dir, frames)
            if buffer is not None and "replay_buffer" not in modules:
                log.warning(
                    "resumed without the replay buffer (checkpoint.replay_buffer=false): "
                    "training goes on from an empty buffer, not the one the run had "
                    "at %d frames",
                    frames,
                )
        else:  # stopped before its first checkpoint was complete: nothing to load
            log.warning(
                "%s has no complete checkpoint yet: starting it again from frame 0", run_dir
            )
        stored = values.get("config", {})
        changed = sorted(
            k
            for k in config
            if k not in ("resume", "run_dir") and k in stored and stored[k] != config[k]
        )
        if changed:
            log.warning("resumed with a config that differs from the checkpoint's in %s", changed)
    total = OmegaConf.select(cfg, "collector.total_frames", default=None)
    return checkpoint, rotation, None if total is None else total - frames


def _finish_run(
    cfg: DictConfig,
    run_dir: Path,
    logger,
    policies: Mapping[str, Callable],
    *,
    title: str,
    facts: Mapping[str, object],
    step: int,
    certificate: LyapunovCertificate | None = None,
) -> Path:
    """Evaluate ``policies`` (and nothing else: pass the reference ones in) on the held-out
    ``cfg.eval`` scenes (the run's envs, :func:`~torchrl_auv.training.held_out_env`; rows side
    by side in ``cfg.eval.workers`` processes, 1 when absent), write ``summary.md`` (with
    the evaluation's wall time; with ``cfg.eval.video_steps`` the first policy's episode in
    one held-out scene, ``cfg.eval.seed`` and the first sea, as ``eval_episode.mp4``), log
    ``eval/<sea>/<policy>/<metric>``, close the logger and write ``eval.csv`` last (its
    presence marks a finished run) and let go of the folder's lock. Returns the summary's
    path."""
    eval_env = held_out_env(cfg, cfg.eval.num_envs, cfg.eval.steps)
    began = time.perf_counter()
    workers = OmegaConf.select(cfg, "eval.workers", default=None) or 1
    rows = evaluate(
        eval_env,
        policies,
        cfg.eval.sea_states,
        seed=cfg.eval.seed,
        steps=cfg.eval.steps,
        progress=True,
        workers=workers,
        transition_stats=certificate,
    )
    facts = {**facts, "evaluation wall time (s)": time.perf_counter() - began}
    if certificate is not None:
        facts["Lyapunov certificate"] = write_certificate(rows, run_dir, certificate).name
    video_steps = OmegaConf.select(cfg, "eval.video_steps", default=0) or 0
    if video_steps:  # the first policy (the run's own), one held-out scene (eval.seed)
        name, policy = next(iter(policies.items()))
        sea = cfg.eval.sea_states[0]
        one_scene = held_out_env(cfg, 1, video_steps)(sea, cfg.eval.seed)
        frames = episode_frames(one_scene, policy, video_steps)
        path = write_episode_video(frames, run_dir / "eval_episode.mp4", logger=logger, step=step)
        facts["evaluation video"] = f"{path.name}: {name}, {sea}, {len(frames) - 1} decisions"
    summary = write_summary(run_dir, title=title, rows=rows, facts=facts)
    for row in rows:
        log_metrics(
            logger,
            {f"eval/{row['sea_state']}/{row['policy']}/{key}": row[key] for key in SUMMARY_COLUMNS},
            step,
        )
    close_logger(logger)
    write_eval(rows, run_dir)  # last: eval.csv marks a finished run
    release_run_folder(run_dir)
    log.info("summary: %s", summary)
    return summary


class Run:
    """One training run (module docstring): built from a recipe config, it checks every value
    before any work, seeds, creates the folder (:func:`_start_run`) and the logger.

    The calls, in the order a recipe makes them: :meth:`restore` (what a checkpoint holds; the
    newest one loaded on resume), :meth:`collect` (the loop), :meth:`finish`, :meth:`evaluate`;
    :meth:`collect` refuses to run before :meth:`restore`, :meth:`finish` before
    :meth:`collect`.

    Attributes:
        cfg: the recipe config.
        dir: the run folder (``resume`` when set, else ``run_dir``).
        logger: the TorchRL logger of ``cfg.logger`` (``None`` when its backend is empty).
        progress: the :class:`Progress` counters (frames: :meth:`collect`; updates: the
            learner given to :meth:`restore`), restored from the checkpoint on resume.
    """

    def __init__(self, cfg: DictConfig) -> None:
        self.cfg = cfg
        self.dir = _start_run(cfg)
        self.logger = logger_from_config(cfg, self.dir)
        self.progress = Progress()
        self.checkpoint: Checkpoint | None = None
        self.rotation: VerifiedRotation | None = None
        self.tracker: RunTracker | None = None
        self.remaining: int | None = None
        self._logged: tuple[dict[str, float], object] = ({}, None)

    def restore(
        self,
        learner: Learner | None = None,
        buffer=None,
        *,
        modules: Mapping[str, object] | None = None,
    ) -> int | None:
        """Register what a checkpoint saves (the ``learner``'s losses and optimisers,
        ``modules``: anything else with ``state_dict``; the counters, the RNG states and the
        config always; the ``buffer`` with ``cfg.checkpoint.replay_buffer``) and, with
        ``cfg.resume``, load the newest checkpoint into them (:func:`_prepare_resume`). The
        learner then counts its updates into :attr:`progress`. Returns the frames still to
        collect (``None`` without ``cfg.collector``)."""
        if isinstance(learner, Mapping):
            raise TypeError(
                "Run.restore(learner, buffer, modules=...): the first argument is the learner "
                "(or None); pass other checkpointed modules as modules={...}"
            )
        parts = dict(modules or {})
        if learner is not None:
            parts = {**learner.checkpoint_modules(), **parts}
            learner.progress = self.progress
        self.checkpoint, self.rotation, self.remaining = _prepare_resume(
            self.cfg, self.dir, parts, self.progress, buffer
        )
        return self.remaining

    def collect(self, collector, eval_policy=None) -> Iterator:
        """The training loop's batches: ``for data in run.collect(collector): ...``.

        Starts the loop's bookkeeping (:class:`RunTracker`: the progress bar, the learning
        curve of ``eval_policy`` when ``cfg.eval.every_frames``, checkpoints every
        ``cfg.checkpoint.every_frames``), then yields each batch after adding its frames to
        ``progress.frames``; after the loop's body, logs what the body gave :meth:`log` and
        evaluates and checkpoints when due. Yields nothing when :meth:`restore` found the run
        complete. A ``break`` out of the loop leaves the batch it breaks on unlogged."""
        if self.checkpoint is None:
            raise RuntimeError("call Run.restore(...) before Run.collect(collector)")
        self.tracker = RunTracker(
            self.cfg,
            self.dir,
            self.logger,
            self.progress,
            self.checkpoint,
            self.rotation,
            eval_policy=eval_policy,
        )
        if self.remaining is not None and self.remaining <= 0:
            return
        for data in collector:
            self.progress.frames += data.numel()
            self._logged = ({}, None)
            yield data
            metrics, spec = self._logged
            self.tracker.step(data, metrics, spec)

    def log(self, metrics: Mapping[str, float], spec=None) -> None:
        """The metrics of the batch :meth:`collect` yielded last (logged after the loop's body;
        ``spec``: the Lyapunov spec in force, shown on the progress bar)."""
        self._logged = (dict(metrics), spec)

    def finish(self, collector) -> dict[str, object]:
        """After the loop: shut the collector down, save the last checkpoint; returns the
        session's facts (frames, wall time, frames/s, peak memory, gradient updates)."""
        if self.tracker is None:
            raise RuntimeError("call Run.collect(collector) before Run.finish(collector)")
        facts = self.tracker.finish(collector)
        facts["gradient updates"] = self.progress.updates
        return facts

    def evaluate(
        self,
        policies: Mapping[str, Callable],
        *,
        title: str,
        facts: Mapping[str, object],
        certificate: LyapunovCertificate | None = None,
    ) -> Path:
        """The final evaluation on held-out scenes, ``eval.csv``, ``summary.md``; closes the
        logger (:func:`_finish_run`). With ``certificate``, every row also measures the
        decrease condition on its executed approach transitions, written to
        ``lyapunov_certificate.json`` (:func:`write_certificate`). Returns the summary's
        path."""
        return _finish_run(
            self.cfg,
            self.dir,
            self.logger,
            policies,
            title=title,
            facts=facts,
            step=self.progress.frames,
            certificate=certificate,
        )
