"""Gymnasium ids: registered once, pass gymnasium's own env checker."""

from __future__ import annotations

import importlib

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import torchrl_auv.envs
from torchrl_auv.envs.gym import register_gymnasium_ids


def test_gymnasium_make_and_env_checker():
    env = gymnasium.make("torchrl_auv/Tracking-v0", sea_state="es", max_steps=5)
    check_env(env.unwrapped, skip_render_check=True)
    env.reset(seed=3)
    total, steps, done = 0.0, 0, False
    while not done:
        _, reward, terminated, truncated, info = env.step(env.action_space.sample())
        total += reward
        steps += 1
        done = terminated or truncated
    assert steps == 5 and np.isfinite(total) and "metrics" in info and info["cost"] >= 0


def test_same_seed_same_episode():
    def episode(seed):
        env = gymnasium.make("torchrl_auv/Tracking-v0", max_steps=3)
        obs, _ = env.reset(seed=seed)
        return [obs] + [env.step(np.zeros(3, np.float32))[0] for _ in range(3)]

    assert all(np.array_equal(a, b) for a, b in zip(episode(1), episode(1), strict=True))


def test_registration_is_idempotent():
    register_gymnasium_ids()
    importlib.reload(torchrl_auv.envs)
    assert "torchrl_auv/Tracking-v0" in gymnasium.registry
    assert "torchrl_auv/DataCollection-v2" in gymnasium.registry


def test_data_collection_id_passes_the_env_checker():
    env = gymnasium.make("torchrl_auv/DataCollection-v2", num_auvs=2, max_steps=4)
    check_env(env.unwrapped, skip_render_check=True)
    rendering = gymnasium.make(
        "torchrl_auv/DataCollection-v2", render_mode="rgb_array", max_steps=4
    )
    check_env(rendering.unwrapped)  # with its render check
    obs, _ = env.reset(seed=0)
    assert obs.shape == (76,) and env.action_space.shape == (6,)
    done, info = False, {}
    while not done:
        _, reward, terminated, truncated, info = env.step(env.action_space.sample())
        done = terminated or truncated
    assert np.isfinite(reward) and info["cost"] >= 0 and "ssn" in info["metrics"]


@pytest.mark.parametrize("env_id", ["torchrl_auv/DataCollection-v2", "torchrl_auv/Tracking-v0"])
def test_a_non_finite_or_misshapen_gymnasium_action_is_an_error_naming_it(env_id):
    """Through gymnasium a NaN action used to end the episode as diverged with NaN metrics."""
    env = gymnasium.make(env_id, max_steps=4)
    env.reset(seed=0)
    action = env.action_space.sample()
    action[0] = np.nan
    with pytest.raises(ValueError, match="action has 1 non-finite entries"):
        env.step(action)
    with pytest.raises(ValueError, match=rf"action must have shape \[{action.size}\]"):
        env.step(np.zeros(action.size - 1, dtype=np.float32))


@pytest.mark.parametrize("env_id", ["torchrl_auv/DataCollection-v2", "torchrl_auv/Tracking-v0"])
def test_unseeded_envs_start_differently_as_gymnasium_expects(env_id):
    """Gymnasium's convention: no seed means entropy. Unseeded, every env used to start as seed
    0: a vector env's workers trained on copies of one scene."""
    starts = [gymnasium.make(env_id, max_steps=3).reset()[0] for _ in range(2)]
    assert not np.array_equal(*starts)
    vector = gymnasium.make_vec(env_id, num_envs=2, vectorization_mode="sync", max_steps=3)
    first, _ = vector.reset()
    assert not np.array_equal(first[0], first[1])
    env = gymnasium.make(env_id, max_steps=3)  # seeded once, later resets continue its stream
    seeded = [env.reset(seed=7)[0], env.reset()[0]]
    again = gymnasium.make(env_id, max_steps=3)
    replayed = [again.reset(seed=7)[0], again.reset()[0]]
    assert all(np.array_equal(a, b) for a, b in zip(seeded, replayed, strict=True))
    constructed = [gymnasium.make(env_id, max_steps=3, seed=5).reset()[0] for _ in range(2)]
    assert np.array_equal(*constructed)  # a seed keyword is a seed too


def test_render_mode_none_is_accepted_and_an_unknown_mode_is_named():
    env = gymnasium.make("torchrl_auv/Tracking-v0", render_mode=None, max_steps=3)
    assert env.unwrapped.render_mode is None
    with pytest.raises(ValueError, match="render_mode must be None"):
        gymnasium.make("torchrl_auv/Tracking-v0", render_mode="human")


@pytest.mark.parametrize("env_id", ["torchrl_auv/DataCollection-v2", "torchrl_auv/Tracking-v0"])
def test_reset_and_step_infos_have_the_same_keys(env_id):
    """Minari's DataCollector(record_infos=True) refuses infos whose keys change."""
    env = gymnasium.make(env_id, max_steps=3)
    _, first = env.reset(seed=0)
    assert first["cost"] == 0.0
    infos = [env.step(env.action_space.sample())[-1] for _ in range(3)]

    def keys(info):
        return sorted(info), sorted(info["metrics"])

    assert all(keys(info) == keys(first) for info in infos)
    assert infos[-1]["metrics"] != first["metrics"]  # the episode's metrics, not reset's
