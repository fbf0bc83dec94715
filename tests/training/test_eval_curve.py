"""RunTracker's learning curve: deterministic held-out evaluations at frame 0 and each time the
frame count passes a multiple of eval.every_frames, to eval_curve.csv and eval/ metrics."""

from __future__ import annotations

import csv

import torch
from omegaconf import OmegaConf
from tensordict import TensorDict
from tensordict.nn import TensorDictModule

from torchrl_auv import training


def _cfg(every):
    return OmegaConf.create(
        {
            "env": {"sea_state": "ideal", "controller": "s_surface", "rate_model": "shannon"},
            "collector": {"total_frames": 40},
            "checkpoint": {"every_frames": 10_000},
            "eval": {"seed": 100000, "every_frames": every, "curve_envs": 1, "curve_steps": 4},
        }
    )


def _batch():
    return TensorDict(
        {
            "next": {
                "agents": {"cost": torch.ones(4, 2, 1)},
                "done": torch.zeros(4, 1, dtype=torch.bool),
            }
        },
        [4],
    )


class _Calls(TensorDictModule):
    """Zero actions, counting the decisions it is asked for."""

    def __init__(self):
        super().__init__(
            lambda obs: torch.zeros(*obs.shape[:-1], 3),
            in_keys=[("agents", "observation")],
            out_keys=[("agents", "action")],
        )
        self.calls = 0

    def forward(self, tensordict, *args, **kwargs):
        self.calls += 1
        return super().forward(tensordict, *args, **kwargs)


def _curve_steps(path):
    with open(path) as handle:
        rows = list(csv.DictReader(handle, fieldnames=("step", "key", "value")))
    return sorted({int(r["step"]) for r in rows if r["key"] == "eval/cost_mean"}), rows


def test_the_curve_is_evaluated_at_the_start_and_at_each_multiple(tmp_path):
    policy, progress = _Calls(), training.Progress()
    tracker = training.RunTracker(
        _cfg(10), tmp_path, None, progress, None, None, eval_policy=policy
    )
    assert policy.calls == 4  # frame 0: one episode of curve_steps decisions
    for frames in (8, 16, 30, 31):
        progress.frames = frames
        tracker.step(_batch(), {})
    steps, rows = _curve_steps(tmp_path / "eval_curve.csv")
    assert steps == [0, 16, 30]  # 8: not yet 10; 30 jumps two multiples: one evaluation
    assert policy.calls == 12
    keys = {r["key"] for r in rows}
    assert {"eval/cost_mean", "eval/ssn", "eval/terminated", "time/eval_s"} <= keys
    assert tracker.eval_seconds > 0


def test_a_resumed_run_does_not_evaluate_its_start_again_and_off_means_off(tmp_path):
    policy, progress = _Calls(), training.Progress(frames=16)
    tracker = training.RunTracker(
        _cfg(10), tmp_path, None, progress, None, None, eval_policy=policy
    )
    progress.frames = 19
    tracker.step(_batch(), {})
    assert policy.calls == 0
    progress.frames = 20
    tracker.step(_batch(), {})
    assert _curve_steps(tmp_path / "eval_curve.csv")[0] == [20]
    off = _Calls()
    (tmp_path / "off").mkdir()
    training.RunTracker(
        _cfg(None), tmp_path / "off", None, training.Progress(), None, None, eval_policy=off
    ).step(_batch(), {})
    assert off.calls == 0 and not (tmp_path / "off" / "eval_curve.csv").exists()


def test_a_resumed_run_drops_the_curve_rows_logged_after_its_checkpoint(tmp_path):
    """The session that died logged rows past its last checkpoint; resumed from frames 16,
    the curves go on from 16 and never run back in time."""
    first = training.RunTracker(
        _cfg(10), tmp_path, None, training.Progress(), None, None, eval_policy=_Calls()
    )
    for frames in (10, 20, 30):  # curve points at 0, 10, 20, 30; training rows at 10, 20, 30
        first.progress.frames = frames
        first.step(_batch(), {})
    training.RunTracker(
        _cfg(10), tmp_path, None, training.Progress(frames=16), None, None, eval_policy=_Calls()
    )
    assert _curve_steps(tmp_path / "eval_curve.csv")[0] == [0, 10]
    train_rows = _curve_steps(tmp_path / "train_curve.csv")[1][1:]  # after the header
    assert train_rows and {int(r["step"]) for r in train_rows} == {10}


