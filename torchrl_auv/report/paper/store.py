"""A results store: the finished jobs' outputs that the report reads, kept where git keeps them.

The paper budget's grid runs for many hours over several sittings, and a sitting's machine may
not be the next one's: checkpoints, replay buffers and first stages (3.6 MB per proposer, 21
of them) stay on the machine that made them, but what the report reads from a finished job is
a few kilobytes of text (:data:`STORED_FILES`). ``recipes/paper/run_all.py store=DIR`` copies
them into ``DIR`` (``results/paper`` in the repository: commit it after a sitting) as each job
finishes, and back into the run folder at the start of the next sitting, where a job whose
``eval.csv`` is back is finished and skipped. A job that had not finished starts again on a
new machine (its checkpoints are not stored); a first stage a job needs is rebuilt (the same
artefact: its build is seeded).

Examples:
    >>> import tempfile
    >>> from pathlib import Path
    >>> from torchrl_auv.report.paper.grid import Job
    >>> root, store = Path(tempfile.mkdtemp()), Path(tempfile.mkdtemp())
    >>> job = Job("sac", "ves", "s_surface", 0)
    >>> run = root / "jobs" / job.name
    >>> (run / "checkpoints").mkdir(parents=True)
    >>> _ = (run / "eval.csv").write_text("sea_state,policy\\nves,sac\\n")
    >>> [p.relative_to(store).as_posix() for p in save_finished(root, store, [job])]
    ['jobs/sac/ves/s_surface/seed0/eval.csv']
    >>> fresh = Path(tempfile.mkdtemp())
    >>> [p.relative_to(fresh).as_posix() for p in restore_finished(store, fresh, [job])]
    ['jobs/sac/ves/s_surface/seed0/eval.csv']
"""

from __future__ import annotations

import shutil
from collections.abc import Iterable
from pathlib import Path

from torchrl_auv.report.paper.grid import Job

__all__ = ["FINISHED_MARK", "STORED_FILES", "restore_finished", "save_finished"]

#: The file whose presence makes a job finished (``run_all.job_state``).
FINISHED_MARK = "eval.csv"

#: What the store keeps of a finished job (those that exist): the evaluation, the learning
#: curves, the Lyapunov trace and the advisor's decisions the report reads, the summary and
#: the resolved config that say how the numbers were made.
STORED_FILES = (
    FINISHED_MARK,
    "eval_curve.csv",
    "train_curve.csv",
    "lyapunov_trace.csv",
    "advisor.jsonl",
    "summary.md",
    ".hydra/config.yaml",
    ".hydra/overrides.yaml",
)


def _copy_finished(source: Path, target: Path, jobs: Iterable[Job]) -> list[Path]:
    """Copy :data:`STORED_FILES` of the jobs finished under ``source`` and not under
    ``target``; returns the written paths."""
    written = []
    for job in jobs:
        src, dst = source / "jobs" / job.name, target / "jobs" / job.name
        if not (src / FINISHED_MARK).exists() or (dst / FINISHED_MARK).exists():
            continue
        for name in sorted(STORED_FILES, key=lambda n: n == FINISHED_MARK):  # the mark last
            if (src / name).is_file():
                (dst / name).parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(src / name, dst / name)
                written.append(dst / name)
    return written


def save_finished(root: str | Path, store: str | Path, jobs: Iterable[Job]) -> list[Path]:
    """Copy the outputs (:data:`STORED_FILES`) of ``jobs`` finished under the run folder
    ``root`` into ``store`` (``store/jobs/<job.name>/``), each job once: a job already in the
    store is left as it is. Its ``eval.csv`` is copied last, so a copy cut short is not taken
    for a finished job. Returns the written paths."""
    return _copy_finished(Path(root), Path(store), jobs)


def restore_finished(store: str | Path, root: str | Path, jobs: Iterable[Job]) -> list[Path]:
    """Copy the stored outputs of ``jobs`` back under ``root`` (:func:`save_finished` in
    reverse) where ``root`` does not hold that job finished; returns the written paths."""
    return _copy_finished(Path(store), Path(root), jobs)
