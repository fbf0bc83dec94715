"""A results store: the finished jobs' outputs that the report reads, kept where git keeps them.

The paper budget's grid runs for many hours over several sittings, and a sitting's machine may
not be the next one's: checkpoints, replay buffers and first stages (3.6 MB per proposer, 21
of them) stay on the machine that made them, but what the report reads from a finished job is
a few kilobytes of text (:data:`STORED_FILES`). ``recipes/paper/run_all.py store=DIR`` copies
them into ``DIR`` (``results/paper`` in the repository: commit it after a sitting) as each job
finishes, and back into the run folder at the start of the next sitting, where a job whose
``eval.csv`` is back is finished and skipped. A job that had not finished starts again on a
new machine (its checkpoints are not stored); a first stage a job needs is rebuilt (the same
artefact: its build is seeded). Of each built first stage the store keeps the record Fig. 4
reads (:data:`FIRST_STAGE_FILES`, under ``DIR/first_stage/<artefact>/``), restored into
``<run folder>/first_stage_records/`` (not ``first_stage/``: an artefact folder without its
proposer would be taken for a built one), and the report's Fig. 5/6 rollouts
(:data:`REPORT_FILES`), which Fig. 5/6 draws again where its first stage is gone.

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

import json
import os
import shutil
from collections.abc import Iterable
from pathlib import Path

from torchrl_auv.report.paper.grid import Job

__all__ = [
    "FINISHED_MARK",
    "FIRST_STAGE_FILES",
    "RECORDS",
    "REPORT_FILES",
    "SITTINGS",
    "STORED_FILES",
    "read_sittings",
    "record_sitting",
    "restore_finished",
    "save_finished",
]

#: The file whose presence makes a job finished
#: (:func:`~torchrl_auv.report.paper.progress.job_state`).
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

#: What the store keeps of a built first stage (its proposer stays on the machine).
FIRST_STAGE_FILES = ("pretrain_loss.csv", "metrics.json", "values.json")

#: Where the restored first-stage records go under a run folder.
RECORDS = "first_stage_records"

#: The store's record of the grid's sittings (:func:`record_sitting`).
SITTINGS = "sittings.json"

#: Report outputs made from a first stage alone, kept so that a machine without it can make
#: them again: Fig. 5/6's rolled-out candidates (about 30 kB) and the sampler ablation's
#: proposer times per decision.
REPORT_FILES = ("report/fig5_6/fig5_6.json", "report/sampler/sampler.json")


def _copy_marked(src: Path, dst: Path, names: tuple[str, ...], mark: str) -> list[Path]:
    """Copy ``names`` (those that exist) from ``src`` to ``dst`` when ``src`` holds ``mark``
    and ``dst`` does not; ``mark`` last, so a copy cut short is not taken for a whole one.
    Returns the written paths."""
    if not (src / mark).is_file() or (dst / mark).exists():
        return []
    written = []
    for name in sorted(names, key=lambda n: n == mark):
        if (src / name).is_file():
            (dst / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src / name, dst / name)
            written.append(dst / name)
    return written


def _copy_first_stages(source: Path, target: Path) -> list[Path]:
    """The records (:data:`FIRST_STAGE_FILES`) of every complete first stage under ``source``
    (``values.json`` written; not a build cut short, ``.<name>.partial-*``) that ``target``
    lacks."""
    if not source.is_dir():
        return []
    return [
        path
        for folder in sorted(source.iterdir())
        if not folder.name.startswith(".")
        for path in _copy_marked(folder, target / folder.name, FIRST_STAGE_FILES, "values.json")
    ]


def _copy_report_files(source: Path, target: Path, *, update: bool) -> list[Path]:
    """:data:`REPORT_FILES` that ``source`` holds and ``target`` lacks or, with ``update``
    (saving: the run folder's report is the latest), holds with other content."""
    written = []
    for name in REPORT_FILES:
        src, dst = source / name, target / name
        if not src.is_file():
            continue
        if dst.exists() and not (update and dst.read_bytes() != src.read_bytes()):
            continue
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src, dst)
        written.append(dst)
    return written


def _copy_finished(source: Path, target: Path, jobs: Iterable[Job]) -> list[Path]:
    """Copy :data:`STORED_FILES` of the jobs finished under ``source`` and not under
    ``target``; returns the written paths."""
    return [
        path
        for job in jobs
        for path in _copy_marked(
            source / "jobs" / job.name, target / "jobs" / job.name, STORED_FILES, FINISHED_MARK
        )
    ]


def save_finished(
    root: str | Path, store: str | Path, jobs: Iterable[Job], *, report: bool = False
) -> list[Path]:
    """Copy the outputs (:data:`STORED_FILES`) of ``jobs`` finished under the run folder
    ``root`` into ``store`` (``store/jobs/<job.name>/``), each job once: a job already in the
    store is left as it is. Its ``eval.csv`` is copied last, so a copy cut short is not taken
    for a finished job. The records of the first stages built under ``root/first_stage`` go
    to ``store/first_stage``. ``report``: right after a report was written under ``root``,
    its :data:`REPORT_FILES` go to ``store/report`` too, over older ones (at other times a
    run folder's report may be older than the store's). Returns the written paths."""
    root, store = Path(root), Path(store)
    records = _copy_first_stages(root / "first_stage", store / "first_stage")
    made = _copy_report_files(root, store, update=True) if report else []
    return _copy_finished(root, store, jobs) + records + made


def restore_finished(store: str | Path, root: str | Path, jobs: Iterable[Job]) -> list[Path]:
    """Copy the stored outputs of ``jobs`` back under ``root`` (:func:`save_finished` in
    reverse) where ``root`` does not hold that job finished, and the first-stage records into
    ``root/first_stage_records`` (:data:`RECORDS`); returns the written paths."""
    store, root = Path(store), Path(root)
    records = _copy_first_stages(store / "first_stage", root / RECORDS)
    report = _copy_report_files(store, root, update=False)
    return _copy_finished(store, root, jobs) + records + report


def read_sittings(store: str | Path) -> list[dict]:
    """The sittings :func:`record_sitting` recorded in ``store`` (none: ``[]``)."""
    path = Path(store) / SITTINGS
    return json.loads(path.read_text()) if path.exists() else []


def record_sitting(store: str | Path, sitting: dict) -> None:
    """Record (or update, by its ``"start"``) one sitting of the grid in ``store``: when it
    started, when its last job ended, how many jobs it finished, on what machine. Written
    whole to a temporary file, then moved over the record, so a sitting killed mid-write
    leaves the previous record."""
    path = Path(store) / SITTINGS
    sittings = [s for s in read_sittings(store) if s.get("start") != sitting["start"]]
    sittings = sorted([*sittings, dict(sitting)], key=lambda s: s["start"])
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_suffix(".partial")
    partial.write_text(json.dumps(sittings, indent=1) + "\n")
    os.replace(partial, path)
