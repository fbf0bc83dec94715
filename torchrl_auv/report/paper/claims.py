"""The paper's claims (§IV), each judged from our runs by a stated rule.

A claim is a set of comparisons the paper says hold (``A`` is better than ``B`` in a metric,
or a number is close to the paper's). Each comparison of means over seeds has an outcome,
against the noise: the standard error of the difference ``sqrt(sa^2/na + sb^2/nb)``, ``n``
the seeds with a finite value (one standard error: a lenient bar with three seeds):

- ``"holds"``: the paper's way by more than the noise (two or more seeds each side);
- ``"within noise"``: the paper's way by no more than the noise (or with one seed);
- ``"reversed within noise"``: the other way by no more than the noise (or with one seed);
- ``"reversed"``: the other way by more than the noise;
- ``"missing"``: a side has no finished job yet.

A closeness comparison holds when the ratio of ours to the paper's is within its stated
tolerance, and is reversed otherwise. A claim's verdict (:func:`verdict`) over its
comparisons that ran: every one holds: ``"reproduced"``; none holds and one or more is
reversed: ``"not reproduced"``; none is beyond the noise either way: ``"inconclusive"``;
else ``"partly"``; none ran: ``"not run yet"``. With comparisons missing the verdict says how
many ran. The rules are fixed here, before the results: no threshold is chosen per claim.

Examples:
    >>> compare((5.0, 0.5, 3), (2.0, 0.5, 3), higher=True)
    'holds'
    >>> compare((2.1, 0.5, 3), (2.0, 0.5, 3), higher=True)
    'within noise'
    >>> compare((1.9, 0.5, 3), (2.0, 0.5, 3), higher=True)
    'reversed within noise'
    >>> compare((1.0, 0.1, 3), (2.0, 0.1, 3), higher=True)
    'reversed'
    >>> verdict(["holds", "holds", "missing"])
    'reproduced (2 of 3 comparisons ran)'
    >>> verdict(["holds", "reversed"]), verdict(["reversed", "within noise"])
    ('partly', 'not reproduced')
    >>> verdict(["within noise", "reversed within noise"]), verdict(["missing"])
    ('inconclusive', 'not run yet')
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from itertools import pairwise
from pathlib import Path

from torchrl_auv.report.paper.figures import lyapunov_trace, tenth_means
from torchrl_auv.report.paper.grid import (
    ALPHAS,
    CONTROLLERS,
    FIXED_ALPHA,
    FIXED_FORM,
    FORMS,
    MAIN_SEA,
    SEAS,
    Job,
)
from torchrl_auv.report.paper.output import mean_std, metric_value, read_eval
from torchrl_auv.report.paper.tables import LABELS

__all__ = ["CLAIMS", "OUTCOMES", "Claim", "compare", "judge", "verdict"]

#: (mean, std over seeds, runs)
Stat = tuple[float, float, int]
#: A comparison's outcomes (module docstring), in the order the results page counts them.
OUTCOMES = ("holds", "within noise", "reversed within noise", "reversed", "missing")
#: a closeness comparison holds within this factor of the paper's number (half a decade: the
#: same order of magnitude)
CLOSE_FACTOR = math.sqrt(10.0)
#: "comparable" (the paper's word for EC across the diffusion frameworks): within 10 % of
#: their mean
COMPARABLE = 0.10


def compare(a: Stat, b: Stat, *, higher: bool) -> str:
    """Whether ``a`` beats ``b`` (``higher``: a larger mean is better): the module's outcomes."""
    (ma, sa, na), (mb, sb, nb) = a, b
    if not (na and nb and math.isfinite(ma) and math.isfinite(mb)):
        return "missing"
    gap = (ma - mb) if higher else (mb - ma)
    beyond = na >= 2 and nb >= 2 and abs(gap) > math.sqrt(sa**2 / na + sb**2 / nb)
    if gap > 0:
        return "holds" if beyond else "within noise"
    return "reversed" if beyond else "reversed within noise"


