"""recipes/paper/run_all.py: every job of the paper's grid composes and passes the checks in
both budgets; finished jobs are skipped, stopped ones resumed, failed ones named; a reduced
grid runs end to end (slow)."""

from __future__ import annotations

import csv
import importlib.util
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from torchrl_auv.report.paper.figures import fig4
from torchrl_auv.report.paper.grid import EXPERIMENTS, Job, grid
from torchrl_auv.report.paper.output import first_stage_folder
from torchrl_auv.report.paper.store import read_sittings
from torchrl_auv.training import check_choices, check_config

REPO = Path(__file__).resolve().parents[2]
RECIPES = REPO / "recipes"


def _load_run_all():
    spec = importlib.util.spec_from_file_location("_run_all", RECIPES / "paper" / "run_all.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("budget", ["quick", "paper"])
def test_every_job_composes_and_passes_the_checks(budget, tmp_path):
    jobs = grid(list(EXPERIMENTS), seeds=(0,))  # other seeds differ in seed= only
    assert len(jobs) == 35
    with initialize_config_dir(config_dir=str(RECIPES), version_base="1.3"):
        for job in jobs:
            cfg = compose("train", overrides=job.overrides(budget, root=tmp_path, frames=50000))
            # an OpenAI-compatible advisor's endpoint is checked when its job starts
            check = check_choices if job.variant == "openai" else check_config
            check(OmegaConf.to_container(cfg, resolve=True))
            assert cfg.env.sea_state == job.sea and cfg.seed == job.seed
            assert list(cfg.eval.sea_states) == [job.sea]


FAKE_TRAIN = """
import sys, pathlib
args = dict(a.split("=", 1) for a in sys.argv[1:])
run = pathlib.Path(args.get("resume") or args["run_dir"])
run.mkdir(parents=True, exist_ok=True)
(run / "argv.txt").write_text(" ".join(sys.argv[1:]))
(run / "train_curve.csv").write_text("frames,cost_mean\\n100,1.0\\n")
if args["seed"] == "13":
    sys.exit(3)
(run / "eval.csv").write_text("sea_state,policy,ssn\\nves,sac,1.0\\n")
"""


def test_finished_jobs_are_skipped_stopped_ones_resumed_failed_ones_named(tmp_path, monkeypatch):
    run_all = _load_run_all()
    fake = tmp_path / "fake_train.py"
    fake.write_text(FAKE_TRAIN)
    monkeypatch.setattr(run_all, "TRAIN", fake)
    cfg = OmegaConf.create({"budget": "quick", "frames": None})
    root = tmp_path / "root"
    new, stopped, failing = (
        Job("sac", "ves", "pid", 0),
        Job("sac", "ves", "pid", 1),
        Job("sac", "ves", "pid", 13),
    )
    (root / "jobs" / stopped.name / "checkpoints" / "checkpoint-100").mkdir(parents=True)
    assert run_all.run_job(new, cfg, root)[1] == "finished"
    assert run_all.run_job(new, cfg, root)[1] == "skipped (finished)"
    assert run_all.run_job(stopped, cfg, root)[1] == "resumed and finished"
    argv = (root / "jobs" / stopped.name / "argv.txt").read_text()
    assert f"resume={root / 'jobs' / stopped.name}" in argv
    _, state, _ = run_all.run_job(failing, cfg, root)
    assert state.startswith("FAILED (exit 3") and str(root / "logs") in state
    assert "$ " in (root / "logs" / "sac__ves__pid__seed13.log").read_text()


def test_a_job_waits_for_its_first_stage_while_the_other_core_goes_on(tmp_path, monkeypatch):
    """The LAC job is next in order but its first stage is building: the second core takes
    the SAC job instead, and the LAC job starts only once its builder has ended."""
    run_all = _load_run_all()
    builder, user, sac = (
        Job("diffusion", "ves", "pid", 0),
        Job("diffusion_lac", "ves", "pid", 0),
        Job("sac", "ves", "pid", 0),
    )
    events, sac_started = [], threading.Event()

    def fake_run_job(job, cfg, root):
        events.append(("start", job.name))
        if job == sac:
            sac_started.set()
        if job == builder:
            assert sac_started.wait(timeout=20), "the other core sat idle behind the build"
        events.append(("end", job.name))
        return job.name, "finished", 0.0

    monkeypatch.setattr(run_all, "run_job", fake_run_job)
    cfg = OmegaConf.create({"budget": "quick", "frames": None, "parallel": 2})
    assert run_all.run_jobs([builder, user, sac], cfg, tmp_path, None) == []
    assert events.index(("start", user.name)) > events.index(("end", builder.name))
    assert {name for kind, name in events if kind == "end"} == {builder.name, user.name, sac.name}


def test_a_first_stage_not_built_is_built_by_one_job_and_a_failed_builder_fails_its_jobs(
    tmp_path, monkeypatch
):
    """The ves/pid builder ended (restored from a store) but its first stage is not on this
    machine: its two jobs run one after the other (the first builds it). The es/pid builder
    fails: its job fails unrun. A job whose process cannot start fails, the others run."""
    run_all = _load_run_all()
    restored = Job("diffusion", "ves", "pid", 0)
    users = [Job("diffusion_rl", "ves", "pid", 0), Job("diffusion_lac", "ves", "pid", 0)]
    broken, orphan = Job("diffusion", "es", "pid", 0), Job("diffusion_rl", "es", "pid", 0)
    crashing, sac = Job("sac", "es", "smc", 0), Job("sac", "ves", "smc", 0)
    events, lock = [], threading.Lock()

    def fake_run_job(job, cfg, root):
        with lock:
            events.append(("start", job.name))
        if job == crashing:
            raise OSError("no space left on device")
        if job == users[0]:  # slow enough for the other core to look for work meanwhile
            time.sleep(0.5)
        with lock:
            events.append(("end", job.name))
        if job == restored:
            return job.name, "skipped (finished)", 0.0
        if job == broken:
            return job.name, "FAILED (exit 1; log x)", 1.0
        return job.name, "finished", 1.0

    monkeypatch.setattr(run_all, "run_job", fake_run_job)
    cfg = OmegaConf.create({"budget": "quick", "frames": None, "parallel": 2})
    jobs = [restored, *users, broken, orphan, crashing, sac]
    failed = run_all.run_jobs(jobs, cfg, tmp_path, None)
    assert sorted(failed) == sorted([broken.name, orphan.name, crashing.name])
    assert ("start", orphan.name) not in events
    assert events.index(("start", users[1].name)) > events.index(("end", users[0].name))
    assert ("end", sac.name) in events


def test_a_store_carries_finished_jobs_to_another_machine(tmp_path, monkeypatch):
    """Sitting 1 stores each finished job (not the failed one, nor checkpoints); the command
    on a fresh run folder (another machine) gets them back, and its jobs skip them."""
    run_all = _load_run_all()
    fake = tmp_path / "fake_train.py"
    fake.write_text(FAKE_TRAIN)
    monkeypatch.setattr(run_all, "TRAIN", fake)
    cfg = OmegaConf.create({"budget": "quick", "frames": None, "parallel": 2})
    done, later = grid(["fig7"], seeds=(0,))[:2]
    failing = Job("sac", "es", "pid", 13)
    store, first, second = tmp_path / "store", tmp_path / "machine1", tmp_path / "machine2"
    (first / "jobs" / done.name / "checkpoints" / "checkpoint-100").mkdir(parents=True)
    stage = first / "first_stage" / "ideal-s_surface-shannon-seed0-abc"  # built: records kept
    for name, text in (
        ("proposer.pt", "weights"),
        ("metrics.json", "{}"),
        ("values.json", "{}"),
        ("pretrain_loss.csv", "step,split,loss\n10,train,0.5\n10,heldout,0.7\n"),
    ):
        (stage / name).parent.mkdir(parents=True, exist_ok=True)
        (stage / name).write_text(text)
    partial = first / "first_stage" / ".ideal-s_surface-shannon-seed1-abc.partial-7"
    unfinished = first / "first_stage" / "es-s_surface-shannon-seed0-x"  # no values.json
    for folder, names in (
        (partial, ("pretrain_loss.csv", "values.json")),
        (unfinished, ("pretrain_loss.csv",)),
    ):
        folder.mkdir()
        for name in names:
            (folder / name).write_text("{}")
    assert run_all.run_jobs([done, failing], cfg, first, store) == [failing.name]
    run_all.sync_store(first, store, [done, failing])  # the next sitting on this machine
    stored = sorted(p.relative_to(store).as_posix() for p in store.rglob("*") if p.is_file())
    assert stored == [
        f"first_stage/{stage.name}/{name}"
        for name in ("metrics.json", "pretrain_loss.csv", "values.json")
    ] + [f"jobs/{done.name}/eval.csv", f"jobs/{done.name}/train_curve.csv", "sittings.json"]
    # the sitting is recorded: the one job it finished (the failed one does not count)
    (sitting,) = read_sittings(store)
    assert sitting["jobs_finished"] == 1 and sitting["end"] >= sitting["start"]
    command = [
        sys.executable,
        str(RECIPES / "paper" / "run_all.py"),
        "budget=quick",
        "seeds=[0]",
        "experiments=[fig7]",
        "jobs=false",
        "report=false",
        f"run_root={second}",
        f"store={store}",
    ]
    subprocess.run(command, check=True, cwd=tmp_path, timeout=120)
    assert run_all.job_state(second / "jobs" / done.name) == "done"
    assert run_all.job_state(second / "jobs" / later.name) == "new"
    # the first stage's record is back for Fig. 4, not as an artefact a job would reuse
    assert not (second / "first_stage").exists()
    assert first_stage_folder(second, "ideal", 0) is None
    record = first_stage_folder(second, "ideal", 0, records=True)
    assert (record / "pretrain_loss.csv").read_text() == (stage / "pretrain_loss.csv").read_text()
    (tmp_path / "fig4").mkdir()
    fig4(second, tmp_path / "fig4", [0], "header")
    rows = json.loads((tmp_path / "fig4" / "fig4.json").read_text())["rows"]
    assert rows[0]["sea_state"] == "ideal" and rows[0]["heldout_loss"] == 0.7
    assert run_all.run_jobs([done, later], cfg, second, store) == []
    assert [s["jobs_finished"] for s in read_sittings(store)] == [1, 1]
    assert not (second / "jobs" / done.name / "argv.txt").exists()  # skipped, not run again
    assert (store / "jobs" / later.name / "eval.csv").exists()


@pytest.mark.slow
def test_a_reduced_grid_runs_end_to_end(tmp_path):
    """The quick budget, one seed, Fig. 5/6 and Fig. 8/9 (the proposer alone and the full
    framework in VES): the figures and tables, their numbers the job's."""
    env = {**os.environ, "OMP_NUM_THREADS": "1", "WANDB_MODE": "offline"}
    command = [
        sys.executable,
        str(RECIPES / "paper" / "run_all.py"),
        "budget=quick",
        "seeds=[0]",
        "experiments=[fig5_6,fig8_9]",
        f"run_root={tmp_path}",
    ]
    subprocess.run(command, check=True, env=env, cwd=tmp_path, timeout=1200)
    report = tmp_path / "report"
    for name in (
        "fig5_6/fig5.png",
        "fig5_6/fig6.png",
        "fig8_9/fig8_9.png",
        "fig8_9/fig8_9.md",
        "fig8_9/fig8_9.csv",
        "run.json",
    ):
        assert (report / name).stat().st_size > 0, name
    rows = json.loads((report / "fig8_9" / "fig8_9.json").read_text())["rows"]
    with open(tmp_path / "jobs/diffusion_lac/ves/s_surface/seed0/eval.csv", newline="") as f:
        own = {row["policy"]: row for row in csv.DictReader(f)}
    assert len(rows) == 9  # OA, CA1-CA4, RL (LAC); the proposer alone, expert, random
    for row in rows:
        policy = "RL" if row["policy"] == "RL (LAC)" else row["policy"].removesuffix(" (reference)")
        assert row["runs"] == 1
        assert row["ssn"] == pytest.approx(float(own[policy]["ssn"]))
    # a second run finds every job finished and only writes the report again
    out = subprocess.run(
        command, check=True, env=env, cwd=tmp_path, capture_output=True, text=True, timeout=600
    )
    assert (out.stdout + out.stderr).count("skipped (finished)") == 2
