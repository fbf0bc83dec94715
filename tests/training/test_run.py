"""Run: the typed counters survive a checkpoint; the env's history comes from cfg.env."""

from __future__ import annotations

import pytest
import torch
from omegaconf import OmegaConf

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
    assert run.restore({"net": net}) == 100
    run.progress.frames, run.progress.updates = 40, 7
    run.rotation.save(run.checkpoint, step=40)
    weights = net.weight.detach().clone()

    fresh_net = torch.nn.Linear(2, 1)
    resumed = training.Run(_cfg(tmp_path / "other", resume=str(tmp_path / "run")))
    assert resumed.dir == tmp_path / "run"
    assert resumed.restore({"net": fresh_net}) == 60  # frames still to go
    assert resumed.progress == training.Progress(frames=40, updates=7)
    torch.testing.assert_close(fresh_net.weight, weights)


def test_run_steps_need_restore_and_track_first(tmp_path):
    run = training.Run(_cfg(tmp_path))
    with pytest.raises(RuntimeError, match=r"Run.restore"):
        run.track()
    with pytest.raises(RuntimeError, match=r"Run.track"):
        run.finish(None)


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
    from torchrl_auv.training.summary import write_eval

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
