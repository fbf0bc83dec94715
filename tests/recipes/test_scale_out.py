"""Scale-out by config alone: the same recipe with 2 worker processes and with 2 Ray remote
collectors trains on the frames asked for and writes its evaluation."""

from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
TINY = [
    "framework=sac",
    "preset=quick",
    "collector.total_frames=200",
    "collector.frames_per_batch=100",
    "collector.init_random_frames=100",
    "optim.updates_per_batch=4",
    "eval.steps=20",
    "logger.backend=",
]


def _train(tmp_path: Path, *overrides: str, slow_start=None) -> Path:
    run_dir = tmp_path / "run"
    env = {**os.environ, "OMP_NUM_THREADS": "1", "RAY_ADDRESS": "", "HOME": str(tmp_path)}
    result = subprocess.run(
        [sys.executable, "recipes/train.py", *TINY, f"run_dir={run_dir}", *overrides],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    if result.returncode and slow_start is not None:
        slow_start(result.stderr)
    assert result.returncode == 0, result.stderr[-3000:]
    return run_dir


def _check(run_dir: Path) -> None:
    assert "- frames: 200" in (run_dir / "summary.md").read_text()
    with open(run_dir / "eval.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert [r["policy"] for r in rows] == ["sac", "expert", "idle", "random"]
    assert all(float(r["decisions"]) == 20.0 for r in rows)


@pytest.mark.slow  # minutes: kept out of the default suite's 20-minute budget
def test_a_run_with_two_worker_processes(tmp_path):
    _check(_train(tmp_path, "collector.num_workers=2"))


@pytest.mark.slow  # minutes: kept out of the default suite's 20-minute budget
def test_a_run_whose_collection_uses_two_ray_remote_collectors(
    tmp_path, skip_if_ray_started_too_slowly
):
    pytest.importorskip("ray")
    _check(
        _train(
            tmp_path,
            "collector.backend=ray",
            "collector.num_workers=2",
            slow_start=skip_if_ray_started_too_slowly,
        )
    )
