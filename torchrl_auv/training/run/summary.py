"""A run's written results: ``eval.csv`` (one row per sea state and policy) and ``summary.md``.

Examples:
    >>> import tempfile, pathlib
    >>> rows = [{"sea_state": "ideal", "policy": "expert", "sdr_mbit": 26.4, "ssn": 15.1}]
    >>> with tempfile.TemporaryDirectory() as d:
    ...     _ = write_eval(rows, d)
    ...     print(pathlib.Path(d, "eval.csv").read_text().splitlines()[1])
    ideal,expert,26.4,15.1
"""

from __future__ import annotations

import csv
import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

from torchrl_auv.evaluation import CERTIFICATE_KEYS

__all__ = ["SUMMARY_COLUMNS", "write_certificate", "write_eval", "write_summary"]

#: The evaluation columns summary.md shows (eval.csv has every one).
SUMMARY_COLUMNS = (
    "sdr_mbit",
    "ssn",
    "ec_w",
    "collisions",
    "violation_rate",
    "terminated",
    "cost_mean",
    "heading_error_mean",
    "depth_error_mean",
)


def write_eval(rows: Sequence[Mapping], run_dir: str | Path) -> Path:
    """Write ``run_dir/eval.csv`` (columns: the first row's keys) whole or not at all (a
    temporary file renamed into place): its presence marks a finished run
    (``recipes/paper/run_all.py`` skips it)."""
    path = Path(run_dir) / "eval.csv"
    partial = path.with_name(f".{path.name}.partial-{os.getpid()}")
    try:
        with open(partial, "w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
        os.replace(partial, path)
    finally:
        partial.unlink(missing_ok=True)
    return path


def _fmt(value) -> str:
    return f"{value:.3g}" if isinstance(value, float) else str(value)


def write_summary(
    run_dir: str | Path, *, title: str, rows: Sequence[Mapping], facts: Mapping[str, object]
) -> Path:
    """Write ``run_dir/summary.md``: the run's facts (frames, rates, wall time, ...) and the
    evaluation table (:data:`SUMMARY_COLUMNS`). Returns its path."""
    lines = [f"# {title}", ""]
    lines += [f"- {key}: {_fmt(value)}" for key, value in facts.items()]
    cols = ["sea_state", "policy", *SUMMARY_COLUMNS]
    lines += ["", "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    lines += ["| " + " | ".join(_fmt(row.get(c, "")) for c in cols) + " |" for row in rows]
    path = Path(run_dir) / "summary.md"
    path.write_text("\n".join(lines) + "\n")
    return path


def write_certificate(rows: list[dict], run_dir: Path, certificate) -> Path:
    """``run_dir/lyapunov_certificate.json``: per sea state and policy row, the decrease
    condition on the row's executed approach transitions
    (``certificate``: the :class:`~torchrl_auv.evaluation.LyapunovCertificate` of the
    rows; :data:`~torchrl_auv.evaluation.CERTIFICATE_KEYS` without their ``lyapunov_`` prefix:
    ``transitions``, ``decrease_holds``, ``violation_upper95``, ``delta_mean``,
    ``change_std``, ``margin_mean``, ``legs``, ``leg_decrease_holds``, ``legs_arrived``), with the
    Lyapunov spec the critic was read with. Returns its path."""
    spec = certificate.spec
    out = {
        "spec": {"form": spec.form, "alpha": spec.alpha, "prior": spec.prior},
        "condition": "(1 - e)(1 - d) L(s', a') - L(s, a) + alpha c <= 0 on approach transitions",
        "rows": [
            {
                "sea_state": row["sea_state"],
                "policy": row["policy"],
                **{key.removeprefix("lyapunov_"): row[key] for key in CERTIFICATE_KEYS},
            }
            for row in rows
        ],
    }
    path = Path(run_dir) / "lyapunov_certificate.json"
    path.write_text(json.dumps(out, indent=2))
    return path
