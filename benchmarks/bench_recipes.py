"""Training frames/s of the four recipes on the same env, batch and update ratio (1 thread).

Each recipe's ``train.py`` runs as a subprocess with the same overrides: ``quick`` config (ideal
sea, 2 scenes, 300-decision episodes, networks 64x64), ``collector.frames_per_batch=200``,
``optim.updates_per_batch=50`` (one gradient update per 4 frames), ``collector.total_frames``
frames, logging off, the proposer reused from one first stage built up front (so only
collection and training are timed), a tiny evaluation. The rate is the recipe's own
"training frames/s" from its ``summary.md`` (collection and updates together, excluding start-up
and evaluation). Issue [10/13]'s target: diffusion_lac / sac >= 0.5.
"""

from __future__ import annotations

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


def run(recipe: str, run_dir: Path, frames: int, proposer: Path | None) -> float:
    overrides = ["--config-name=quick", f"run_dir={run_dir}", f"collector.total_frames={frames}",
                 "collector.frames_per_batch=200", "eval.steps=5", "logger.backend="]  # fmt: skip
    if recipe != "diffusion":
        overrides.append("optim.updates_per_batch=50")
    if recipe == "sac":  # the others have no random phase (the proposer acts from the start)
        overrides.append("collector.init_random_frames=0")
    if proposer is not None:
        overrides.append(f"proposer.path={proposer}")
    env = {**os.environ, "OMP_NUM_THREADS": os.environ.get("OMP_NUM_THREADS", "1")}
    result = subprocess.run([sys.executable, f"recipes/{recipe}/train.py", *overrides],
                            cwd=REPO, env=env, capture_output=True, text=True)  # fmt: skip
    if result.returncode:
        raise RuntimeError(f"{recipe} failed:\n{result.stderr[-2000:]}")
    summary = (run_dir / "summary.md").read_text()
    return float(re.search(r"frames/s: ([0-9.e+]+)", summary).group(1))


def main() -> None:
    args = setup(__doc__)
    frames = 600 if args.quick else 2000
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        first = Path(tmp, "first")
        run("diffusion", first, 200, None)  # builds and caches the proposer
        proposer = first / "proposer" / "proposer.pt"
        print(f"first stage (demonstrations + pretraining): {time.perf_counter() - start:.0f} s")
        rates = {r: run(r, Path(tmp, r), frames, None if r == "sac" else proposer)
                 for r in RECIPES}  # fmt: skip
    rows = [(name, rate, rate / rates["sac"]) for name, rate in rates.items()]
    print_table("training frames/s (2 scenes, 50 updates per 200 frames)",
                ["recipe", "frames/s", "vs sac"], rows)  # fmt: skip
    print_summary("recipes", diffusion_lac_vs_sac=rates["diffusion_lac"] / rates["sac"],
                  diffusion_rl_vs_sac=rates["diffusion_rl"] / rates["sac"],
                  diffusion_vs_sac=rates["diffusion"] / rates["sac"], target=">= 0.5",
                  frames=frames)  # fmt: skip


if __name__ == "__main__":
    main()
