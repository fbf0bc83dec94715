"""A training run's lifecycle, one file per job: the :class:`Run` object the recipes drive and
what it owns.

==========================  ========================================================================
module                      job
==========================  ========================================================================
``training_run``            :class:`Run`: start, restore, the loop's batches, finish, evaluation
``progress``                :class:`Progress`, the run's counters (frames, updates)
``lock``                    one writer per run folder (an exclusive lock, stale locks taken over)
``folder``                  the folder under Hydra: nothing written before the values are checked
``checkpointing``           TorchRL checkpoints: components, resume from the newest
``verified_rotation``       checkpoints with a size and SHA-256 per file, checked before loading
``loggers``                 TorchRL's loggers (wandb offline, CSV, TensorBoard), the curve CSVs
``tracking``                the loop's bookkeeping: metrics, progress bar, learning curve
``summary``                 ``eval.csv`` and ``summary.md``
``seeding``                 threads and seeds
``episode_video``           one held-out episode as top-view frames and an mp4
==========================  ========================================================================

Examples:
    >>> from torchrl_auv.training.run import Progress
    >>> Progress(frames=1000).updates
    0
"""

from __future__ import annotations

from torchrl_auv.training.run.checkpointing import ProgressState, make_checkpoint, resume_latest
from torchrl_auv.training.run.episode_video import FPS, episode_frames, write_episode_video
from torchrl_auv.training.run.folder import hydra_folder, remove_if_unused, write_hydra_files
from torchrl_auv.training.run.lock import (
    LOCK_FILE,
    RunFolderInUse,
    acquire_run_folder,
    release_run_folder,
)
from torchrl_auv.training.run.loggers import (
    close_logger,
    log_metrics,
    logger_from_config,
    make_logger,
    truncate_curve,
)
from torchrl_auv.training.run.progress import Progress
from torchrl_auv.training.run.seeding import configure_threads, seed_everything
from torchrl_auv.training.run.summary import (
    SUMMARY_COLUMNS,
    write_certificate,
    write_eval,
    write_summary,
)
from torchrl_auv.training.run.tracking import (
    EPISODE_METRICS,
    RunTracker,
    batch_metrics,
    peak_rss_mb,
    progress_postfix,
)
from torchrl_auv.training.run.training_run import Run
from torchrl_auv.training.run.verified_rotation import (
    CHECKSUMS,
    VerifiedRotation,
    checkpoint_problems,
    write_checksums,
)

__all__ = [
    "CHECKSUMS",
    "EPISODE_METRICS",
    "FPS",
    "LOCK_FILE",
    "SUMMARY_COLUMNS",
    "Progress",
    "ProgressState",
    "Run",
    "RunFolderInUse",
    "RunTracker",
    "VerifiedRotation",
    "acquire_run_folder",
    "batch_metrics",
    "checkpoint_problems",
    "close_logger",
    "configure_threads",
    "episode_frames",
    "hydra_folder",
    "log_metrics",
    "logger_from_config",
    "make_checkpoint",
    "make_logger",
    "peak_rss_mb",
    "progress_postfix",
    "release_run_folder",
    "remove_if_unused",
    "resume_latest",
    "seed_everything",
    "truncate_curve",
    "write_certificate",
    "write_checksums",
    "write_episode_video",
    "write_eval",
    "write_hydra_files",
    "write_summary",
]
