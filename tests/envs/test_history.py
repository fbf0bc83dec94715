"""StateActionHistory: contents against a reference built from the rollout, resets, specs."""

from __future__ import annotations

import pytest
import torch
from torchrl.envs import GymEnv, TransformedEnv
from torchrl.envs.utils import check_env_specs
from torchrl.testing.mocking_classes import CountingEnv

from torchrl_auv.envs.history import StateActionHistory, history_key_for

L = 3


def _reference_history(obs, act, is_first):
    """Per element, the last L (obs, action) pairs since the episode start, oldest first."""
    steps, batch = obs.shape[:2]
    ref_obs = torch.zeros(steps, batch, L, obs.shape[-1])
    ref_act = torch.zeros(steps, batch, L, act.shape[-1])
    ref_mask = torch.zeros(steps, batch, L, dtype=torch.bool)
    for b in range(batch):
        pairs: list[tuple[torch.Tensor, torch.Tensor]] = []
        for t in range(steps):
            if is_first[t, b]:
                pairs = []
            recent = pairs[-L:]
            for j, (o, a) in enumerate(reversed(recent)):
                ref_obs[t, b, L - 1 - j] = o
                ref_act[t, b, L - 1 - j] = a
                ref_mask[t, b, L - 1 - j] = True
            pairs.append((obs[t, b].float(), act[t, b].float()))
    return ref_obs, ref_act, ref_mask


def test_history_matches_reference_across_partial_resets():
    env = TransformedEnv(CountingEnv(max_steps=4, batch_size=[3]), StateActionHistory(L))
    env.set_seed(0)
    td = env.rollout(25, break_when_any_done=False)  # [3, 25]: envs reset at different times
    td = td.transpose(0, 1)  # [time, batch]
    done = td["next", "done"].squeeze(-1)
    is_first = torch.zeros_like(done)
    is_first[0] = True
    is_first[1:] = done[:-1]
    assert done.any() and not done.all(), "the scenario must contain partial resets"
    ref_obs, ref_act, ref_mask = _reference_history(td["observation"], td["action"], is_first)
    torch.testing.assert_close(td["history", "observation"].float(), ref_obs)
    torch.testing.assert_close(td["history", "action"].float(), ref_act)
    assert torch.equal(td["history", "mask"], ref_mask)


def test_history_specs_and_gym_env():
    env = TransformedEnv(GymEnv("Pendulum-v1"), StateActionHistory(10))
    check_env_specs(env, seed=0)
    td = env.rollout(12)
    assert td["history", "observation"].shape == (12, 10, 3)
    assert td["history", "action"].shape == (12, 10, 1)
    # the newest entry at step t is the pair (o_{t-1}, a_{t-1})
    torch.testing.assert_close(td["history", "observation"][1:, -1], td["observation"][:-1])
    torch.testing.assert_close(td["history", "action"][1:, -1], td["action"][:-1])
    assert td["history", "mask"].sum(-1).tolist() == [min(t, 10) for t in range(12)]


def test_history_key_default_follows_observation_key():
    assert history_key_for(("agents", "observation")) == ("agents", "history")
    transform = StateActionHistory(
        2, observation_key=("agents", "observation"), action_key=("agents", "action")
    )
    assert transform.history_obs_key == ("agents", "history", "observation")


def test_bad_length_raises():
    with pytest.raises(ValueError, match="length"):
        StateActionHistory(0)
