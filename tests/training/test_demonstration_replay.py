"""SAC with the expert's demonstrations: half of each batch from them, collected on their own
scenes by the scripted expert, the count checked before any work."""

from __future__ import annotations

import pytest
import torch
from omegaconf import OmegaConf

from torchrl_auv import training


def _frames(n, marker):
    env = training.make_env("ideal", seed=0, num_envs=1)
    frames = training.select_for_replay(env.rollout(n))
    frames["next", "agents", "reward"] = torch.full_like(frames["next", "agents", "reward"], marker)
    return frames


def test_every_batch_is_half_demonstrations():
    online = training.make_replay_buffer(100, batch_size=8)
    online.extend(_frames(5, 0.0))
    sample = training.symmetric_sampler(online, _frames(7, 1.0), batch_size=8)
    for _ in range(5):
        batch = sample()
        assert batch.batch_size == torch.Size([8])
        from_demos = batch["next", "agents", "reward"][:, 0, 0] == 1.0
        assert from_demos.sum().item() == 4
    with pytest.raises(ValueError, match="batch_size must be even"):
        training.symmetric_sampler(online, _frames(7, 1.0), batch_size=7)


def test_the_demonstrations_are_the_experts_on_their_own_scenes():
    cfg = OmegaConf.create(
        {
            "seed": 3,
            "device": "cpu",
            "env": {
                "sea_state": "ideal",
                "controller": "s_surface",
                "rate_model": "shannon",
                "num_envs": 2,
                "max_steps": 50,
                "compile_physics": False,
            },
            "collector": {"frames_per_batch": 6},
            "demonstrations": {"frames": 10},
            "replay_buffer": {"batch_size": 4},
        }
    )
    online = training.make_replay_buffer(100, batch_size=4)
    _, frames = training.sampler_from_config(cfg, online)
    assert frames == 12  # two collected batches of 6 cover the 10 asked for
    scenes = training.env_factory(cfg)(seed=3 + training.DEMONSTRATION_SEED_OFFSET)
    expert = training.expert_policy(scenes)
    reference = training.select_for_replay(scenes.rollout(3, expert))  # [2 scenes x 3] frames
    demos = training.collect_demonstrations(cfg, 6)
    torch.testing.assert_close(demos["agents", "action"], reference["agents", "action"])
    assert training.sampler_from_config({**cfg, "demonstrations": {"frames": 0}}, online)[1] == 0


def test_a_bad_demonstration_count_is_named_before_any_work():
    with pytest.raises(ValueError, match=r"demonstrations\.frames"):
        training.check_choices({"demonstrations": {"frames": -5}})
    with pytest.raises(ValueError, match=r"demonstrations\.frames"):
        training.demonstration_frames({"demonstrations": {"frames": 2.5}})