def close(ours: Stat, paper: float, factor: float = CLOSE_FACTOR) -> str:
    """Whether our mean is within ``factor`` of the paper's number."""
    mean, _, runs = ours
    if not runs or not math.isfinite(mean):
        return "missing"
    ratio = mean / paper
    return "holds" if 1.0 / factor <= ratio <= factor else "reversed"


def verdict(outcomes: Sequence[str]) -> str:
    """A claim's verdict from its comparisons' outcomes (module docstring)."""
    ran = [o for o in outcomes if o != "missing"]
    if not ran:
        return "not run yet"
    if all(o == "holds" for o in ran):
        word = "reproduced"
    elif "holds" not in ran and "reversed" in ran:
        word = "not reproduced"
    elif "holds" not in ran:
        word = "inconclusive"
    else:
        word = "partly"
    if len(ran) < len(outcomes):
        word += f" ({len(ran)} of {len(outcomes)} comparisons ran)"
    return word


@dataclass(frozen=True)
class Claim:
    """One claim of the paper: its words (paraphrased), where (figure or table), and the
    comparisons that decide it: ``check(root, seeds) -> [(outcome, our numbers)]``."""

    text: str
    where: str
    check: Callable[[Path, Sequence[int]], list[tuple[str, str]]]


def _stat(
    root: Path,
    framework: str,
    sea: str,
    controller: str,
    seeds: Sequence[int],
    metric: str,
    *,
    policy: str | None = None,
    variant: str = "",
) -> Stat:
    """Mean, std and count over the seeds whose finished job has a finite ``metric`` in the
    row of ``policy`` (``None``: the job's own framework). ``"return"``: minus the cost per
    AUV-decision times the decisions of the episode (the Fig. 8/9 table's)."""
    values = []
    for seed in seeds:
        job = Job(framework, sea, controller, seed, variant)
        row = (read_eval(root, job) or {}).get(policy or framework)
        if row is None:
            continue
        value = metric_value(row, metric)
        if math.isfinite(value):
            values.append(value)
    mean, std = mean_std(values)
    return mean, std, len(values)


def _fmt(stat: Stat) -> str:
    mean, std, runs = stat
    if not (runs and math.isfinite(mean)):
        return "-"
    return f"{mean:.3g} (one seed)" if runs == 1 else f"{mean:.3g} ± {std:.2g}"


def _pair(name_a: str, a: Stat, name_b: str, b: Stat, *, higher: bool) -> tuple[str, str]:
    return compare(a, b, higher=higher), f"{name_a} {_fmt(a)} vs {name_b} {_fmt(b)}"


def _fig4(root: Path, seeds: Sequence[int]) -> list[tuple[str, str]]:
    path = root / "report" / "fig4" / "fig4.json"
    rows = json.loads(path.read_text())["rows"] if path.exists() else []
    found = []
    for row in rows:
        stat = (row["heldout_loss"], row["heldout_loss_std"], row["runs"])
        found.append((close(stat, 3e-2), f"{row['sea_state']} {_fmt(stat)}"))
    return found or [("missing", "-")]


def _versus_sac(metric: str, higher: bool):
    def check(root: Path, seeds: Sequence[int]) -> list[tuple[str, str]]:
        out = []
        for sea in SEAS:
            sac = _stat(root, "sac", sea, "s_surface", seeds, metric)
            for framework in ("diffusion_rl", "diffusion_lac"):
                ours = _stat(root, framework, sea, "s_surface", seeds, metric)
                name = f"{sea}: {LABELS[framework]}"
                out.append(_pair(name, ours, "RL", sac, higher=higher))
        return out

    return check


