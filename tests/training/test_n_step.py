"""n-step returns for the Q critics (``optim.n_steps``): the stored frames against the
definition, windows across batch boundaries, and the loss's discount per frame."""

from __future__ import annotations

import pytest
import torch

from torchrl_auv import training

GAMMA = 0.9
N = 3


@pytest.fixture(scope="module")
def rollout():
    """9 frames of 2 scenes whose episodes end at frames 3 and 7 (max_steps 4), rewards
    replaced by distinct values and frame 3 of scene 0 marked terminated."""
    env = training.make_env("ideal", seed=0, num_envs=2, max_steps=4)
    data = env.rollout(9, break_when_any_done=False)
    assert data["next", "done"][..., 0].nonzero()[:, 1].tolist() == [3, 7, 3, 7]
    reward = torch.arange(2 * 9 * 2, dtype=torch.float32).reshape(2, 9, 2, 1) / 10
    data["next", "agents", "reward"] = reward
    terminated = torch.zeros(2, 9, 2, 1, dtype=torch.bool)
    terminated[0, 3] = True
    data["next", "agents", "terminated"] = terminated
    return data


def by_definition(data, t: int, scene: int):
    """Frame ``t``'s n-step reward, its window's length and its window's last frame."""
    done = data["next", "done"][scene, :, 0]
    reward = data["next", "agents", "reward"][scene]
    total, m = torch.zeros_like(reward[0]), 0
    while m < N:
        total = total + GAMMA**m * reward[t + m]
        m += 1
        if done[t + m - 1]:
            break
    return total, m, t + m - 1


def test_each_frame_sums_its_window_and_takes_the_state_and_flags_at_its_end(rollout):
    frames = training.NStepReturns(N, GAMMA)(rollout.clone())
    assert frames.batch_size == torch.Size([2, 9 - N])
    lengths = []
    for scene in range(2):
        for t in range(9 - N):
            reward, m, last = by_definition(rollout, t, scene)
            got = frames[scene, t]
            torch.testing.assert_close(got["next", "agents", "reward"], reward)
            assert got[training.N_STEPS_KEY].flatten().tolist() == [m, m]
            for key in (("agents", "observation"), ("agents", "terminated")):
                assert torch.equal(got["next", key], rollout["next", key][scene, last])
            lengths.append(m)
    assert lengths[:6] == [3, 3, 2, 1, 3, 3]  # cut at the episode's end (frame 3)
    # the terminated flag reached frames 1-3 of scene 0, whose windows end at frame 3
    assert frames[0]["next", "agents", "terminated"][:, 0].flatten().tolist() == [
        False,
        True,
        True,
        True,
        False,
        False,
    ]


def test_windows_run_across_batch_boundaries(rollout):
    whole = training.NStepReturns(N, GAMMA)(rollout.clone())
    split = training.NStepReturns(N, GAMMA)
    first, second = split(rollout[:, :5].clone()), split(rollout[:, 5:].clone())
    assert first.shape[-1] == 5 - N and second.shape[-1] == 4
    joined = torch.cat([first, second], dim=1)
    for key in (("next", "agents", "reward"), ("next", "agents", "observation")):
        torch.testing.assert_close(joined[key], whole[key])
    assert torch.equal(joined[training.N_STEPS_KEY], whole[training.N_STEPS_KEY])


def test_too_few_decisions_store_nothing_yet_and_the_replay_keys_are_kept(rollout):
    returns = training.NStepReturns(N, GAMMA)
    assert training.select_for_replay(rollout[:, :N].clone(), n_step=returns) is None
    frames = training.select_for_replay(rollout[:, N:].clone(), n_step=returns)
    assert frames.batch_size == torch.Size([2 * (9 - N)])
    assert set(frames.keys(True, True)) == set(training.REPLAY_KEYS) | set(training.N_STEP_KEYS)


def test_the_sac_target_discounts_by_each_frames_own_steps():
    env = training.make_env("ideal", seed=0, num_envs=2)
    actor = training.make_actor(env, (8,))
    loss, _ = training.make_sac_loss(actor, training.make_q_critic(env, (8,)), env, gamma=GAMMA)
    reward, next_value = torch.rand(4, 2, 1), torch.rand(4, 2, 1)
    td = training.select_for_replay(env.rollout(2)).clone()
    td["next", "agents", "reward"] = reward
    td["next", "agents", "terminated"] = torch.zeros(4, 2, 1, dtype=torch.bool)
    one_step = loss.value_estimator.value_estimate(td.clone(), next_value=next_value)
    torch.testing.assert_close(one_step, reward + GAMMA * next_value)
    steps = torch.tensor([1, 2, 3, 3]).reshape(4, 1, 1).expand(4, 2, 1)
    td[training.N_STEPS_KEY] = steps
    n_step = loss.value_estimator.value_estimate(td, next_value=next_value)
    torch.testing.assert_close(n_step, reward + GAMMA ** steps.float() * next_value)


@pytest.mark.parametrize("n_steps", [0, -2, 2.5, True])
def test_a_wrong_n_steps_is_refused_naming_the_key(n_steps):
    with pytest.raises(ValueError, match=r"optim.n_steps: n_steps must be an integer >= 2"):
        training.n_step_from_config({"optim": {"n_steps": n_steps, "gamma": 0.99}})


def test_one_step_needs_no_transform():
    assert training.n_step_from_config({"optim": {"n_steps": 1, "gamma": 0.99}}) is None
    assert training.n_step_from_config({"optim": {"gamma": 0.99}}) is None
    assert training.n_step_from_config({"seed": 0}) is None  # e.g. a demonstrations-only config