def test_a_run_started_again_from_frame_0_owns_no_earlier_rows(tmp_path):
    """A session killed before its first checkpoint, started again (resume= finds nothing to
    load): its frame-0 evaluation and training rows are gone, not repeated beside the new."""
    first = training.RunTracker(
        _cfg(10), tmp_path, None, training.Progress(), None, None, eval_policy=_Calls()
    )
    first.progress.frames = 8
    first.step(_batch(), {})
    training.RunTracker(
        _cfg(10), tmp_path, None, training.Progress(), None, None, eval_policy=_Calls()
    )
    steps, rows = _curve_steps(tmp_path / "eval_curve.csv")
    assert steps == [0] and len([r for r in rows if r["key"] == "eval/cost_mean"]) == 1
    assert _curve_steps(tmp_path / "train_curve.csv")[1][1:] == []


def test_the_bar_shows_the_last_ended_episodes_not_nan(tmp_path):
    tracker = training.RunTracker(_cfg(None), tmp_path, None, training.Progress(), None, None)
    tracker.step(_batch(), {})
    assert set(tracker.bar.postfix.replace(" ", "").split(",")) == {"cost=1.000"}  # none ended
    ended = _batch()
    ended["next", "done"][-1] = True
    names = ("sdr", "ssn", "collisions", "violations")
    ended["next", "metrics"] = TensorDict({name: torch.full((4,), 3.0) for name in names}, [4])
    tracker.step(ended, {})
    tracker.step(_batch(), {})  # no episode ended in this batch: the bar keeps the last ones
    assert "sdr=3.0" in tracker.bar.postfix and "ssn=3.0" in tracker.bar.postfix
    assert "nan" not in tracker.bar.postfix


class _Saves:
    """A rotation that records, at each save, the frame and the curve points logged by then."""

    def __init__(self, curve):
        self.curve, self.saves = curve, []

    def save(self, checkpoint, step):
        logged = _curve_steps(self.curve)[0] if self.curve.exists() else []
        self.saves.append((step, logged))


def test_background_curve_points_are_the_foreground_ones_and_checkpoints_hold_them(tmp_path):
    """eval.curve_background: the points come back from a worker process with the numbers the
    loop's own evaluation gives, and a checkpoint at F is saved only once every point <= F
    is logged."""
    env = training.held_out_env(_cfg(10), 1, 4)("ideal", 0)
    actor = training.make_actor(env, (8,))  # picklable, deterministic
    runs = {}
    for background in (False, True):
        cfg = _cfg(10)
        cfg.eval.curve_background = background
        cfg.checkpoint.every_frames = 8
        folder = tmp_path / str(background)
        folder.mkdir()
        rotation = _Saves(folder / "eval_curve.csv")
        tracker = training.RunTracker(
            cfg, folder, None, training.Progress(), None, rotation, eval_policy=actor
        )
        for frames in (8, 16, 24, 32, 40):
            tracker.progress.frames = frames
            tracker.step(_batch(), {})
        tracker.finish(type("Collector", (), {"shutdown": lambda self: None})())
        points = [0, 16, 24, 32, 40]  # frame 0, then where the count passed a multiple of 10
        for frames, logged in rotation.saves:
            assert [p for p in points if p <= frames] == [s for s in logged if s <= frames]
        steps, rows = _curve_steps(folder / "eval_curve.csv")
        assert steps == points and rotation.saves[-1][0] == 40
        runs[background] = {
            (r["step"], r["key"]): r["value"] for r in rows if r["key"].startswith("eval/")
        }
    assert runs[True] == runs[False]


def test_a_session_that_trains_nothing_reports_no_rate_rather_than_zero(tmp_path):
    done = type("Collector", (), {"shutdown": lambda self: None})()
    rotation = _Saves(tmp_path / "eval_curve.csv")
    resumed = training.RunTracker(
        _cfg(None), tmp_path, None, training.Progress(frames=40), None, rotation
    )
    facts = resumed.finish(done)
    assert facts["training frames/s"].startswith("none trained")
    assert (facts["frames"], facts["frames this session"]) == (40, 0)
    fresh = training.RunTracker(_cfg(None), tmp_path, None, training.Progress(), None, rotation)
    fresh.progress.frames = 8
    facts = fresh.finish(done)
    assert facts["training frames/s"] > 0 and facts["frames this session"] == 8