def _lac_over_rl(controllers: Sequence[str]):
    """Diffusion+RL (LAC) against Diffusion+RL in SDR and SSN, per controller, ES and VES."""

    def check(root: Path, seeds: Sequence[int]) -> list[tuple[str, str]]:
        out = []
        for controller in controllers:
            for sea in ("es", "ves"):
                for metric in ("sdr_mbit", "ssn"):
                    lac = _stat(root, "diffusion_lac", sea, controller, seeds, metric)
                    rl = _stat(root, "diffusion_rl", sea, controller, seeds, metric)
                    where = f"{controller} " if len(controllers) > 1 else ""
                    name = f"{where}{sea} {metric}: LAC"
                    out.append(_pair(name, lac, "Diffusion+RL", rl, higher=True))
        return out

    return check


def _ec_comparable(root: Path, seeds: Sequence[int]) -> list[tuple[str, str]]:
    out = []
    for sea in SEAS:
        lac = _stat(root, "diffusion_lac", sea, "s_surface", seeds, "ec_w")
        rl = _stat(root, "diffusion_rl", sea, "s_surface", seeds, "ec_w")
        text = f"{sea}: LAC {_fmt(lac)} vs Diffusion+RL {_fmt(rl)} W"
        if not (lac[2] and rl[2] and lac[0] + rl[0] > 0):  # NaN compares False
            out.append(("missing", text))
            continue
        gap = abs(lac[0] - rl[0]) / (0.5 * (lac[0] + rl[0]))
        out.append(("holds" if gap <= COMPARABLE else "reversed", f"{text} ({gap:.0%} apart)"))
    return out


def _faster_start(root: Path, seeds: Sequence[int]) -> list[tuple[str, str]]:
    """The first point of the evaluation curves (Fig. 7) after training began (frame 0 is
    before any update: the pretrained proposer against an untrained actor): the diffusion
    frameworks' cost below RL's, each sea."""
    path = root / "report" / "fig7" / "fig7.json"
    rows = json.loads(path.read_text())["rows"] if path.exists() else []
    first: dict[tuple[str, str], Stat] = {}
    for row in sorted(rows, key=lambda r: r["frames"]):
        if row["metric"] == "eval/cost_mean" and row["frames"] > 0:
            key = (row["sea_state"], row["framework"])
            first.setdefault(key, (row["value"], row["value_std"], row["runs"]))
    out = []
    for sea in SEAS:
        sac = first.get((sea, LABELS["sac"]), (math.nan, math.nan, 0))
        for framework in ("diffusion_rl", "diffusion_lac"):
            ours = first.get((sea, LABELS[framework]), (math.nan, math.nan, 0))
            out.append(_pair(f"{sea}: {LABELS[framework]}", ours, "RL", sac, higher=False))
    return out


def _s_surface_first(
    frameworks: Sequence[str], seas: Sequence[str], metrics: Sequence[str], *, higher: bool
):
    """S-Surface against PID and against SMC, per framework, sea and metric."""

    def check(root: Path, seeds: Sequence[int]) -> list[tuple[str, str]]:
        out = []
        for framework in frameworks:
            for sea in seas:
                for metric in metrics:
                    best = _stat(root, framework, sea, "s_surface", seeds, metric)
                    for other in ("pid", "smc"):
                        them = _stat(root, framework, sea, other, seeds, metric)
                        name = f"{LABELS[framework]} {sea} {metric}: S-Surface"
                        out.append(_pair(name, best, other.upper(), them, higher=higher))
        return out

    return check


def _smc_degrades(root: Path, seeds: Sequence[int]) -> list[tuple[str, str]]:
    out = []
    for framework in ("diffusion_rl", "diffusion_lac"):
        es = _stat(root, framework, "es", "smc", seeds, "ssn")
        ves = _stat(root, framework, "ves", "smc", seeds, "ssn")
        out.append(_pair(f"{LABELS[framework]} SMC SSN: es", es, "ves", ves, higher=True))
    return out


TRACKING = ("heading_error_mean", "depth_error_mean")


