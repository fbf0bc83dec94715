"""Run checkpoints with ``torchrl.checkpoint``: atomic saves, rotation, RNG states, resume.

:func:`make_checkpoint` registers what a training run must restore (modules, optimisers, the
run's counters, the global RNG states) with TorchRL's :class:`~torchrl.checkpoint.Checkpoint`;
:class:`~torchrl_auv.training.run.verified_rotation.VerifiedRotation` (TorchRL's rotation with a
size and SHA-256 per file) keeps the newest ``keep_last`` under ``run_dir/checkpoints``. A run
killed at any moment (even SIGKILL) resumes from the newest complete checkpoint: a checkpoint is
published by renaming it into place, so a save cut short leaves no partial entry; one damaged
afterwards is passed over with a warning naming it, and rotation never deletes the newest
intact one.

Examples:
    >>> import tempfile, torch
    >>> from torchrl_auv.training.run.progress import Progress
    >>> net, progress = torch.nn.Linear(2, 1), Progress()
    >>> with tempfile.TemporaryDirectory() as run_dir:
    ...     ckpt, rotation = make_checkpoint(run_dir, modules={"net": net}, progress=progress)
    ...     progress.frames = 128
    ...     _ = rotation.save(ckpt, step=128)
    ...     progress.frames = 0
    ...     resume_latest(run_dir, ckpt, progress)[0]
    128
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Mapping
from pathlib import Path

from torchrl.checkpoint import Checkpoint, CheckpointError, GlobalRNGState

from torchrl_auv.training.run.progress import Progress
from torchrl_auv.training.run.verified_rotation import (
    CHECKSUMS,
    VerifiedRotation,
    checkpoint_problems,
)

__all__ = ["ProgressState", "make_checkpoint", "resume_latest"]


class ProgressState:
    """A run's counters (:class:`~torchrl_auv.training.Progress`) as a checkpoint component,
    updated in place on load."""

    def __init__(self, progress: Progress) -> None:
        if not isinstance(progress, Progress):
            raise TypeError(f"progress must be a Progress, got {type(progress).__name__}")
        self.progress = progress

    def state_dict(self) -> dict:
        return dataclasses.asdict(self.progress)

    def load_state_dict(self, state: Mapping) -> None:
        for key, value in state.items():
            setattr(self.progress, key, value)


def make_checkpoint(
    run_dir: str | Path,
    *,
    modules: Mapping[str, object],
    progress: Progress,
    keep_last: int = 2,
) -> tuple[Checkpoint, VerifiedRotation]:
    """A checkpoint of ``modules`` (anything with ``state_dict``: networks, losses with their
    targets and dual variables, optimisers, replay buffers), the ``progress`` counters (updated
    in place on load) and the global RNG states (python, numpy, torch).

    Returns:
        ``(checkpoint, rotation)``; save with ``rotation.save(checkpoint, step=frames)``.
    """
    checkpoint = Checkpoint(**modules, progress=ProgressState(progress), rng=GlobalRNGState())
    return checkpoint, VerifiedRotation(Path(run_dir) / "checkpoints", keep_last=keep_last)


def resume_latest(
    run_dir: str | Path, checkpoint: Checkpoint, progress: Progress
) -> tuple[int, dict]:
    """Load the newest intact checkpoint under ``run_dir/checkpoints`` into ``checkpoint``'s
    live components (a newer damaged one is passed over with a warning naming its path and
    problems). Returns the frames it had reached and its plain (JSON) values, e.g. the stored
    ``config`` (``(0, {})`` and nothing loaded when there is none).

    Raises:
        CheckpointError: checkpoints exist but none is intact (each path and problem named).
    """
    rotation = VerifiedRotation(Path(run_dir) / "checkpoints", keep_last=1)
    intact, damaged = rotation.newest_intact()
    for path, problems in damaged:
        warnings.warn(
            f"checkpoint {path} is damaged and was not loaded: {'; '.join(problems)}", stacklevel=2
        )
    if intact is None:
        if damaged:
            raise CheckpointError(
                f"no intact checkpoint under {rotation.directory}: "
                + " | ".join(f"{path}: {'; '.join(problems)}" for path, problems in damaged)
            )
        return 0, {}
    # newest_intact hashed it already; only a checkpoint without checksums is unverified
    if not (intact / CHECKSUMS).exists() and (problems := checkpoint_problems(intact)):
        warnings.warn(
            f"checkpoint {intact} cannot be verified ({'; '.join(problems)}); "
            "loading it unverified",
            stacklevel=2,
        )
    elif damaged:
        warnings.warn(f"resuming from {intact}, the newest intact checkpoint", stacklevel=2)
    try:
        result = checkpoint.load(intact)
    except Exception as error:  # a legacy checkpoint without checksums may still be damaged
        raise CheckpointError(f"checkpoint {intact} could not be loaded: {error}") from error
    return int(progress.frames), dict(result.values)
