"""AUVTrackingEnv: specs across batch sizes, sea states and controllers; determinism; bounds."""

from __future__ import annotations

import pytest
import torch
from torchrl.envs import TransformedEnv
from torchrl.envs.utils import check_env_specs

from torchrl_auv.envs import AUVTrackingEnv, ScriptedExpert, StateActionHistory


@pytest.mark.parametrize("batch_size", [[], [1], [8]])
@pytest.mark.parametrize("sea_state", ["ideal", "es", "ves"])
@pytest.mark.parametrize("controller", ["s_surface", "pid", "smc"])
def test_check_env_specs(batch_size, sea_state, controller):
    env = AUVTrackingEnv(batch_size=batch_size, sea_state=sea_state, controller=controller, seed=0)
    check_env_specs(env, seed=0)


def test_same_seed_same_rollout_different_seed_differs():
    def rollout(seed):
        env = AUVTrackingEnv(batch_size=[2], sea_state="ves", seed=seed)
        return env.rollout(5, ScriptedExpert(env))

    a, b, c = rollout(3), rollout(3), rollout(4)
    assert (a == b).all()
    assert not torch.equal(a["next", "truth", "eta"], c["next", "truth", "eta"])


def test_observation_is_the_estimate_not_the_truth():
    env = AUVTrackingEnv(batch_size=[4], sea_state="es", seed=0)
    td = env.rollout(5)
    estimate, truth = td["next", "kf", "mean"][..., :3], td["next", "truth", "eta"][..., :3]
    assert not torch.equal(estimate, truth)
    assert (estimate - truth).abs().max() < 2.0  # but a good one


def test_expert_tracks_better_than_random_actions():
    env = AUVTrackingEnv(batch_size=[4], sea_state="es", seed=1)
    expert = env.rollout(60, ScriptedExpert(env))
    env.set_seed(1)
    random = env.rollout(60)
    assert expert["next", "cost"].mean() < 0.6 * random["next", "cost"].mean()
    assert (expert["next", "cost"] >= 0).all()
    torch.testing.assert_close(expert["next", "reward"], -expert["next", "cost"])


def test_truncation_and_metrics_at_the_time_limit():
    env = AUVTrackingEnv(batch_size=[2], seed=0, max_steps=4)
    td = env.rollout(10, break_when_any_done=False)
    truncated = td["next", "truncated"].squeeze(-1)
    assert truncated[:, 3].all() and not truncated[:, :3].any()
    assert not td["next", "terminated"].any()
    metrics = td["next", "metrics"][:, 3]
    for name in ("heading_error_mean", "heading_error_std", "depth_error_mean", "depth_error_std"):
        assert torch.isfinite(metrics[name]).all() and (metrics[name] >= 0).all()


@pytest.mark.parametrize("seed", [0, 1])
def test_random_actions_in_ves_stay_finite_and_in_bounds(seed):
    env = AUVTrackingEnv(batch_size=[4], sea_state="ves", seed=seed)
    td = env.rollout(150, break_when_any_done=False)
    for key in td.keys(True, True):
        value = td.get(key)
        if value.is_floating_point():
            assert torch.isfinite(value).all(), key
    assert env.action_spec.is_in(td["action"][:, 0])
    eta, nu = td["next", "truth", "eta"], td["next", "truth", "nu"]
    assert (eta[..., 2] >= 0).all() and (eta[..., 4].abs() < 1.4).all()
    assert (nu[..., :3].norm(dim=-1) < 5.0).all()


def test_history_transform_on_the_env():
    env = TransformedEnv(AUVTrackingEnv(batch_size=[2], seed=0), StateActionHistory(10))
    check_env_specs(env, seed=0)
    td = env.rollout(3)
    assert td["history", "observation"].shape == (2, 3, 10, 16)
    assert td["history", "action"].shape == (2, 3, 10, 3)


def test_bad_input():
    with pytest.raises(ValueError, match="sea_state"):
        AUVTrackingEnv(sea_state="storm")
    with pytest.raises(ValueError, match="controller"):
        AUVTrackingEnv(controller="lqr")
    with pytest.raises(ValueError, match="max_steps"):
        AUVTrackingEnv(max_steps=0)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(3))
def test_thousand_decision_episodes_in_ves_stay_finite_and_bounded(seed):
    env = AUVTrackingEnv(batch_size=[4], sea_state="ves", seed=seed, max_steps=1000)
    td = env.rollout(1000, break_when_any_done=False)
    for key in td.keys(True, True):
        value = td.get(key)
        if value.is_floating_point():
            assert torch.isfinite(value).all(), key
    eta, nu = td["next", "truth", "eta"], td["next", "truth", "nu"]
    assert (eta[..., 2] >= 0).all() and (eta[..., 4].abs() < 1.4).all()
    assert (nu[..., :3].norm(dim=-1) < 5.0).all()
    assert td["next", "truncated"][:, -1].all()


def test_constructor_seed_equals_set_seed():
    a = AUVTrackingEnv(batch_size=[2], seed=5).reset()
    env = AUVTrackingEnv(batch_size=[2], seed=0)
    env.set_seed(5)
    assert (a == env.reset()).all()
