"""A resumed run goes on with its replay buffer when the checkpoint holds it, and says so when
it does not (``checkpoint.replay_buffer``; the paper grid's jobs resume across sittings)."""

from __future__ import annotations

import logging

import torch
from omegaconf import OmegaConf
from tensordict import TensorDict

from torchrl_auv.training import Progress
from torchrl_auv.training.replay import make_replay_buffer
from torchrl_auv.training.run.training_run import _prepare_resume


def _cfg(run_dir, *, keep_buffer: bool, resume: bool):
    return OmegaConf.create(
        {
            "resume": str(run_dir) if resume else None,
            "checkpoint": {"replay_buffer": keep_buffer, "keep_last": 2},
            "collector": {"total_frames": 100},
        }
    )


def _save_a_run(run_dir, keep_buffer: bool) -> TensorDict:
    frames = TensorDict({"observation": torch.randn(30, 3), "cost": torch.rand(30, 1)}, [30])
    buffer = make_replay_buffer(100, batch_size=4)
    buffer.extend(frames)
    progress = Progress()
    checkpoint, rotation, _ = _prepare_resume(
        _cfg(run_dir, keep_buffer=keep_buffer, resume=False),
        run_dir,
        {"net": torch.nn.Linear(3, 1)},
        progress,
        buffer,
    )
    progress.frames = 30
    rotation.save(checkpoint, step=30)
    return frames


def _resume(run_dir, keep_buffer: bool):
    buffer = make_replay_buffer(100, batch_size=4)
    progress = Progress()
    *_, remaining = _prepare_resume(
        _cfg(run_dir, keep_buffer=keep_buffer, resume=True),
        run_dir,
        {"net": torch.nn.Linear(3, 1)},
        progress,
        buffer,
    )
    return buffer, remaining


def test_a_run_resumed_with_its_buffer_goes_on_from_the_same_frames(tmp_path, caplog):
    frames = _save_a_run(tmp_path, keep_buffer=True)
    with caplog.at_level(logging.WARNING):
        buffer, remaining = _resume(tmp_path, keep_buffer=True)
    assert remaining == 70 and len(buffer) == 30
    assert torch.equal(buffer[:30]["observation"], frames["observation"])
    assert "without the replay buffer" not in caplog.text


def test_a_run_resumed_without_its_buffer_says_it_starts_from_an_empty_one(tmp_path, caplog):
    _save_a_run(tmp_path, keep_buffer=False)
    with caplog.at_level(logging.WARNING):
        buffer, remaining = _resume(tmp_path, keep_buffer=False)
    assert remaining == 70 and len(buffer) == 0
    assert "resumed without the replay buffer" in caplog.text and "at 30 frames" in caplog.text
