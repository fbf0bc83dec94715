"""Every experiment's figures and tables under ``<root>/report/<experiment>/``.

Examples:
    >>> sorted(REPORTS)[:3]
    ['advisor', 'advisor_llm', 'fig10']
"""

from __future__ import annotations

import datetime
import json
import platform
import subprocess
from collections.abc import Callable, Mapping, Sequence
from functools import partial
from pathlib import Path

from torchrl_auv.report.paper import figures, tables

__all__ = ["REPORTS", "write_report"]

#: experiment -> ``(root, out_dir, seeds, header) -> written paths``
REPORTS: dict[str, Callable] = {
    "fig4": figures.fig4,
    "fig5_6": figures.fig5_6,
    "fig7": figures.fig7,
    "table2": tables.table2,
    "table3": tables.table3,
    "fig8_9": figures.fig8_9,
    "fig10": lambda root, out, seeds, header: (
        figures.fig10_11(root, out, seeds, header, "fig10")
        + tables.ablation_tables(root, out, seeds, header, "fig10")
    ),
    "fig11": lambda root, out, seeds, header: (
        figures.fig10_11(root, out, seeds, header, "fig11")
        + tables.ablation_tables(root, out, seeds, header, "fig11")
    ),
    "advisor": partial(tables.ablation_tables, experiment="advisor"),
    "advisor_llm": partial(tables.ablation_tables, experiment="advisor"),
    "lyapunov_cost": partial(tables.ablation_tables, experiment="lyapunov_cost"),
    "sampler": partial(tables.ablation_tables, experiment="sampler"),
}
#: the fixed-schedule tracking table per budget: runs per cell and seconds per run
TABLE3_FIXED = {"quick": (1, 20.0), "paper": (4, 300.0)}
#: the rate-model table per budget: held-out scenes per sea and decisions per scene
RATE_MODELS = {"quick": (2, 50), "paper": (4, 1000)}
#: the experiments that run no job (their own simulations, in the report)
STANDALONE = ("table3_fixed", "rate_models")


def _commit() -> str:
    try:
        return subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
            cwd=Path(__file__).parent,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def write_report(
    root: str | Path,
    experiments: Sequence[str],
    *,
    seeds: Sequence[int],
    budget: str,
    frames: int | None = None,
    command: str = "",
    config: Mapping | None = None,
) -> list[Path]:
    """The figures and tables of ``experiments`` (keys of :data:`REPORTS` and
    :data:`STANDALONE`) from the jobs under ``root``, in ``root/report/<experiment>/``, and
    ``root/report/run.json`` (budget, seeds, frames, date, commit, command, machine). Each
    table's first line states the budget, frames and seeds (the :data:`STANDALONE` ones, which
    train nothing: the budget and what they ran). Returns the written paths."""
    unknown = [e for e in experiments if e not in REPORTS and e not in STANDALONE]
    if unknown:
        raise ValueError(
            f"experiments {unknown} are unknown; known: {sorted([*REPORTS, *STANDALONE])}"
        )
    root = Path(root)
    out = root / "report"
    header = (
        f"budget {budget}"
        + (f", {frames} frames per job" if frames else "")
        + f", seeds {list(seeds)}, rate model shannon, held-out evaluation scenes"
    )
    written = []
    for experiment in experiments:
        folder = out / experiment
        folder.mkdir(parents=True, exist_ok=True)
        if experiment == "table3_fixed":
            runs, duration = TABLE3_FIXED[budget]
            written += tables.table3_fixed(folder, f"budget {budget}", runs=runs, duration=duration)
        elif experiment == "rate_models":
            scenes, steps = RATE_MODELS[budget]
            written += tables.rate_models(folder, f"budget {budget}", scenes=scenes, steps=steps)
        else:
            written += REPORTS[experiment](root, folder, list(seeds), header)
    facts = {
        "budget": budget,
        "frames": frames,
        "seeds": list(seeds),
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "commit": _commit(),
        "command": command,
        "machine": platform.platform(),
        "processor": platform.processor(),
        "config": dict(config or {}),
    }
    run = out / "run.json"
    run.write_text(json.dumps(facts, indent=1, default=str))
    return [*written, run]
