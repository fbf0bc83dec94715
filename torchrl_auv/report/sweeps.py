"""One table from a sweep's run folders: every ``eval.csv``, grouped by the sweep's axes.

A sweep (``recipes/sweeps/``) writes one folder per job, each with ``eval.csv`` (a row per
evaluation sea state and policy) and Hydra's ``.hydra/overrides.yaml`` (the job's values).
:func:`load_runs` reads them all; the *axes* are the override keys whose values differ
between jobs. :func:`aggregate` groups the rows by the axes other than ``over`` (the seed, by
default), the evaluation sea state and the policy, and gives each metric's mean, standard
deviation (``ddof=1``; NaN for one run: a spread not measured, not a spread of 0) and the
number of runs. By default only each job's own
framework is kept (the row whose policy is named after ``framework``); ``policies`` picks
others (``"expert"``, ``"random"``, ``"OA"``, ...).

Examples:
    >>> import tempfile, pathlib
    >>> root = pathlib.Path(tempfile.mkdtemp())
    >>> for seed, ssn in ((0, 4.0), (1, 6.0)):
    ...     job = root / f"sac/seed{seed}"
    ...     (job / ".hydra").mkdir(parents=True)
    ...     _ = (job / ".hydra/overrides.yaml").write_text(f"- framework=sac\\n- seed={seed}\\n")
    ...     _ = (job / "eval.csv").write_text(f"sea_state,policy,ssn\\nideal,sac,{ssn}\\n")
    >>> rows = aggregate(load_runs(root), metrics=("ssn",))
    >>> rows[0]["policy"], rows[0]["runs"], rows[0]["ssn"], round(rows[0]["ssn_std"], 3)
    ('sac', 2, 5.0, 1.414)
    >>> print(markdown_table(rows, metrics=("ssn",)))
    | framework | sea_state | policy | runs | ssn |
    |---|---|---|---|---|
    | sac | ideal | sac | 2 | 5 ± 1.41 |
"""

from __future__ import annotations

import csv
import math
import statistics
from collections.abc import Sequence
from pathlib import Path

import yaml

__all__ = [
    "DEFAULT_METRICS",
    "aggregate",
    "load_runs",
    "markdown_table",
    "mean_std_text",
    "parse_number",
]

#: The metrics the table shows by default (eval.csv has more: pass ``metrics=``).
DEFAULT_METRICS = ("sdr_mbit", "ssn", "ec_w", "collisions", "violation_rate", "cost_mean",
                   "heading_error_mean", "depth_error_mean")  # fmt: skip


#: Overrides that say where a job writes, not what it ran: never an axis of a table.
LOCATION_KEYS = ("run_dir", "run_root", "resume", "proposer.cache_dir")


def _job_values(run: Path) -> dict[str, str]:
    """The job's ``key=value`` overrides (``+``/``~`` prefixes dropped; Hydra's own and
    :data:`LOCATION_KEYS` skipped)."""
    path = run / ".hydra" / "overrides.yaml"
    if not path.exists():
        return {}
    values = {}
    for item in yaml.safe_load(path.read_text()) or ():
        key, sep, value = str(item).lstrip("+~").partition("=")
        if sep and not key.startswith("hydra") and key not in LOCATION_KEYS:
            values[key] = value
    return values


def load_runs(root: str | Path) -> list[dict]:
    """Every row of every ``eval.csv`` under ``root``, each with its job's values (the keys
    that differ between jobs), ``run`` (the folder relative to ``root``) and, where the job
    set one, ``framework``. Numbers are floats. Raises ``FileNotFoundError`` naming ``root``
    when it holds no ``eval.csv``."""
    root = Path(root)
    runs = sorted(path.parent for path in root.rglob("eval.csv"))
    if not runs:
        raise FileNotFoundError(f"no eval.csv under {root} (is it a sweep's run folder?)")
    values = {run: _job_values(run) for run in runs}
    keys = sorted({key for found in values.values() for key in found})
    axes = [key for key in keys if len({found.get(key) for found in values.values()}) > 1]
    rows = []
    for run in runs:
        with open(run / "eval.csv", newline="") as handle:
            for row in csv.DictReader(handle):
                parsed = {key: parse_number(value) for key, value in row.items()}
                parsed.update({axis: values[run].get(axis, "") for axis in axes})
                parsed["run"] = str(run.relative_to(root))
                if "framework" in values[run]:
                    parsed["framework"] = values[run]["framework"]
                rows.append(parsed)
    return rows


def parse_number(text: str):
    """``text`` as a float when it is one, else unchanged (a CSV cell)."""
    try:
        return float(text)
    except ValueError:
        return text


def aggregate(
    rows: Sequence[dict],
    *,
    over: str = "seed",
    metrics: Sequence[str] = DEFAULT_METRICS,
    policies: Sequence[str] | None = None,
) -> list[dict]:
    """Rows grouped by the axes (but ``over``), ``sea_state`` and ``policy``: ``runs`` and,
    per metric, ``<metric>`` (mean) and ``<metric>_std``. ``policies=None`` keeps each job's
    own framework (all rows when the jobs set none)."""
    axes = [key for key in rows[0] if key not in (over, "run", "sea_state", "policy")
            and not isinstance(rows[0][key], float)] if rows else []  # fmt: skip
    groups: dict[tuple, list[dict]] = {}
    for row in rows:
        own = row.get("framework")
        if policies is None and own is not None and row["policy"] != own:
            continue
        if policies is not None and row["policy"] not in policies:
            continue
        key = (*(row.get(axis, "") for axis in axes), row["sea_state"], row["policy"])
        groups.setdefault(key, []).append(row)
    table = []
    for key, members in groups.items():
        out = dict(zip((*axes, "sea_state", "policy"), key, strict=True))
        out["runs"] = len(members)
        for metric in metrics:
            numbers = [m[metric] for m in members if isinstance(m.get(metric), float)]
            out[metric] = statistics.fmean(numbers) if numbers else math.nan
            out[f"{metric}_std"] = statistics.stdev(numbers) if len(numbers) > 1 else math.nan
        table.append(out)
    return table


def markdown_table(table: Sequence[dict], *, metrics: Sequence[str] = DEFAULT_METRICS) -> str:
    """``table`` (:func:`aggregate`) as Markdown, each metric as ``mean ± std`` (``mean (one
    run)`` where a single run measured no spread)."""
    if not table:
        return "(no rows)"
    labels = [key for key in table[0] if key not in metrics and not key.endswith("_std")]
    lines = ["| " + " | ".join([*labels, *metrics]) + " |",
             "|" + "---|" * (len(labels) + len(metrics))]  # fmt: skip
    for row in table:
        cells = [str(row[label]) for label in labels]
        cells += [mean_std_text(row[m], row[f"{m}_std"]) for m in metrics]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def mean_std_text(mean: float, std: float, single: str = "one run") -> str:
    """``mean ± std`` to 3 significant digits; ``mean (<single>)`` where a finite mean has no
    finite spread (one value measured none, which ``± 0`` would claim)."""
    if math.isfinite(mean) and not math.isfinite(std):
        return f"{mean:.3g} ({single})"
    return f"{mean:.3g} ± {std:.3g}"
