"""The RL stage against its own prior (our observation, not a claim of the paper).

Every Diffusion+RL and Diffusion+RL (LAC) job starts from a pretrained proposer (its first
stage) and evaluates that proposer acting alone on the same held-out scenes (the ``proposer
alone`` row of its ``eval.csv``). :func:`prior_counts` compares each finished job of the
grid's main cells (no variant: the ablations' variants share one proposer and would count it
again) with its own proposer alone: at frame 0 (the first point of ``eval_curve.csv``, on
the curve's ``eval.curve_envs`` scenes: critic and actor untrained) and at the end (the
job's own row, on the same scenes as the proposer alone's), counted per framework. A
difference counts when it exceeds :data:`MARGIN` of the proposer alone's value.
:func:`extreme_shares` reads which candidates the selection executed while the job trained:
the share of AUV-decisions whose executed action is the largest or the smallest of the K
candidates' first actions, per action dimension (``train/selected_extreme_<d>`` of its
``train_curve.csv``), in its first and its last ``window`` frames.
:func:`cost_term_changes` splits each job's change of cost at the end (its row minus its
proposer alone's) by the cost's terms (:data:`COST_TERMS_V2`: the stored grid ran on the task
v2 cost, whose terms these are).

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
from torchrl_auv.report.paper.output import mean_std, read_eval, window_means
from torchrl_auv.report.paper.tables import LABELS
from torchrl_auv.report.sweeps import mean_std_text

__all__ = [
    "COST_TERMS_V2",
    "FRAMEWORKS_WITH_PRIOR",
    "cost_term_changes",
    "extreme_shares",
    "format_cost_term_changes",
    "format_extreme_shares",
    "format_prior",
    "prior_counts",
]

FRAMEWORKS_WITH_PRIOR = ("diffusion_rl", "diffusion_lac")
#: the relative difference a comparison needs to count (smaller ones are ties)
MARGIN = 0.01
#: count -> its row on the results page
ROWS = {
    "start_worse": "costs more than the proposer alone at frame 0 (critic and actor untrained)",
    "end_cheaper": "costs less than the proposer alone at the end",
    "end_fewer_ssn": "serves fewer nodes (SSN) than the proposer alone at the end",
}
#: the terms of the task v2 cost, the one the stored paper grid ran with (``share_<term>`` of its
#: ``eval.csv``); task v3 replaced it (:mod:`torchrl_auv.iout.reward`)
COST_TERMS_V2 = ("distance", "regress", "energy", "collision", "violation", "waiting", "overflow")
#: each task v2 cost term's row on the results page
TERM_ROWS = {
    "distance": "distance to the target",
    "regress": "moving away from the target",
    "energy": "energy",
    "collision": "collision",
    "violation": "violation (outside the area, or too near the seabed or the surface)",
    "waiting": "data waiting in the nodes",
    "overflow": "overflow (packets lost)",
    "total": "all terms (the cost)",
}
#: the action dimensions, in the order of ``train/selected_extreme_<d>``
ACTION_DIMS = ("depth", "heading", "propeller")


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


def extreme_shares(root: str | Path, jobs: Sequence[Job], window: int = 5000) -> dict:
    """Per framework of :data:`FRAMEWORKS_WITH_PRIOR` and action dimension of
    :data:`ACTION_DIMS`: ``jobs`` (finished, no variant, whose ``train_curve.csv`` logs
    ``train/selected_extreme_<d>``), ``first`` and ``last``: the mean and std over those jobs
    of each job's mean share in its first and its last ``window`` frames (the training
    batches: exploration on). A pick blind to the candidates' order gives ``2 / K``. (The
    proposer alone, framework ``diffusion``, logs it too, but over its own
    ``alone_candidates`` draws, so it is left out.)"""
    out = {
        f: {d: {"jobs": 0, "first": [], "last": []} for d in ACTION_DIMS}
        for f in FRAMEWORKS_WITH_PRIOR
    }
    for job in jobs:
        folder = Path(root) / "jobs" / job.name
        curve = folder / "train_curve.csv"
        if job.framework not in out or job.variant or not (folder / "eval.csv").exists():
            continue
        curves = read_curve(curve) if curve.exists() else {}
        for i, dim in enumerate(ACTION_DIMS):
            means = window_means(curves, f"train/selected_extreme_{i}", window)
            if means is not None:
                cell = out[job.framework][dim]
                cell["jobs"] += 1
                cell["first"].append(means[0])
                cell["last"].append(means[1])
    for cells in out.values():
        for cell in cells.values():
            cell["first"], cell["last"] = mean_std(cell["first"]), mean_std(cell["last"])
    return out


def format_extreme_shares(shares: dict, num_candidates: int, window: int = 5000) -> list[str]:
    """:func:`extreme_shares` as the results page's Markdown lines."""
    frameworks = [f for f in shares if any(c["jobs"] for c in shares[f].values())]
    if not frameworks:
        return [
            "*No job has logged which candidate it executed yet (`train/selected_extreme_<d>`).*"
        ]
    blind = 2 / num_candidates
    lines = [
        f"Which candidate was executed while the job trained: the share of AUV-decisions whose "
        f"executed action is the largest or the smallest of the K = {num_candidates} "
        f"candidates' first actions (`train/selected_extreme_<d>`; 2 / K = {blind:.2g} for a "
        f"pick blind to their order, somewhat more where candidates tie at an action bound), "
        f"each job's mean over its first and its last "
        f"{window:,} frames, then mean ± std over the finished jobs that log it.",
        "",
        f"| dimension, frames | {' | '.join(LABELS[f] for f in frameworks)} |",
        "|---" * (len(frameworks) + 1) + "|",
    ]
    jobs = [str(max(c["jobs"] for c in shares[f].values())) for f in frameworks]
    lines.append(f"| jobs | {' | '.join(jobs)} |")
    for dim in ACTION_DIMS:
        for part in ("first", "last"):
            values = [shares[f][dim][part] for f in frameworks]
            cells = [
                mean_std_text(*v, single="one job") if math.isfinite(v[0]) else "-" for v in values
            ]
            lines.append(f"| {dim}, {part} {window:,} | {' | '.join(cells)} |")
    return lines