def _tracking_lac_best(root: Path, seeds: Sequence[int]) -> list[tuple[str, str]]:
    out = []
    for metric in TRACKING:
        lac = _stat(root, "diffusion_lac", MAIN_SEA, "s_surface", seeds, metric)
        for framework in ("sac", "diffusion", "diffusion_rl"):
            them = _stat(root, framework, MAIN_SEA, "s_surface", seeds, metric)
            out.append(_pair(f"{metric}: LAC", lac, LABELS[framework], them, higher=False))
    return out


def _rank(root: Path, seeds: Sequence[int], policy: str, metric: str) -> Stat:
    return _stat(root, "diffusion_lac", MAIN_SEA, "s_surface", seeds, metric, policy=policy)


def _ranks_monotone(root: Path, seeds: Sequence[int]) -> list[tuple[str, str]]:
    order = ("OA", "CA1", "CA2", "CA3", "CA4")
    return [
        _pair(a, _rank(root, seeds, a, "return"), b, _rank(root, seeds, b, "return"), higher=True)
        for a, b in pairwise(order)
    ]


def _oa_best(root: Path, seeds: Sequence[int]) -> list[tuple[str, str]]:
    out = []
    for metric in ("sdr_mbit", "ssn"):
        oa = _rank(root, seeds, "OA", metric)
        for other in ("CA1", "CA2", "CA3", "CA4", "RL"):
            name = "RL (LAC)" if other == "RL" else other
            out.append(
                _pair(f"{metric}: OA", oa, name, _rank(root, seeds, other, metric), higher=True)
            )
    return out


def _contraction_ratio(root: Path, seeds: Sequence[int], variant: str) -> Stat:
    """The Lyapunov value's mean over the last tenth of the held-out episodes over its mean
    over the first tenth (lower: contracts more), per seed (``lyapunov_trace.csv``; the
    decisions weighed by their episodes running, :func:`tenth_means`)."""
    ratios = []
    for seed in seeds:
        trace = lyapunov_trace(root, Job("diffusion_lac", MAIN_SEA, "s_surface", seed, variant))
        first, last = (math.nan, math.nan) if trace is None else tenth_means(trace)
        if first > 0:
            ratios.append(last / first)
    mean, std = mean_std(ratios)
    return mean, std, len(ratios)


def _contraction(pairs: Sequence[tuple[str, str]]):
    """``pairs`` of variants (``fixed-<form>-alpha<alpha>``): the first contracts more."""

    def check(root: Path, seeds: Sequence[int]) -> list[tuple[str, str]]:
        out = []
        for a, b in pairs:
            ra, rb = _contraction_ratio(root, seeds, a), _contraction_ratio(root, seeds, b)
            out.append(
                _pair(a.removeprefix("fixed-"), ra, b.removeprefix("fixed-"), rb, higher=False)
            )
        return out

    return check


def _advisor(root: Path, seeds: Sequence[int]) -> list[tuple[str, str]]:
    fixed = _stat(
        root,
        "diffusion_lac",
        MAIN_SEA,
        "s_surface",
        seeds,
        "cost_mean",
        variant="fixed-softplus-alpha0.1",
    )
    out = [
        _pair(
            "rule-based advisor",
            _stat(root, "diffusion_lac", MAIN_SEA, "s_surface", seeds, "cost_mean"),
            "fixed spec",
            fixed,
            higher=False,
        )
    ]
    llm = _stat(root, "diffusion_lac", MAIN_SEA, "s_surface", seeds, "cost_mean", variant="openai")
    if llm[2]:
        out.append(_pair("LLM advisor", llm, "fixed spec", fixed, higher=False))
    return out


_ALPHA_PAIRS = [
    (f"fixed-{FIXED_FORM}-alpha{b}", f"fixed-{FIXED_FORM}-alpha{a}") for a, b in pairwise(ALPHAS)
]
_SQUARED = f"fixed-squared-alpha{FIXED_ALPHA}"
_FORM_PAIRS = [
    (_SQUARED, f"fixed-{form}-alpha{FIXED_ALPHA}") for form in FORMS if form != "squared"
]

