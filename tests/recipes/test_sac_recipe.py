"""recipes/sac: the command contract with tiny overrides, outputs, bad values, SIGKILL + resume."""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
TINY = [
    "--config-name=quick",
    "collector.frames_per_batch=100",
    "collector.init_random_frames=100",
    "optim.updates_per_batch=4",
    "eval.steps=20",
]


def _command(run_dir: Path, *overrides: str) -> list[str]:
    return [sys.executable, "recipes/sac/train.py", *TINY, f"run_dir={run_dir}", *overrides]


def _env() -> dict:
    return {**os.environ, "OMP_NUM_THREADS": "1", "WANDB_MODE": "offline"}


def _run(command: list[str], timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run(
        command, cwd=REPO, env=_env(), capture_output=True, text=True, timeout=timeout
    )


def _checkpoint_steps(run_dir: Path) -> list[int]:
    return sorted(
        int(p.name.split("-")[-1]) for p in (run_dir / "checkpoints").glob("checkpoint-*")
    )


def test_sac_runs_with_tiny_overrides_and_writes_its_outputs(tmp_path):
    run_dir = tmp_path / "run"
    result = _run(
        _command(
            run_dir, "collector.total_frames=200", "logger.backend=wandb", "eval.video_steps=6"
        )
    )
    assert result.returncode == 0, result.stderr[-3000:]
    with open(run_dir / "eval.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert [(r["sea_state"], r["policy"]) for r in rows] == [
        ("ideal", "sac"),
        ("ideal", "expert"),
        ("ideal", "idle"),
        ("ideal", "random"),
    ]
    for row in rows:  # 20 decisions per scene: the metrics are finite numbers
        assert float(row["decisions"]) == 20.0 and float(row["cost_mean"]) >= 0.0
    summary = (run_dir / "summary.md").read_text()
    assert "- frames: 200" in summary and "bytes per stored frame: 660" in summary
    assert _checkpoint_steps(run_dir) == [200]
    # the run's policy in one held-out scene, the reset and 6 decisions, as a video
    import imageio.v3 as iio

    assert iio.imread(run_dir / "eval_episode.mp4").shape == (7, 400, 400, 3)
    assert "- evaluation video: eval_episode.mp4: sac, ideal, 6 decisions" in summary
    # the offline run's record file (protobuf records, strings stored as UTF-8) holds the
    # config and the train/eval metrics by name
    (record_file,) = (run_dir / "wandb").glob("offline-run-*/run-*.wandb")
    records = record_file.read_bytes()
    for name in (
        b"sea_state",
        b"updates_per_batch",
        b"train/cost_mean",
        b"time/frames_per_s",
        b"eval/ideal/sac/ssn",
        b"eval/ideal/expert/ssn",
        b"eval/episode",
    ):
        assert name in records, name


@pytest.mark.parametrize(
    ("override", "named"),
    [
        ("env.sea_state=calm", "env.sea_state"),
        ("env.controller=lqr", "env.controller"),
        ("env.rate_model=fast", "env.rate_model"),
        ("collector.backend=slurm", "collector.backend"),
        ("collector.total_frames=0", "collector.total_frames"),
        ("eval.video_steps=-1", "eval.video_steps"),
    ],
)
def test_an_unknown_value_fails_before_any_work_naming_it(tmp_path, override, named):
    result = _run(_command(tmp_path / "run", override, "logger.backend="), timeout=120)
    assert result.returncode != 0 and named in result.stderr
    assert not (tmp_path / "run").exists()  # no half-made folder (Hydra's is removed)


@pytest.mark.slow  # minutes: kept out of the default suite's 20-minute budget
def test_a_run_killed_with_sigkill_resumes_from_its_latest_checkpoint(tmp_path):
    run_dir = tmp_path / "run"
    command = _command(
        run_dir, "collector.total_frames=1000", "checkpoint.every_frames=200", "logger.backend="
    )
    process = subprocess.Popen(
        command, cwd=REPO, env=_env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and not any(
        s >= 400 for s in _checkpoint_steps(run_dir) if (run_dir / "checkpoints").exists()
    ):
        time.sleep(0.2)
    process.send_signal(signal.SIGKILL)
    process.wait()
    reached = max(_checkpoint_steps(run_dir))
    assert 400 <= reached < 1000 and not (run_dir / "summary.md").exists()

    # resume names the run; run_dir keeps its default (a new stamped folder under run_root),
    # which must not be made
    resume = [
        sys.executable,
        "recipes/sac/train.py",
        *TINY,
        "collector.total_frames=1000",
        "checkpoint.every_frames=200",
        "logger.backend=",
        f"resume={run_dir}",
        f"run_root={tmp_path / 'root'}",
    ]
    result = _run(resume)
    assert result.returncode == 0, result.stderr[-3000:]
    assert not (tmp_path / "root").exists()
    assert "resume=" in (run_dir / ".hydra" / "overrides.yaml").read_text()
    assert "resumed" in (run_dir / "train.log").read_text()
    assert f"resumed {run_dir} at {reached} frames" in result.stdout + result.stderr
    assert "resumed without the replay buffer" in result.stdout + result.stderr  # said, not silent
    summary = (run_dir / "summary.md").read_text()
    assert "- frames: 1000" in summary  # continued the count, did not start over
    steps = _checkpoint_steps(run_dir)
    assert steps[-1] == 1000 and len(steps) <= 2  # rotation keeps the newest two

    # the finished run is not touched by a refused new run in the same folder: checkpoints,
    # Hydra's files and the log stay as they were
    kept = {p: p.read_bytes() for p in [*(run_dir / ".hydra").iterdir(), run_dir / "train.log"]}
    again = _run(_command(run_dir, "collector.total_frames=200", "logger.backend="), timeout=120)
    assert again.returncode != 0 and f"resume={run_dir}" in again.stderr
    assert _checkpoint_steps(run_dir) == steps
    assert {p: p.read_bytes() for p in kept} == kept
    missing = _run(_command(run_dir, "logger.backend=", f"resume={tmp_path / 'none'}"), 120)
    assert missing.returncode != 0 and "holds no checkpoints" in missing.stderr
    assert not (tmp_path / "none").exists() and {p: p.read_bytes() for p in kept} == kept
