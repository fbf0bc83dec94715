"""Plot a run's learning curve from its ``train_curve.csv`` (PNG)."""

from __future__ import annotations

import csv
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path

from torchrl_auv.report.pyplot import pyplot

__all__ = ["plot_learning_curve", "read_curve"]

DEFAULT_KEYS = (
    "train/cost_mean",
    "train/episode_ssn",
    "train/episode_sdr",
    "train/lambda",
    "train/violation_rate",
)


def read_curve(path: str | Path) -> dict[str, tuple[list[int], list[float]]]:
    """``{key: (steps, values)}`` from a long-format ``step,key,value`` CSV.

    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp(), "c.csv")
    >>> _ = p.write_text("step,key,value\\n200,train/cost_mean,0.5\\n400,train/cost_mean,0.4\\n")
    >>> read_curve(p)["train/cost_mean"]
    ([200, 400], [0.5, 0.4])
    """
    curves: dict[str, tuple[list[int], list[float]]] = defaultdict(lambda: ([], []))
    with open(path, newline="") as handle:
        for row in csv.DictReader(handle):
            steps, values = curves[row["key"]]
            steps.append(int(row["step"]))
            values.append(float(row["value"]))
    return dict(curves)


def plot_learning_curve(
    path: str | Path,
    out: str | Path,
    *,
    keys: Sequence[str] = DEFAULT_KEYS,
    offline_frames: int = 0,
) -> Path:
    """One panel per key present in the curve CSV ``path``, against frames; writes ``out``.
    ``offline_frames``: frames collected before training (a first stage's demonstrations and
    DAgger rounds, SAC's demonstrations): the axis starts there and says so, since such frames
    are not free."""
    if (
        isinstance(offline_frames, bool)
        or not isinstance(offline_frames, int)
        or offline_frames < 0
    ):
        raise ValueError(f"offline_frames must be an integer >= 0, got {offline_frames!r}")
    plt = pyplot()

    curves = read_curve(path)
    present = [k for k in keys if k in curves] or sorted(curves)[:4]
    fig, axes = plt.subplots(
        len(present), 1, figsize=(7, 2.2 * len(present)), sharex=True, squeeze=False
    )
    for ax, key in zip(axes[:, 0], present, strict=True):
        steps, values = curves[key]
        ax.plot([step + offline_frames for step in steps], values, marker=".")
        ax.set_ylabel(key.split("/", 1)[-1], fontsize=8)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel(
        f"frames, from {offline_frames:,} collected offline" if offline_frames else "frames"
    )
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return Path(out)
