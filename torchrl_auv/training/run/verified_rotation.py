"""Checkpoints that cannot resume wrong: a size and SHA-256 per file, verified before loading.

TorchRL's :class:`~torchrl.checkpoint.CheckpointRotation` publishes a checkpoint atomically
(a save cut short leaves no entry), but it loads whatever a published checkpoint holds: a
weight file truncated afterwards (a full disk, a bad copy, a damaged volume) loads as zeros
and training goes on from it. :class:`VerifiedRotation` writes ``checksums.json`` (each
file's size in bytes and SHA-256) into the staged checkpoint before publishing it, so every
published checkpoint carries its checksums; :meth:`VerifiedRotation.newest_intact` finds the
newest checkpoint whose files all match, and :meth:`~VerifiedRotation.prune` never deletes
the newest intact one. A checkpoint written before checksums existed (no ``checksums.json``)
counts as unverified: used only when no checkpoint of the run verifies, with a warning.

Examples:
    >>> import tempfile, torch
    >>> from pathlib import Path
    >>> from torchrl.checkpoint import Checkpoint
    >>> net = torch.nn.Linear(2, 1)
    >>> with tempfile.TemporaryDirectory() as run_dir:
    ...     rotation = VerifiedRotation(Path(run_dir) / "checkpoints", keep_last=2)
    ...     first = rotation.save(Checkpoint(net=net), step=1)
    ...     newest = rotation.save(Checkpoint(net=net), step=2)
    ...     weights = next(newest.rglob("*.memmap"))
    ...     _ = weights.write_bytes(weights.read_bytes()[:3])  # truncate a weight file
    ...     intact, damaged = rotation.newest_intact()
    ...     intact == first, [path == newest for path, _ in damaged]
    (True, [True])
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import uuid
from pathlib import Path

from torchrl.checkpoint import Checkpoint, CheckpointRotation

__all__ = ["CHECKSUMS", "VerifiedRotation", "checkpoint_problems", "write_checksums"]

#: the file in each checkpoint that lists every other file's size and SHA-256
CHECKSUMS = "checksums.json"


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _files(root: Path) -> list[Path]:
    return sorted(p for p in root.rglob("*") if p.is_file() and p.name != CHECKSUMS)


def write_checksums(root: Path) -> None:
    """Write ``root/checksums.json``: ``{relative path: {"bytes": size, "sha256": digest}}`` of
    every file under ``root``, atomically (a temporary file renamed into place)."""
    table = {
        p.relative_to(root).as_posix(): {"bytes": p.stat().st_size, "sha256": _sha256(p)}
        for p in _files(root)
    }
    temporary = root / f".{CHECKSUMS}.{uuid.uuid4().hex}"
    temporary.write_text(json.dumps(table, indent=1, sort_keys=True) + "\n")
    os.replace(temporary, root / CHECKSUMS)


def checkpoint_problems(root: Path) -> list[str]:
    """What is wrong with the checkpoint directory ``root`` against its ``checksums.json``
    (a missing, resized, changed or unlisted file; no or an unreadable checksums file); an
    empty list when every file matches."""
    listing = root / CHECKSUMS
    if not listing.is_file():
        return [f"no {CHECKSUMS} (written before checksums existed, or not a checkpoint)"]
    try:
        table = json.loads(listing.read_text())
    except (OSError, ValueError) as error:
        return [f"{listing} is unreadable: {error}"]
    problems = []
    for name, expected in sorted(table.items()):
        path = root / name
        if not path.is_file():
            problems.append(f"{path} is missing")
        elif path.stat().st_size != expected["bytes"]:
            problems.append(f"{path} has {path.stat().st_size} bytes, {expected['bytes']} written")
        elif _sha256(path) != expected["sha256"]:
            problems.append(f"{path} does not match its SHA-256")
    unlisted = [p for p in _files(root) if p.relative_to(root).as_posix() not in table]
    problems += [f"{p} was not part of the checkpoint" for p in unlisted]
    return problems


class VerifiedRotation(CheckpointRotation):
    """TorchRL's :class:`~torchrl.checkpoint.CheckpointRotation` (directory checkpoints) with
    ``checksums.json`` written before each checkpoint is published and a retention policy that
    keeps the newest intact checkpoint (module docstring)."""

    def save(self, checkpoint: Checkpoint, *, step: int, **kwargs) -> Path:
        """Save ``checkpoint`` at ``step`` with its checksums, publish it, then prune."""
        if checkpoint.format != "directory":
            raise ValueError(
                f"VerifiedRotation saves directory checkpoints, got format {checkpoint.format!r}"
            )
        self._validate_step(step)
        self.directory.mkdir(parents=True, exist_ok=True)
        stage = self.directory / f".stage-{uuid.uuid4().hex}"  # not a name the rotation reads
        destination = self._checkpoint_path(step, "directory")
        try:
            checkpoint.save(stage, **kwargs)
            write_checksums(stage)
            if destination.exists():  # the same step saved again: replace it
                self._remove_atomically(destination)
            os.replace(stage, destination)  # publish: one rename
        finally:
            shutil.rmtree(stage, ignore_errors=True)
        self.prune()
        return destination

    def checkpoint_dirs(self) -> list[Path]:
        """Every checkpoint directory of the rotation by step, oldest first, including those
        TorchRL no longer recognises (an unreadable manifest)."""
        if not self.directory.is_dir():
            return []
        steps = {}
        for path in self.directory.iterdir():
            step = path.name.removeprefix(f"{self.prefix}-")
            if path.is_dir() and step != path.name and step.isdigit():
                steps[int(step)] = path
        return [steps[k] for k in sorted(steps)]

    def newest_intact(self) -> tuple[Path | None, list[tuple[Path, list[str]]]]:
        """``(path, passed over)``: the newest checkpoint whose files match their checksums
        (when none does, the newest one written without checksums; ``None`` when neither
        exists) and the newer checkpoints passed over, each with its problems."""
        passed = []
        for path in reversed(self.checkpoint_dirs()):
            problems = checkpoint_problems(path)
            if not problems:
                return path, passed
            passed.append((path, problems))
        for index, (path, _) in enumerate(passed):
            if not (path / CHECKSUMS).exists() and (path / "manifest.json").is_file():
                return path, passed[:index]
        return None, passed

    def prune(self) -> tuple[Path, ...]:
        """Keep the newest ``keep_last`` checkpoints and, if none of them verifies, the newest
        one that does; remove the rest and any save a kill left staged."""
        for stale in self.directory.glob(".stage-*"):
            shutil.rmtree(stale, ignore_errors=True)
        paths = self.checkpoint_dirs()
        keep = set(paths[-self.keep_last :])
        if not any(not checkpoint_problems(p) for p in keep):
            intact = next((p for p in reversed(paths) if not checkpoint_problems(p)), None)
            keep |= {intact} if intact is not None else set()
        removed = tuple(p for p in paths if p not in keep)
        for path in removed:
            self._remove_atomically(path)
        return removed
