"""The RL stage against its own prior (our observation, not a claim of the paper).

Every Diffusion+RL and Diffusion+RL (LAC) job starts from a pretrained proposer (its first
stage) and evaluates that proposer acting alone on the same held-out scenes (the ``proposer
alone`` row of its ``eval.csv``). :func:`prior_counts` compares each finished job of the
grid's main cells (no variant: the ablations' variants share one proposer and would count it
again) with its own proposer alone: at frame 0 (the first point of ``eval_curve.csv``, on
the curve's ``eval.curve_envs`` scenes: critic and actor untrained) and at the end (the
job's own row, on the same scenes as the proposer alone's), counted per framework. A
difference counts when it exceeds :data:`MARGIN` of the proposer alone's value.

Examples:
    >>> import pathlib, tempfile
    >>> from torchrl_auv.report.paper.grid import Job
    >>> root = pathlib.Path(tempfile.mkdtemp())
    >>> job = Job("diffusion_rl", "es", "s_surface", 0)
    >>> (root / "jobs" / job.name).mkdir(parents=True)
    >>> _ = (root / "jobs" / job.name / "eval.csv").write_text(
    ...     "sea_state,policy,cost_mean,ssn\\nes,diffusion_rl,1.2,8\\nes,proposer alone,1.5,10\\n")
    >>> prior_counts(root, [job])["diffusion_rl"]["end_cheaper"]
    (1, 1)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

from torchrl_auv.report.curves import read_curve
from torchrl_auv.report.paper.grid import Job
from torchrl_auv.report.paper.output import read_eval
from torchrl_auv.report.paper.tables import LABELS

__all__ = ["FRAMEWORKS_WITH_PRIOR", "format_prior", "prior_counts"]

FRAMEWORKS_WITH_PRIOR = ("diffusion_rl", "diffusion_lac")
#: the relative difference a comparison needs to count (smaller ones are ties)
MARGIN = 0.01
#: count -> its row on the results page
ROWS = {
    "start_worse": "costs more than the proposer alone at frame 0 (critic and actor untrained)",
    "end_cheaper": "costs less than the proposer alone at the end",
    "end_fewer_ssn": "serves fewer nodes (SSN) than the proposer alone at the end",
}


def _frame0_cost(folder: Path) -> float:
    path = folder / "eval_curve.csv"
    if not path.exists():
        return math.nan
    steps, values = read_curve(path).get("eval/cost_mean", ([], []))
    return dict(zip(steps, values, strict=True)).get(0, math.nan)


def prior_counts(root: str | Path, jobs: Sequence[Job]) -> dict[str, dict]:
    """Per framework of :data:`FRAMEWORKS_WITH_PRIOR`: ``jobs`` (finished, no variant, with a
    ``proposer alone`` row) and, per key of :data:`ROWS`, ``(yes, compared)``: the jobs where
    it holds by more than :data:`MARGIN` and those where both numbers exist (a job without a
    frame-0 evaluation is left out of ``start_worse``). Cost per AUV-decision: lower is
    better."""
    counts = {f: {"jobs": 0, **{key: (0, 0) for key in ROWS}} for f in FRAMEWORKS_WITH_PRIOR}
    for job in jobs:
        if job.framework not in counts or job.variant:
            continue
        rows = read_eval(root, job)
        if not rows or "proposer alone" not in rows or job.framework not in rows:
            continue
        own, alone = rows[job.framework], rows["proposer alone"]
        cost, ssn = alone["cost_mean"], alone.get("ssn")
        tests = {  # (a, b, the proposer alone's value): holds when a - b > MARGIN * |value|
            "start_worse": (_frame0_cost(Path(root) / "jobs" / job.name), cost, cost),
            "end_cheaper": (cost, own["cost_mean"], cost),
            "end_fewer_ssn": (ssn, own.get("ssn"), ssn),
        }
        cell = counts[job.framework]
        cell["jobs"] += 1
        for key, (a, b, value) in tests.items():
            if isinstance(a, float) and isinstance(b, float) and math.isfinite(a + b):
                yes, compared = cell[key]
                cell[key] = (yes + (a - b > MARGIN * abs(value)), compared + 1)
    return counts


def format_prior(counts: dict[str, dict]) -> list[str]:
    """:func:`prior_counts` as the results page's Markdown lines."""
    if not any(cell["jobs"] for cell in counts.values()):
        return ["*Not yet: no Diffusion+RL or Diffusion+RL (LAC) job has finished.*"]
    names = [LABELS[f] for f in counts]
    lines = [f"| the RL stage ... | {' | '.join(names)} |", "|---" * (len(names) + 1) + "|"]
    for key, text in ROWS.items():
        cells = [f"{counts[f][key][0]} of {counts[f][key][1]}" for f in counts]
        lines.append(f"| {text} | {' | '.join(cells)} |")
    return lines
