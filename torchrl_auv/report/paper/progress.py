"""How far a grid of the paper's jobs has run: each job finished, stopped (and at how many
frames) or not started, and the time left at the rate of the sittings so far.

``recipes/paper/run_all.py status=true`` prints :func:`format_status` and runs nothing; the
scheduler reads :func:`job_state` to skip finished jobs and resume stopped ones.

Examples:
    >>> import tempfile
    >>> from pathlib import Path
    >>> from torchrl_auv.report.paper.grid import Job
    >>> root = Path(tempfile.mkdtemp())
    >>> done, stopped = Job("sac", "ves", "s_surface", 0), Job("sac", "ves", "s_surface", 1)
    >>> (root / "jobs" / done.name).mkdir(parents=True)
    >>> _ = (root / "jobs" / done.name / "eval.csv").write_text("sea_state,policy\\n")
    >>> (root / "jobs" / stopped.name / "checkpoints" / "checkpoint-000000020000").mkdir(
    ...     parents=True)
    >>> job_state(root / "jobs" / done.name), job_state(root / "jobs" / stopped.name)
    ('done', 'stopped')
    >>> checkpoint_frames(root / "jobs" / stopped.name)
    20000
"""

from __future__ import annotations

import datetime
import math
from collections import Counter
from collections.abc import Sequence
from pathlib import Path

from torchrl_auv.report.paper.grid import FRAMEWORKS, Job
from torchrl_auv.report.paper.store import FINISHED_MARK

__all__ = ["checkpoint_frames", "format_status", "grid_status", "job_state", "sitting_hours"]


def job_state(run_dir: str | Path) -> str:
    """``"done"`` (``eval.csv`` written), ``"stopped"`` (checkpoints: resume) or ``"new"``."""
    run_dir = Path(run_dir)
    if (run_dir / FINISHED_MARK).exists():
        return "done"
    checkpoints = run_dir / "checkpoints"
    if checkpoints.is_dir() and any(checkpoints.iterdir()):
        return "stopped"
    return "new"


def checkpoint_frames(run_dir: str | Path) -> int | None:
    """The frames of the newest checkpoint under ``run_dir/checkpoints`` (named
    ``checkpoint-<frames>``), or ``None`` where there is none."""
    checkpoints = Path(run_dir) / "checkpoints"
    steps = []
    for path in checkpoints.glob("checkpoint-*") if checkpoints.is_dir() else ():
        step = path.name.removeprefix("checkpoint-")
        if step.isdigit():
            steps.append(int(step))
    return max(steps, default=None)


def sitting_hours(sittings: Sequence[dict]) -> float:
    """The hours of ``sittings`` (``store.read_sittings``), each from its start to its last
    finished job (none for a sitting without one); sittings at the same time (two
    ``run_all.py`` at once) count their shared hours once: the union of their spans."""
    spans = sorted(
        (datetime.datetime.fromisoformat(s["start"]), datetime.datetime.fromisoformat(s["end"]))
        for s in sittings
        if s.get("end")
    )
    seconds, reached = 0.0, None
    for start, end in spans:
        start = start if reached is None else max(start, reached)
        if end > start:
            seconds += (end - start).total_seconds()
            reached = end
    return seconds / 3600.0


def grid_status(
    root: str | Path,
    jobs: Sequence[Job],
    *,
    store: str | Path | None = None,
    sittings: Sequence[dict] = (),
) -> dict:
    """Each job's state under ``root`` (finished also where only the results ``store`` holds
    it), counts by framework, and the rate of the ``sittings`` (``store.read_sittings``).

    Returns:
        a dict: ``jobs`` (``(name, state, frames)`` per job), ``counts`` (per framework a
        ``Counter`` of states), ``finished``, ``total``, ``sittings`` (numbers of jobs and
        sittings), ``rate_per_hour`` (jobs finished per hour of the sittings; NaN without
        any) and ``hours_left`` (the jobs not finished at that rate; NaN). A state is
        ``"done"``, ``"stopped"`` (checkpoints: stopped, or running now; ``frames`` its
        newest checkpoint's) or ``"new"``.
    """
    root = Path(root)
    rows, counts = [], {framework: Counter() for framework in FRAMEWORKS}
    for job in jobs:
        run_dir = root / "jobs" / job.name
        state = job_state(run_dir)
        if state != "done" and store is not None:
            state = "done" if (Path(store) / "jobs" / job.name / FINISHED_MARK).exists() else state
        frames = checkpoint_frames(run_dir) if state == "stopped" else None
        rows.append((job.name, state, frames))
        counts[job.framework][state] += 1
    finished = sum(state == "done" for _, state, _ in rows)
    hours = sitting_hours(sittings)
    in_sittings = sum(int(s.get("jobs_finished", 0)) for s in sittings)
    rate = in_sittings / hours if hours > 0 and in_sittings else math.nan
    return {
        "jobs": rows,
        "counts": counts,
        "finished": finished,
        "total": len(rows),
        "sittings": len(sittings),
        "rate_per_hour": rate,
        "hours_left": (len(rows) - finished) / rate,
    }


def format_status(status: dict) -> str:
    """:func:`grid_status` as text: a line per job, the counts by framework, the time left."""
    lines = []
    for name, state, frames in status["jobs"]:  # a job running now has checkpoints as well
        label = {"done": "finished", "new": "not started"}.get(state, "started")
        if state == "stopped" and frames:
            label = f"checkpoint at {frames:,} frames"
        lines.append(f"  {label:<30} {name}")
    lines.append(
        f"finished {status['finished']} of {status['total']}; by framework "
        "(finished / started / not started):"
    )
    for framework, count in status["counts"].items():
        if sum(count.values()):
            lines.append(f"  {framework:<14} {count['done']} / {count['stopped']} / {count['new']}")
    rate = status["rate_per_hour"]
    if not math.isnan(rate):
        lines.append(
            f"at the sittings' rate so far ({rate:.2f} jobs per hour) the jobs not "
            f"finished take about {status['hours_left']:.1f} h"
        )
    elif status["sittings"]:
        lines.append("the sittings recorded have finished no job yet: no estimate of the time left")
    else:
        lines.append(
            "no sitting recorded (the results store, store=..., records them): no "
            "estimate of the time left"
        )
    return "\n".join(lines)
