"""One writer per run folder (``torchrl_auv.training.run.lock``): two starts or two resumes
on one folder at the same moment, exactly one proceeds; the other is refused naming the holder
and writes nothing; a lock left by a killed run is taken over with a warning."""

from __future__ import annotations

import logging
import multiprocessing
import os
import signal
import time

import pytest
from omegaconf import OmegaConf

from torchrl_auv.training import Run, RunFolderInUse
from torchrl_auv.training.run.lock import LOCK_FILE, acquire_run_folder, release_run_folder


def _cfg(run_dir, resume=None):
    return OmegaConf.create(
        {
            "seed": 0,
            "threads": 1,
            "run_dir": str(run_dir),
            "resume": resume,
            "logger": {"backend": None, "exp_name": "x", "project": "p", "offline": True},
            "checkpoint": {"keep_last": 1},
        }
    )


def _start(run_dir, resume, barrier, results):
    """In a child: start a run when both children are ready; the winner writes one file of
    its own and holds the folder a moment."""
    barrier.wait()
    try:
        run = Run(_cfg(run_dir, resume))
    except RunFolderInUse as error:
        results.put(("refused", os.getpid(), str(error)))
        return
    (run.dir / f"written-by-{os.getpid()}").write_text("one run's file\n")
    results.put(("started", os.getpid(), ""))
    time.sleep(0.3)


def _race(run_dir, resume=None):
    context = multiprocessing.get_context("fork")
    barrier, results = context.Barrier(2), context.Queue()
    children = [
        context.Process(target=_start, args=(run_dir, resume, barrier, results)) for _ in range(2)
    ]
    for child in children:
        child.start()
    outcomes = [results.get(timeout=60) for _ in children]
    for child in children:
        child.join(timeout=60)
        assert child.exitcode == 0
    return outcomes


@pytest.mark.parametrize("attempt", range(20))
@pytest.mark.parametrize("resume", [False, True])
def test_two_runs_on_one_folder_at_once_exactly_one_proceeds(tmp_path, attempt, resume):
    run_dir = tmp_path / "run"
    if resume:  # a run to resume: its published checkpoint
        (run_dir / "checkpoints" / "checkpoint-000000000200").mkdir(parents=True)
    outcomes = _race(run_dir, str(run_dir) if resume else None)
    started = [pid for what, pid, _ in outcomes if what == "started"]
    refused = [message for what, _, message in outcomes if what == "refused"]
    assert len(started) == 1 and len(refused) == 1, outcomes
    assert f"in use by another run (pid {started[0]} on " in refused[0]
    written = sorted(path.name for path in run_dir.iterdir() if path.name.startswith("written"))
    assert written == [f"written-by-{started[0]}"]  # the folder's files are one run's


def test_a_refused_start_writes_nothing_into_the_held_folder(tmp_path):
    run_dir = tmp_path / "run"
    holder = _holder_process(run_dir)
    try:
        before = {path: path.stat().st_mtime_ns for path in run_dir.rglob("*")}
        line = (run_dir / LOCK_FILE).read_text()
        for cfg in (_cfg(run_dir), _cfg(tmp_path / "other", resume=str(run_dir))):
            with pytest.raises(RunFolderInUse, match=rf"pid {holder.pid} on .* since "):
                Run(cfg)
        assert {path: path.stat().st_mtime_ns for path in run_dir.rglob("*")} == before
        assert (run_dir / LOCK_FILE).read_text() == line
    finally:
        holder.kill()
        holder.join(timeout=60)


def _hold_forever(run_dir, ready):
    acquire_run_folder(run_dir)
    ready.set()
    time.sleep(600)


def _holder_process(run_dir):
    """A process that takes ``run_dir``'s lock and holds it until killed."""
    context = multiprocessing.get_context("fork")
    ready = context.Event()
    holder = context.Process(target=_hold_forever, args=(run_dir, ready))
    holder.start()
    assert ready.wait(60)
    return holder


def test_a_lock_left_by_a_killed_run_is_taken_over_with_a_warning(tmp_path, caplog):
    run_dir = tmp_path / "run"
    holder = _holder_process(run_dir)
    with pytest.raises(RunFolderInUse, match=f"pid {holder.pid} "):
        Run(_cfg(run_dir))
    os.kill(holder.pid, signal.SIGKILL)
    holder.join(timeout=60)
    with caplog.at_level(logging.WARNING, logger="torchrl_auv.training.run.lock"):
        assert Run(_cfg(run_dir)).dir == run_dir
    assert f"pid {holder.pid} " in caplog.text and "no longer running" in caplog.text
    assert f"pid {os.getpid()} " in (run_dir / LOCK_FILE).read_text()


def test_a_start_refused_by_its_own_checks_leaves_no_lock_file(tmp_path):
    run_dir = tmp_path / "run"
    with pytest.raises(ValueError, match="holds no checkpoints"):
        Run(_cfg(run_dir, resume=str(run_dir)))
    assert not (run_dir / LOCK_FILE).exists()
    acquire_run_folder(run_dir)  # and the lock was let go
    release_run_folder(run_dir)
