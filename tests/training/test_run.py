"""Run: the typed counters survive a checkpoint; the env's history comes from cfg.env."""

from __future__ import annotations

import pytest
import torch
from omegaconf import OmegaConf
from tensordict import TensorDict

from torchrl_auv import training


def _cfg(run_dir, resume=None):
    return OmegaConf.create(
        {
            "seed": 0,
            "threads": 1,
            "device": "cpu",
            "run_dir": str(run_dir),
            "resume": resume,
            "logger": {"backend": None, "exp_name": "t", "project": "p", "offline": True},
            "checkpoint": {"keep_last": 2, "every_frames": 10},
            "collector": {"total_frames": 100},
        }
    )


def test_a_resumed_run_continues_from_its_counters_and_weights(tmp_path):
    net = torch.nn.Linear(2, 1)
    run = training.Run(_cfg(tmp_path / "run"))
    assert run.restore(modules={"net": net}) == 100
    run.progress.frames, run.progress.updates = 40, 7
    run.rotation.save(run.checkpoint, step=40)
    weights = net.weight.detach().clone()

    fresh_net = torch.nn.Linear(2, 1)
    resumed = training.Run(_cfg(tmp_path / "other", resume=str(tmp_path / "run")))
    assert resumed.dir == tmp_path / "run"
    assert resumed.restore(modules={"net": fresh_net}) == 60  # frames still to go
    assert resumed.progress == training.Progress(frames=40, updates=7)
    torch.testing.assert_close(fresh_net.weight, weights)


def test_run_steps_need_restore_and_collect_first(tmp_path):
    run = training.Run(_cfg(tmp_path))
    with pytest.raises(RuntimeError, match=r"Run.restore"):
        next(run.collect([]))
    with pytest.raises(RuntimeError, match=r"Run.collect"):
        run.finish(None)
    with pytest.raises(TypeError, match=r"the first argument is the learner"):
        run.restore({"net": torch.nn.Linear(2, 1)})  # the old call: modules first


class _Learner:
    """A learner's checkpoint contract and its counter, nothing else."""

    def __init__(self):
        self.net = torch.nn.Linear(2, 1)
        self.progress = training.Progress()

    def checkpoint_modules(self):
        return {"net": self.net}

    def step(self):
        self.progress.updates += 1


class _Collector:
    def __init__(self, batches, frames):
        self.batches, self.frames, self.shut = batches, frames, False

    def __iter__(self):
        for _ in range(self.batches):  # what the run reads of a batch: the cost, the ends
            yield TensorDict(
                {
                    ("next", "agents", "cost"): torch.ones(self.frames, 2, 1),
                    ("next", "done"): torch.zeros(self.frames, 1, dtype=torch.bool),
                },
                [self.frames],
            )

    def shutdown(self):
        self.shut = True


def test_the_run_counts_the_frames_it_collects_and_the_updates_its_learner_makes(tmp_path):
    """Run.collect counts a batch's frames before the loop's body sees it; the learner given to
    restore counts its updates into the run's counters, which the checkpoint saves."""
    cfg = _cfg(tmp_path / "run")
    run, learner = training.Run(cfg), _Learner()
    assert run.restore(learner) == 100 and learner.progress is run.progress
    seen = []
    for _ in run.collect(_Collector(batches=4, frames=25)):
        seen.append(run.progress.frames)
        learner.step()
        learner.step()
        run.log({"train/x": 1.0})
    facts = run.finish(_Collector(0, 1))
    assert seen == [25, 50, 75, 100] and run.progress == training.Progress(100, 8)
    assert facts["gradient updates"] == 8
    resumed = training.Run(_cfg(tmp_path / "other", resume=str(tmp_path / "run")))
    fresh = _Learner()
    assert resumed.restore(fresh) == 0 and fresh.progress == training.Progress(100, 8)
    assert list(resumed.collect(_Collector(batches=1, frames=25))) == []  # nothing left to do


@pytest.mark.parametrize(("history", "ok"), [(None, 0), (0, 0), (3, 3), (-1, None), (2.5, None)])
def test_the_envs_history_is_a_field_of_the_env_config(history, ok):
    env = {"sea_state": "ideal"} if history is None else {"sea_state": "ideal", "history": history}
    if ok is None:
        with pytest.raises(ValueError, match=r"env\.history must be an int >= 0"):
            training.env_history({"env": env})
    else:
        assert training.env_history({"env": env}) == ok


def test_eval_csv_is_written_whole_or_not_at_all(tmp_path):
    """eval.csv marks a finished run: a write that fails midway leaves none (nor its
    temporary file), and a rewrite replaces the old one whole."""
    from torchrl_auv.training.run.summary import write_eval

    rows = [{"sea_state": "ves", "policy": "sac", "ssn": 1.0}]
    path = write_eval(rows, tmp_path)
    assert path.read_text().splitlines() == ["sea_state,policy,ssn", "ves,sac,1.0"]
    with pytest.raises(ValueError):  # a row with a column the header lacks, after the header
        write_eval([{"sea_state": "es", "policy": "sac"}, {"unknown": 1}], tmp_path)
    assert path.read_text().splitlines()[1] == "ves,sac,1.0"  # the old one, untouched
    assert [p.name for p in tmp_path.iterdir()] == ["eval.csv"]
    path.unlink()
    with pytest.raises(ValueError):
        write_eval([{"sea_state": "es", "policy": "sac"}, {"unknown": 1}], tmp_path)
    assert list(tmp_path.iterdir()) == []