#: The claims of §IV that our runs can decide, in the paper's order.
CLAIMS = [
    Claim(
        "The proposer's denoising loss settles around 3e-2 (per sea: within a factor √10)",
        "Fig. 4",
        _fig4,
    ),
    Claim(
        "Diffusion+RL and Diffusion+RL (LAC) reach a better return than RL (lower cost per "
        "AUV-decision), in every sea",
        "Fig. 7",
        _versus_sac("cost_mean", higher=False),
    ),
    Claim(
        "... and deliver more data (SDR) than RL, in every sea",
        "Fig. 7",
        _versus_sac("sdr_mbit", higher=True),
    ),
    Claim(
        "... and serve more sensor nodes (SSN) than RL, in every sea",
        "Fig. 7",
        _versus_sac("ssn", higher=True),
    ),
    Claim(
        "... and converge faster than RL (a lower cost at the first evaluation after frame 0)",
        "Fig. 7",
        _faster_start,
    ),
    Claim(
        "LAC adds an improvement over Diffusion+RL under ES and VES (SDR, SSN)",
        "Fig. 7",
        _lac_over_rl(("s_surface",)),
    ),
    Claim(
        "EC is comparable across the diffusion frameworks (within 10 %)", "Fig. 7", _ec_comparable
    ),
    Claim(
        "S-Surface gives the highest SDR and SSN of the three controllers",
        "Table II",
        _s_surface_first(
            ("diffusion_rl", "diffusion_lac"), ("es", "ves"), ("sdr_mbit", "ssn"), higher=True
        ),
    ),
    Claim("SMC degrades severely from ES to VES (SSN)", "Table II", _smc_degrades),
    Claim(
        "LAC improves SDR and SSN with every controller in both seas",
        "Table II",
        _lac_over_rl(CONTROLLERS),
    ),
    Claim(
        "S-Surface has the lowest yaw and depth errors in every framework",
        "Table III",
        _s_surface_first(tuple(LABELS), (MAIN_SEA,), TRACKING, higher=False),
    ),
    Claim(
        "Diffusion+RL (LAC) with S-Surface has the lowest errors of the frameworks (the "
        "paper's own Table III has RL (Baseline)'s mean yaw error, 0.10, below it, 0.11)",
        "Table III",
        _tracking_lac_best,
    ),
    Claim("The return falls monotonically from OA through CA1 to CA4", "Fig. 8", _ranks_monotone),
    Claim(
        "OA has the highest SDR and SSN of the six strategies, RL (LAC) included",
        "Fig. 9",
        _oa_best,
    ),
    Claim(
        "A larger stability weight alpha contracts the Lyapunov value more (last tenth of "
        "an episode over its first, per seed)",
        "Fig. 10",
        _contraction(_ALPHA_PAIRS),
    ),
    Claim(
        "The squared form contracts the Lyapunov value the most",
        "Fig. 11",
        _contraction(_FORM_PAIRS),
    ),
    Claim(
        "Adapting the Lyapunov spec during training beats a fixed spec (cost)",
        "§IV, advisor ablation",
        _advisor,
    ),
]


def judge(root: str | Path, seeds: Sequence[int]) -> list[dict[str, object]]:
    """Every claim of :data:`CLAIMS` judged from the jobs (and the report) under ``root``:
    rows of ``claim``, ``where``, ``verdict``, ``comparisons`` [(outcome, numbers)]."""
    root = Path(root)
    rows = []
    for claim in CLAIMS:
        found = claim.check(root, list(seeds))
        rows.append(
            {
                "claim": claim.text,
                "where": claim.where,
                "verdict": verdict([o for o, _ in found]),
                "comparisons": found,
            }
        )
    return rows
