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

from torchrl_auv.report.intervals import interval, probability_of_improvement

__all__ = [
    "DEFAULT_METRICS",
    "LOWER_IS_BETTER",
    "aggregate",
    "compare",
    "comparison_table",
    "load_runs",
    "markdown_table",
    "mean_std_text",
    "parse_number",
]

#: The metrics the table shows by default (eval.csv has more: pass ``metrics=``).
DEFAULT_METRICS = (
    "sdr_mbit",
    "ssn",
    "ec_w",
    "collisions",
    "violation_rate",
    "cost_mean",
    "heading_error_mean",
    "depth_error_mean",
)


#: Metrics where a lower value is better (:func:`compare`'s probability of improvement).
LOWER_IS_BETTER = (
    "cost_mean",
    "discounted_cost_0.97",
    "discounted_cost_0.99",
    "ec_w",
    "collisions",
    "violation_rate",
    "terminated",
    "heading_error_mean",
    "depth_error_mean",
)


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


def _groups(
    rows: Sequence[dict], over: str, policies: Sequence[str] | None, also: Sequence[str] = ()
):
    """``(axes, {(*axis values, sea_state, policy): rows})``: :func:`aggregate`'s grouping;
    the rows of the policies in ``also`` are kept whatever ``policies`` keeps."""
    axes = (
        [
            key
            for key in rows[0]
            if key not in (over, "run", "sea_state", "policy")
            and not isinstance(rows[0][key], float)
        ]
        if rows
        else []
    )
    groups: dict[tuple, list[dict]] = {}
    for row in rows:
        policy, own = row["policy"], row.get("framework")
        shown = (own is None or policy == own) if policies is None else policy in policies
        if not (shown or policy in also):
            continue
        key = (*(row.get(axis, "") for axis in axes), row["sea_state"], row["policy"])
        groups.setdefault(key, []).append(row)
    return axes, groups


def _values(members: Sequence[dict], metric: str) -> list[float]:
    return [m[metric] for m in members if isinstance(m.get(metric), float)]


def aggregate(
    rows: Sequence[dict],
    *,
    over: str = "seed",
    metrics: Sequence[str] = DEFAULT_METRICS,
    policies: Sequence[str] | None = None,
    intervals: bool = False,
    reps: int = 2000,
) -> list[dict]:
    """Rows grouped by the axes (but ``over``), ``sea_state`` and ``policy``: ``runs`` and,
    per metric, ``<metric>`` (mean) and ``<metric>_std``. ``policies=None`` keeps each job's
    own framework (all rows when the jobs set none). ``intervals``: also the mean's 95 %
    stratified-bootstrap interval over runs, ``<metric>_low`` and ``<metric>_high``
    (:func:`torchrl_auv.report.intervals.interval`, ``reps`` resamples; NaN for one run)."""
    axes, groups = _groups(rows, over, policies)
    table = []
    for key, members in groups.items():
        out = dict(zip((*axes, "sea_state", "policy"), key, strict=True))
        out["runs"] = len(members)
        for metric in metrics:
            numbers = _values(members, metric)
            out[metric] = statistics.fmean(numbers) if numbers else math.nan
            out[f"{metric}_std"] = statistics.stdev(numbers) if len(numbers) > 1 else math.nan
            if intervals:
                found = interval(numbers, reps=reps) if len(numbers) > 1 else None
                out[f"{metric}_low"] = found.low if found else math.nan
                out[f"{metric}_high"] = found.high if found else math.nan
        table.append(out)
    return table


