"""Training frames/s of the four recipes on the same env, batch and update ratio (1 thread).

Each recipe's ``train.py`` runs as a subprocess with the same overrides: ``quick`` config (ideal
sea, 2 scenes, 300-decision episodes, networks 64x64), ``collector.frames_per_batch=200``,
``optim.updates_per_batch=50`` (one gradient update per 4 frames), ``collector.total_frames``
frames, logging off, the proposer reused from one first stage built up front (so only
collection and training are timed), a tiny evaluation. The rate is the recipe's own
"training frames/s" from its ``summary.md`` (collection and updates together, excluding start-up
and evaluation). Issue [10/13]'s target: diffusion_lac / sac >= 0.5.

``--paper`` times the paper preset instead (each recipe's ``paper.yaml``: ``ves``, 8 scenes,
compiled physics, 250 updates per 1000 frames of batch 64, networks 256x256; diffusion_lac with
K = 5 candidates of 50 DDPM steps) on a segment of ``--frames`` frames (default 20,000) of
diffusion_lac and sac, and extrapolates diffusion_lac to the paper's budget (300 episodes x 1000
decisions = 300,000 frames) from the steady rate of the segment's second half (the first batches
include the physics compilation). It also prints each run's peak RSS. Issue [11/13]'s targets:
the budget in <= 1 hour, diffusion_lac / sac >= 0.5, the paper preset in 8 GB.
"""

from __future__ import annotations

import argparse
import csv
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _runner import print_summary, print_table, setup

REPO = Path(__file__).resolve().parents[1]
RECIPES = ("sac", "diffusion", "diffusion_rl", "diffusion_lac")


def _train(recipe: str, overrides: list[str]) -> None:
    env = {**os.environ, "OMP_NUM_THREADS": os.environ.get("OMP_NUM_THREADS", "1")}
    result = subprocess.run(
        [sys.executable, f"recipes/{recipe}/train.py", *overrides],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
    )
    if result.returncode:
        raise RuntimeError(f"{recipe} failed:\n{result.stderr[-2000:]}")


def _fact(run_dir: Path, name: str) -> float:
    summary = (run_dir / "summary.md").read_text()
    return float(re.search(rf"{re.escape(name)}: ([0-9.e+]+)", summary).group(1))


def run(recipe: str, run_dir: Path, frames: int, proposer: Path | None) -> float:
    overrides = [
        "--config-name=quick",
        f"run_dir={run_dir}",
        f"collector.total_frames={frames}",
        "collector.frames_per_batch=200",
        "eval.steps=5",
        "logger.backend=",
    ]
    if recipe != "diffusion":
        overrides.append("optim.updates_per_batch=50")
    if recipe == "sac":  # the others have no random phase (the proposer acts from the start)
        overrides.append("collector.init_random_frames=0")
    if proposer is not None:
        overrides.append(f"proposer.path={proposer}")
    _train(recipe, overrides)
    return _fact(run_dir, "training frames/s")


def steady_rate(run_dir: Path) -> float:
    """Frames/s over the second half of a run's batches, from its ``train_curve.csv``."""
    elapsed: dict[int, float] = {}
    with open(run_dir / "train_curve.csv", newline="") as handle:
        for row in csv.DictReader(handle):
            if row["key"] == "time/elapsed_s":
                elapsed[int(row["step"])] = float(row["value"])
    steps = sorted(elapsed)
    first, last = steps[len(steps) // 2], steps[-1]
    return (last - first) / (elapsed[last] - elapsed[first])


def paper(frames: int, proposer: str | None) -> None:
    """The paper preset's segment (module docstring); ``proposer``: a pretrained
    ``proposer.pt`` to reuse (else diffusion_lac's run builds its first stage, untimed)."""
    budget = 300_000
    rows, rates = [], {}
    with tempfile.TemporaryDirectory() as tmp:
        for recipe in ("diffusion_lac", "sac"):
            run_dir = Path(tmp, recipe)
            start = time.perf_counter()
            overrides = [
                f"run_dir={run_dir}",
                f"collector.total_frames={frames}",
                "eval.steps=5",
                "eval.num_envs=1",
                "logger.backend=",
                f"checkpoint.every_frames={frames}",
            ]
            if proposer and recipe == "diffusion_lac":
                overrides.append(f"proposer.path={proposer}")
            _train(recipe, overrides)
            wall = time.perf_counter() - start
            rates[recipe] = steady_rate(run_dir)
            rows.append(
                [
                    recipe,
                    frames,
                    f"{wall:.0f}",
                    _fact(run_dir, "training frames/s"),
                    rates[recipe],
                    budget / rates[recipe] / 3600,
                    _fact(run_dir, "peak RSS (MB)"),
                ]
            )
    header = [
        "recipe",
        "frames",
        "wall s (incl. start-up)",
        "frames/s (whole run)",
        "steady frames/s",
        "budget hours (extrapolated)",
        "peak RSS MB",
    ]
    print_table(
        f"paper preset, {frames}-frame segment (extrapolated to {budget:,} frames)", header, rows
    )
    hours = budget / rates["diffusion_lac"] / 3600
    print_summary(
        "recipes_paper",
        diffusion_lac_budget_hours=hours,
        diffusion_lac_vs_sac=rates["diffusion_lac"] / rates["sac"],
        target_hours="<= 1",
        target_ratio=">= 0.5",
        frames=frames,
    )


def _arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--paper", action="store_true", help="the paper preset's segment")
    parser.add_argument("--frames", type=int, default=20_000, help="--paper segment length")
    parser.add_argument("--proposer", help="--paper: a pretrained proposer.pt to reuse")


def main() -> None:
    args = setup(__doc__, add_arguments=_arguments)
    if args.paper:
        paper(args.frames, args.proposer)
        return
    frames = 600 if args.quick else 2000
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        first = Path(tmp, "first")
        run("diffusion", first, 200, None)  # builds and caches the proposer
        proposer = first / "proposer" / "proposer.pt"
        print(f"first stage (demonstrations + pretraining): {time.perf_counter() - start:.0f} s")
        rates = {r: run(r, Path(tmp, r), frames, None if r == "sac" else proposer) for r in RECIPES}
    rows = [(name, rate, rate / rates["sac"]) for name, rate in rates.items()]
    print_table(
        "training frames/s (2 scenes, 50 updates per 200 frames)",
        ["recipe", "frames/s", "vs sac"],
        rows,
    )
    print_summary(
        "recipes",
        diffusion_lac_vs_sac=rates["diffusion_lac"] / rates["sac"],
        diffusion_rl_vs_sac=rates["diffusion_rl"] / rates["sac"],
        diffusion_vs_sac=rates["diffusion"] / rates["sac"],
        target=">= 0.5",
        frames=frames,
    )


if __name__ == "__main__":
    main()
