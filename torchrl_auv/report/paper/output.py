"""Reading the jobs of a grid and writing one experiment's tables (Markdown, CSV, JSON).

Examples:
    >>> import tempfile, pathlib
    >>> out = pathlib.Path(tempfile.mkdtemp())
    >>> rows = [{"framework": "sac", "ssn": 4.0, "ssn_std": 1.0, "runs": 2}]
    >>> paths = write_table(out, "demo", rows, ["framework", "runs", "ssn"],
    ...                     header="budget quick, seeds [0, 1]")
    >>> [p.name for p in paths]
    ['demo.md', 'demo.csv', 'demo.json']
    >>> print((out / "demo.md").read_text().splitlines()[2])
    | framework | runs | ssn |
    >>> print((out / "demo.md").read_text().splitlines()[4])
    | sac | 2 | 4 ± 1 |
"""

from __future__ import annotations

import csv
import json
import math
import statistics
from collections.abc import Mapping, Sequence
from pathlib import Path

from torchrl_auv.report.paper.grid import Job
from torchrl_auv.report.paper.store import RECORDS
from torchrl_auv.report.sweeps import mean_std_text, parse_number

__all__ = [
    "first_stage_folder",
    "first_stage_pattern",
    "job_rows",
    "mean_std",
    "metric_value",
    "read_eval",
    "window_means",
    "write_table",
]


def first_stage_pattern(sea: str, seed: int, controller: str = "s_surface") -> str:
    """The glob pattern of the artefact folders of (``sea``, ``controller``, ``seed``)'s first
    stage (``<sea>-<controller>-<rate model>-seed<seed>-<hash>``, any rate model)."""
    return f"{sea}-{controller}-*-seed{seed}-*"


def first_stage_folder(
    root: Path, sea: str, seed: int, *, controller: str = "s_surface", records: bool = False
) -> Path | None:
    """The built first stage of (``sea``, ``controller``, ``seed``) under
    ``root/first_stage`` (the grid's runs share it), ``None`` when none is built.
    ``records``: else its record restored from a results store (``root/first_stage_records``,
    its training losses without the proposer, :mod:`~torchrl_auv.report.paper.store`)."""
    pattern = first_stage_pattern(sea, seed, controller)
    found = sorted((Path(root) / "first_stage").glob(pattern))
    found = [f for f in found if (f / "proposer.pt").exists()]
    if not found and records:
        found = sorted((Path(root) / RECORDS).glob(pattern))
        found = [f for f in found if (f / "pretrain_loss.csv").exists()]
    return found[-1] if found else None


def read_eval(root: Path, job: Job) -> dict[str, dict[str, object]] | None:
    """The job's ``eval.csv`` as ``{policy: row}`` (numbers as floats), ``None`` when the job
    has not finished."""
    path = Path(root) / "jobs" / job.name / "eval.csv"
    if not path.exists():
        return None
    with open(path, newline="") as handle:
        return {
            row["policy"]: {k: parse_number(v) for k, v in row.items()}
            for row in csv.DictReader(handle)
        }


def mean_std(values: Sequence[float]) -> tuple[float, float]:
    """Mean and sample standard deviation of the finite values (NaN for none; the std NaN
    for one: one value has no spread to state, which a 0 would claim)."""
    values = [v for v in values if isinstance(v, float) and math.isfinite(v)]
    if not values:
        return math.nan, math.nan
    return statistics.fmean(values), statistics.stdev(values) if len(values) > 1 else math.nan


def metric_value(row: Mapping, metric: str) -> float:
    """``metric`` of an ``eval.csv`` row (NaN where it has none). ``"return"``: the episode
    return per AUV, minus the cost per AUV-decision times the decisions of the episode (the
    scenes' means of each: exact where every scene ran the same number of decisions)."""
    if metric == "return":
        value = -row.get("cost_mean", math.nan) * row.get("decisions", math.nan)
    else:
        value = row.get(metric, math.nan)
    return value if isinstance(value, float) else math.nan


def window_means(curves: dict, key: str, window: int) -> tuple[float, float] | None:
    """The mean of ``key`` (of :func:`~torchrl_auv.report.curves.read_curve`'s ``curves``)
    over the batches logged at frames ``<= window`` and over those after ``last - window``
    (NaN where the curve is shorter than two windows: they would overlap); ``None`` when the
    curve does not log ``key``."""
    steps, values = curves.get(key, ([], []))
    if not steps:
        return None
    first = [v for s, v in zip(steps, values, strict=True) if s <= window]
    last = [v for s, v in zip(steps, values, strict=True) if s > steps[-1] - window]
    return (
        mean_std(first)[0] if first else math.nan,
        mean_std(last)[0] if steps[-1] >= 2 * window else math.nan,
    )


def job_rows(
    root: Path, jobs: Sequence[Job], policy: str | None, metrics: Sequence[str]
) -> dict[str, object]:
    """Over ``jobs`` (the seeds of one cell): ``runs`` (finished jobs), ``seeds`` and, per
    metric, ``<metric>`` (mean) and ``<metric>_std`` of the ``policy`` row (``None``: the
    job's own framework; a metric of :func:`metric_value`, ``"return"`` included: each job's
    own value, then the mean and std over the jobs)."""
    found = [(job, read_eval(root, job)) for job in jobs]
    found = [(job, rows.get(policy or job.framework)) for job, rows in found if rows]
    found = [(job, row) for job, row in found if row is not None]
    out: dict[str, object] = {"runs": len(found), "seeds": [job.seed for job, _ in found]}
    for metric in metrics:
        mean, std = mean_std([metric_value(row, metric) for _, row in found])
        out[metric], out[f"{metric}_std"] = mean, std
    return out


def _cell(row: Mapping, column: str) -> str:
    value = row.get(column, "")
    if isinstance(value, float):
        std = row.get(f"{column}_std")
        return f"{value:.3g}" if std is None else mean_std_text(value, std, "one seed")
    return str(value)


def write_table(
    out_dir: str | Path,
    name: str,
    rows: Sequence[Mapping],
    columns: Sequence[str],
    *,
    header: str,
    extra: Mapping | None = None,
) -> list[Path]:
    """``<name>.md`` (``header`` line, then ``columns`` with ``mean ± std`` cells),
    ``<name>.csv`` (every key of the rows) and ``<name>.json`` (the header, the rows and
    ``extra``) under ``out_dir``. Returns the three paths."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    lines = [header, "", "| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(_cell(row, c) for c in columns) + " |" for row in rows]
    md = out_dir / f"{name}.md"
    md.write_text("\n".join(lines) + "\n")
    keys = list(dict.fromkeys(k for row in rows for k in row))
    path_csv = out_dir / f"{name}.csv"
    with open(path_csv, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=keys)
        writer.writeheader()
        writer.writerows(rows)
    path_json = out_dir / f"{name}.json"
    path_json.write_text(
        json.dumps({"header": header, "rows": list(rows), **(extra or {})}, indent=1, default=str)
    )
    return [md, path_csv, path_json]
