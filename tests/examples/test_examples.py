"""The first-read examples run end to end (tiny arguments) and write what they say."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def _run(*argv: str) -> str:
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    proc = subprocess.run(
        [sys.executable, *argv], cwd=REPO, env=env, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc.stdout


def test_rollout_expert_prints_metrics_and_plots(tmp_path):
    out = _run("examples/rollout_expert.py", "--steps", "40", "--out", str(tmp_path / "e.png"))
    assert re.search(r"^ssn: \[\d+, \d+\]$", out, re.M)  # one count per scene
    assert (tmp_path / "e.png").stat().st_size > 10_000


def test_record_video_writes_the_episode_and_its_last_frame(tmp_path):
    out = _run("examples/record_video.py", "--steps", "6", "--out", str(tmp_path))
    assert re.search(r"^SDR \d+\.\d\d Mbit, SSN \d+$", out, re.M)
    assert (tmp_path / "rl-video-episode-0.mp4").stat().st_size > 1000
    assert (tmp_path / "last_frame.png").stat().st_size > 1000


def test_lac_in_a_torchrl_loop_reports_the_dual_variables():
    out = _run("examples/lac_in_a_torchrl_loop.py", "--frames", "200")
    lines = re.findall(r"^batch (\d+): cost ([\d.]+), lambda ([\d.]+), beta ([\d.]+)", out, re.M)
    assert [int(b) for b, *_ in lines] == [0, 1]
    assert all(0 < float(lam) <= 1.0 and float(beta) > 0 for _, _, lam, beta in lines)


def test_proposer_candidates_samples_k_chunks_and_plots(tmp_path):
    out = _run(
        "examples/proposer_candidates.py",
        "--pretrain-steps",
        "20",
        "--out",
        str(tmp_path / "c.png"),
    )
    assert "candidates (1, 5, 8, 3)" in out
    assert (tmp_path / "c.png").stat().st_size > 10_000


def test_plain_torchrl_sac_stores_under_1_kb_per_frame_without_a_key_list():
    out = _run("examples/plain_torchrl_sac.py", "--iterations", "2", "--steps", "10")
    lines = re.findall(
        r"^iteration (\d+): (\d+) bytes per frame \(the full rollout: (\d+)\), "
        r"buffer (\d+) frames.*loss_qvalue ([\d.]+)",
        out,
        re.M,
    )
    assert [int(i) for i, *_ in lines] == [0, 1]
    for i, stored, full, buffered, loss in lines:
        assert int(stored) <= 1024 < 10 * int(stored) < int(full)
        assert int(buffered) == (int(i) + 1) * 4 * 10  # 4 scenes x 10 decisions per rollout
        assert float(loss) > 0
