"""How far a paper grid has run: each job's state (finished here or only in the results
store, stopped at its newest checkpoint, not started), counts by framework, and the time left
at the recorded sittings' rate."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

from torchrl_auv.report.paper.grid import Job
from torchrl_auv.report.paper.progress import format_status, grid_status, sitting_hours

REPO = Path(__file__).resolve().parents[2]


def _grid_folders(root: Path, store: Path) -> list[Job]:
    here, stored, stopped, new = (
        Job("sac", "ves", "s_surface", 0),
        Job("diffusion_rl", "ves", "s_surface", 0),
        Job("diffusion_lac", "ves", "s_surface", 0),
        Job("diffusion_lac", "ves", "s_surface", 1),
    )
    (root / "jobs" / here.name).mkdir(parents=True)
    (root / "jobs" / here.name / "eval.csv").write_text("sea_state,policy\n")
    (store / "jobs" / stored.name).mkdir(parents=True)
    (store / "jobs" / stored.name / "eval.csv").write_text("sea_state,policy\n")
    for frames in ("000000010000", "000000030000", "not-a-number"):
        (root / "jobs" / stopped.name / "checkpoints" / f"checkpoint-{frames}").mkdir(parents=True)
    return [here, stored, stopped, new]


def test_each_job_has_its_state_and_the_time_left_follows_the_sittings(tmp_path):
    root, store = tmp_path / "run", tmp_path / "store"
    jobs = _grid_folders(root, store)
    sittings = [
        {
            "start": "2026-12-04T20:00:00+00:00",
            "end": "2026-12-04T21:30:00+00:00",
            "jobs_finished": 2,
        },
        {"start": "2026-12-05T09:00:00+00:00", "end": None, "jobs_finished": 0},
    ]
    status = grid_status(root, jobs, store=store, sittings=sittings)
    assert [(state, frames) for _, state, frames in status["jobs"]] == [
        ("done", None),
        ("done", None),
        ("stopped", 30000),
        ("new", None),
    ]
    assert status["finished"] == 2 and status["total"] == 4
    assert dict(status["counts"]["diffusion_lac"]) == {"stopped": 1, "new": 1}
    # 2 jobs in 1.5 h: 2 left take 1.5 h (a sitting without a finished job adds no hours)
    assert math.isclose(status["rate_per_hour"], 2 / 1.5)
    assert math.isclose(status["hours_left"], 1.5)
    text = format_status(status)
    assert f"checkpoint at 30,000 frames    {jobs[2].name}" in text
    assert f"not started                    {jobs[3].name}" in text
    assert "finished 2 of 4" in text and "diffusion_lac  0 / 1 / 1" in text
    assert "take about 1.5 h" in text
    # without the store, the job only it holds is not finished; without sittings, no estimate
    alone = grid_status(root, jobs)
    assert alone["jobs"][1][1] == "new" and math.isnan(alone["hours_left"])
    assert "no sitting recorded" in format_status(alone)
    idle = grid_status(root, jobs, sittings=sittings[1:])  # a sitting that finished nothing
    assert "finished no job yet: no estimate" in format_status(idle)


def test_sittings_at_the_same_time_count_their_hours_once():
    """Two run_all.py at once on one machine (the grid and a second experiment): the hours
    are the machine's, the union of the sittings' spans, not their sum."""

    def sitting(start, end):
        return {"start": f"2026-12-05T{start}:00+00:00", "end": f"2026-12-05T{end}:00+00:00"}

    apart = [sitting("01:00", "02:00"), sitting("03:00", "03:30")]
    assert math.isclose(sitting_hours(apart), 1.5)
    inside = [sitting("01:00", "04:00"), sitting("02:00", "03:00")]
    assert math.isclose(sitting_hours(inside), 3.0)
    overlapping = [sitting("02:00", "05:00"), sitting("01:00", "03:00"), sitting("06:00", "07:00")]
    assert math.isclose(sitting_hours(overlapping), 5.0)
    assert sitting_hours([sitting("03:00", "02:00")]) == 0.0  # an end before its start
    assert math.isclose(
        sitting_hours([*overlapping, {"start": "2026-12-05T00:00:00+00:00", "end": None}]), 5.0
    )


def test_run_all_status_prints_the_grid_and_runs_and_writes_nothing(tmp_path):
    root, store = tmp_path / "run", tmp_path / "store"
    _grid_folders(root, store)
    before = sorted(tmp_path.rglob("*"))
    done = subprocess.run(
        [
            sys.executable,
            str(REPO / "recipes" / "paper" / "run_all.py"),
            "budget=paper",
            f"run_root={root}",
            f"store={store}",
            "status=true",
            "jobs=false",
            "report=false",
        ],  # (were status ignored: no job would start)
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert "102 jobs (paper budget, seeds [0, 1, 2])" in done.stdout
    assert "finished 2 of 102" in done.stdout
    assert "checkpoint at 30,000 frames" in done.stdout
    # nothing run, stored or restored (Hydra's own log of the command aside)
    assert sorted(p for p in tmp_path.rglob("*") if p.name != "run_all.log") == before