def _term_costs(row: dict) -> dict[str, float] | None:
    """Each cost term per AUV-decision of an ``eval.csv`` row (its share of the cost times the
    cost) and ``total``; ``None`` where the row has no shares."""
    shares = [row.get(f"share_{term}") for term in COST_TERMS_V2]
    cost = row.get("cost_mean")
    if not all(isinstance(v, float) for v in [*shares, cost]):
        return None
    return {
        **{t: cost * share for t, share in zip(COST_TERMS_V2, shares, strict=True)},
        "total": cost,
    }


def cost_term_changes(root: str | Path, jobs: Sequence[Job]) -> dict[str, dict]:
    """Per framework of :data:`FRAMEWORKS_WITH_PRIOR`: where each finished job of the main
    cells (no variant) changed its cost at the end against its own proposer alone, term by
    term (cost per AUV-decision, the job's row minus its proposer alone's). A term's cost is
    its share of the evaluation's cost times the cost (``share_<term>`` x ``cost_mean`` of
    ``eval.csv``): exact where every scene ran to its end, so a job where either row ended a
    scene early (``terminated`` > 0: the termination cost is in no term) is left out and
    counted in ``ended_early``; a job whose ``eval.csv`` has no shares is left out.

    Returns ``{framework: {"jobs", "ended_early", <term or "total">: {"change": (mean, std)
    over the jobs, "lower": jobs where the term fell by more than MARGIN of the proposer
    alone's cost, "higher": where it rose by more}}}``."""
    out = {}
    for framework in FRAMEWORKS_WITH_PRIOR:
        changes: dict[str, list[float]] = {term: [] for term in TERM_ROWS}
        margins, ended_early = [], 0
        for job in jobs:
            rows = read_eval(root, job) if job.framework == framework and not job.variant else None
            if not rows or "proposer alone" not in rows or framework not in rows:
                continue
            own, alone = rows[framework], rows["proposer alone"]
            own_terms, alone_terms = _term_costs(own), _term_costs(alone)
            if own_terms is None or alone_terms is None:
                continue
            if own.get("terminated") != 0.0 or alone.get("terminated") != 0.0:
                ended_early += 1
                continue
            margins.append(MARGIN * abs(alone_terms["total"]))
            for term in TERM_ROWS:
                changes[term].append(own_terms[term] - alone_terms[term])
        cell = {"jobs": len(margins), "ended_early": ended_early}
        for term, values in changes.items():
            cell[term] = {
                "change": mean_std(values),
                "lower": sum(v < -m for v, m in zip(values, margins, strict=True)),
                "higher": sum(v > m for v, m in zip(values, margins, strict=True)),
            }
        out[framework] = cell
    return out


def format_cost_term_changes(changes: dict[str, dict]) -> list[str]:
    """:func:`cost_term_changes` as the results page's Markdown lines."""
    frameworks = [f for f, cell in changes.items() if cell["jobs"]]
    if not frameworks:
        return [
            "*No finished Diffusion+RL or Diffusion+RL (LAC) job has its cost split by term yet.*"
        ]
    left_out = sum(changes[f]["ended_early"] for f in changes)
    lines = [
        "Where the cost changed at the end: each job's cost per AUV-decision minus its "
        "proposer alone's, term by term (the term's share of the evaluation's cost times the "
        "cost; negative: the RL stage costs less), mean ± std over the jobs, and in how many "
        "jobs the term fell or rose by more than 1 % of the proposer alone's cost. Jobs where "
        "either policy ended a scene early are left out (the termination cost is in no term): "
        f"{left_out} job{'' if left_out == 1 else 's'} left out.",
        "",
        f"| cost term | {' | '.join(LABELS[f] for f in frameworks)} |",
        "|---" * (len(frameworks) + 1) + "|",
        f"| jobs | {' | '.join(str(changes[f]['jobs']) for f in frameworks)} |",
    ]
    for term, text in TERM_ROWS.items():
        cells = []
        for f in frameworks:
            cell, n = changes[f][term], changes[f]["jobs"]
            change = mean_std_text(*cell["change"], single="one job")
            cells.append(f"{change} (lower in {cell['lower']}, higher in {cell['higher']} of {n})")
        lines.append(f"| {text} | {' | '.join(cells)} |")
    return lines
