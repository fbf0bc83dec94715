"""ArtefactCache: one folder per values, reused; other values elsewhere; stale folders refused;
a concurrent build of the same values happens once; a failed build leaves nothing behind; a
resumable one cut short goes on in the next build."""

from __future__ import annotations

import json
import multiprocessing
import os
import time

import pytest

from torchrl_auv.training.first_stage.artefacts import ArtefactCache, values_key


def _build_counting(folder):
    (folder / "weights.txt").write_text("w")
    counter = folder.parent / "builds.txt"
    with open(counter, "a") as handle:
        handle.write("x")


def test_same_values_reuse_the_folder_and_other_values_get_their_own(tmp_path):
    cache = ArtefactCache(tmp_path)
    values = {"sea_state": "ves", "seed": 0, "model": {"hidden": 256}}
    folder, built = cache.get_or_build("ves-seed0", values, _build_counting)
    assert built and (folder / "weights.txt").read_text() == "w"
    assert json.loads((folder / "values.json").read_text()) == values
    # the same values in another order: the same key, reused without building
    again, built = cache.get_or_build("ves-seed0", dict(reversed(values.items())), _build_counting)
    assert again == folder and not built
    other, built = cache.get_or_build(
        "ves-seed0", {**values, "model": {"hidden": 128}}, _build_counting
    )
    assert built and other != folder and folder.exists()
    assert (tmp_path / "builds.txt").read_text() == "xx"
    assert values_key(values) in folder.name


def test_a_folder_whose_stored_values_differ_is_refused_naming_the_keys(tmp_path):
    cache = ArtefactCache(tmp_path)
    values = {"seed": 0, "pretraining": {"lr": 1e-3, "steps": 10}}
    folder, _ = cache.get_or_build("stage", values, _build_counting)
    stored = json.loads((folder / "values.json").read_text())
    stored["pretraining"]["lr"] = 1e-4  # edited by hand: no longer what its name says
    (folder / "values.json").write_text(json.dumps(stored))
    with pytest.raises(ValueError, match=r"pretraining\.lr"):
        cache.get_or_build("stage", values, _build_counting)


def test_a_failed_build_leaves_no_artefact_and_the_next_call_builds(tmp_path):
    cache = ArtefactCache(tmp_path)

    def fail(folder):
        (folder / "half.txt").write_text("half")
        raise RuntimeError("interrupted")

    with pytest.raises(RuntimeError, match="interrupted"):
        cache.get_or_build("stage", {"seed": 0}, fail)
    assert [p.name for p in tmp_path.iterdir() if not p.name.endswith(".lock")] == []
    folder, built = cache.get_or_build("stage", {"seed": 0}, _build_counting)
    assert built and not (folder / "half.txt").exists()


def test_a_resumable_build_goes_on_from_the_newest_build_cut_short(tmp_path):
    """resumable=True: an interruption keeps the folder, the next build of the same values
    gets it (the newest of several; the others are cleared); an error still leaves nothing."""
    cache = ArtefactCache(tmp_path)
    name = cache.folder("stage", {"seed": 0}).name

    def first_phase_then_stop(folder):
        (folder / "phase1.txt").write_text("done")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        cache.get_or_build("stage", {"seed": 0}, first_phase_then_stop, resumable=True)
    older = tmp_path / f".{name}.partial-111"  # a build killed before that one
    older.mkdir()
    (older / "stale.txt").write_text("old")
    os.utime(older, (time.time() - 100, time.time() - 100))
    seen = []

    def go_on(folder):
        seen.append(sorted(p.name for p in folder.iterdir()))
        (folder / "phase2.txt").write_text("done")

    folder, built = cache.get_or_build("stage", {"seed": 0}, go_on, resumable=True)
    assert built and seen == [["phase1.txt"]]
    assert sorted(p.name for p in folder.iterdir()) == ["phase1.txt", "phase2.txt", "values.json"]
    assert not list(tmp_path.glob(".*.partial-*"))

    def fail(folder):
        (folder / "half.txt").write_text("half")
        raise RuntimeError("a bug")

    with pytest.raises(RuntimeError, match="a bug"):
        cache.get_or_build("stage", {"seed": 1}, fail, resumable=True)
    assert not list(tmp_path.glob(".*.partial-*"))


def test_builds_cut_short_by_a_kill_are_cleared_by_the_next_build(tmp_path):
    """A SIGKILL skips the cleanup: its half-built folder stays until the next build of the
    same values (which holds the lock, so no build of them is running) removes it."""
    cache = ArtefactCache(tmp_path)
    name = cache.folder("stage", {"seed": 0}).name
    for pid in (111, 222):  # two killed builds
        (tmp_path / f".{name}.partial-{pid}").mkdir()
        (tmp_path / f".{name}.partial-{pid}" / "demos.pt").write_text("half")
    other = tmp_path / ".other-values.partial-333"  # another artefact's: not touched
    other.mkdir()
    folder, built = cache.get_or_build("stage", {"seed": 0}, _build_counting)
    assert built and folder.is_dir()
    left = sorted(p.name for p in tmp_path.iterdir() if ".partial-" in p.name)
    assert left == [other.name]


def _slow_build(folder):
    import time

    time.sleep(1.0)
    _build_counting(folder)


def _worker(root):
    ArtefactCache(root).get_or_build("stage", {"seed": 0}, _slow_build)


def test_two_processes_asking_for_the_same_values_build_it_once(tmp_path):
    context = multiprocessing.get_context("spawn")
    procs = [context.Process(target=_worker, args=(str(tmp_path),)) for _ in range(2)]
    for proc in procs:
        proc.start()
    for proc in procs:
        proc.join(60)
        assert proc.exitcode == 0
    assert (tmp_path / "builds.txt").read_text() == "x"


def test_bad_names_are_refused(tmp_path):
    with pytest.raises(ValueError, match="name"):
        ArtefactCache(tmp_path).folder("../up", {})