def compare(
    rows: Sequence[dict],
    *,
    axis: str,
    reference: str,
    over: str = "seed",
    metrics: Sequence[str] = DEFAULT_METRICS,
    policies: Sequence[str] | None = None,
    reps: int = 2000,
) -> list[dict]:
    """Each group whose ``axis`` is not ``reference`` against the group that has it (the same
    other axes, sea state and policy), metric by metric: its mean, the reference's mean and
    95 % interval over runs, whether the mean lies inside, and the probability that one of
    its runs improves on one of the reference's (lower is better for
    :data:`LOWER_IS_BETTER`), with its interval. ``axis="policy"``: each job's framework (or
    ``policies``) against another row of the same jobs, e.g. ``reference="proposer alone"``
    (the same runs on both sides, unpaired as rliable's probability of improvement is).
    Raises ``ValueError`` naming ``axis`` when the rows have no such axis or no group has
    ``reference``."""
    also = (reference,) if axis == "policy" else ()
    axes, groups = _groups(rows, over, policies, also)
    if axis not in (*axes, "policy"):
        raise ValueError(f"axis must be one of the runs' axes {axes} or policy, got {axis!r}")
    where = (*axes, "sea_state", "policy").index(axis)
    found = []
    for key, members in groups.items():
        if key[where] == reference:
            continue
        base_key = (*key[:where], reference, *key[where + 1 :])
        if base_key not in groups:
            continue
        for metric in metrics:
            x, y = _values(members, metric), _values(groups[base_key], metric)
            if len(x) < 1 or len(y) < 2:
                continue
            base = interval(y, reps=reps)
            sign = -1.0 if metric in LOWER_IS_BETTER else 1.0
            better = probability_of_improvement(
                [sign * v for v in x], [sign * v for v in y], reps=reps
            )
            mean = statistics.fmean(x)
            found.append(
                {
                    **dict(zip((*axes, "sea_state", "policy"), key, strict=True)),
                    "metric": metric,
                    "runs": len(x),
                    "mean": mean,
                    "reference_runs": len(y),
                    "reference": base,
                    "inside": mean in base,
                    "improvement": better,
                }
            )
    if not any(key[where] == reference for key in groups):
        raise ValueError(
            f"no group has {axis}={reference!r}: the reference must be one of "
            f"{sorted({key[where] for key in groups})}"
        )
    return found


def comparison_table(found: Sequence[dict]) -> str:
    """:func:`compare`'s result as Markdown."""
    if not found:
        return "(no pairs)"
    labels = [
        k
        for k in found[0]
        if k
        not in ("metric", "runs", "mean", "reference_runs", "reference", "inside", "improvement")
    ]
    head = [
        *labels,
        "metric",
        "runs",
        "mean",
        "reference runs",
        "reference mean [95 % CI]",
        "inside",
        "P(improvement) [95 % CI]",
    ]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for row in found:
        cells = [str(row[label]) for label in labels]
        cells += [
            row["metric"],
            str(row["runs"]),
            f"{row['mean']:.3g}",
            str(row["reference_runs"]),
            str(row["reference"]),
            "yes" if row["inside"] else "no",
            str(row["improvement"]),
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def markdown_table(table: Sequence[dict], *, metrics: Sequence[str] = DEFAULT_METRICS) -> str:
    """``table`` (:func:`aggregate`) as Markdown, each metric as ``mean ± std`` (``mean (one
    run)`` where a single run measured no spread)."""
    if not table:
        return "(no rows)"
    labels = [
        key
        for key in table[0]
        if key not in metrics and not key.endswith(("_std", "_low", "_high"))
    ]
    lines = [
        "| " + " | ".join([*labels, *metrics]) + " |",
        "|" + "---|" * (len(labels) + len(metrics)),
    ]
    for row in table:
        cells = [str(row[label]) for label in labels]
        cells += [_cell(row, m) for m in metrics]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _cell(row: dict, metric: str) -> str:
    low, high = row.get(f"{metric}_low", math.nan), row.get(f"{metric}_high", math.nan)
    if math.isfinite(low) and math.isfinite(high):
        return f"{row[metric]:.3g} [{low:.3g}, {high:.3g}]"
    return mean_std_text(row[metric], row[f"{metric}_std"])


def mean_std_text(mean: float, std: float, single: str = "one run") -> str:
    """``mean ± std`` to 3 significant digits; ``mean (<single>)`` where a finite mean has no
    finite spread (one value measured none, which ``± 0`` would claim)."""
    if math.isfinite(mean) and not math.isfinite(std):
        return f"{mean:.3g} ({single})"
    return f"{mean:.3g} ± {std:.3g}"
