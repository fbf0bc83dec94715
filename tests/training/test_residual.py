"""The residual actor on the prior's choice: its support, its zero residual, the next state's
prior action the replay stores, the pull toward the prior, and the config checks."""

from __future__ import annotations

import pytest
import torch
from omegaconf import OmegaConf
from torchrl.envs.utils import ExplorationType, set_exploration_type

from torchrl_auv import training
from torchrl_auv.modules import DiffusionProposer
from torchrl_auv.objectives import LyapunovSpec, ResidualLACLoss, lyapunov_value

BOUND = 0.25


@pytest.fixture(scope="module")
def collected():
    """A residual policy's rollout over an episode end (max_steps 4, 7 frames, 2 scenes)."""
    env = training.make_history_env("ideal", history=2, seed=0, num_envs=2, max_steps=4)
    torch.manual_seed(0)
    proposer = DiffusionProposer.for_env(env, num_candidates=3, horizon=2, num_inference_steps=2)
    actor = training.make_residual_actor(env, (16,), bound=BOUND)
    policy = training.residual_policy(proposer, actor, num_candidates=4)
    with set_exploration_type(ExplorationType.RANDOM), torch.no_grad():  # as a collector acts
        data = env.rollout(7, policy, break_when_any_done=False)
    return env, policy, data


def test_the_executed_action_stays_within_the_bound_of_the_prior(collected):
    _, _, data = collected
    prior, action = data[training.PRIOR_ACTION], data["agents", "action"]
    offset = action - prior
    assert offset.abs().max() <= BOUND + 1e-6
    assert offset.abs().max() > 0.05 * BOUND  # a random residual, not the prior itself
    # the prior is the proposer alone's medoid of 4 draws: candidates of that size are stored
    assert data["agents", "proposer", "candidates"].shape[-3] == 4


def test_the_untrained_actor_executes_the_prior_exactly(collected):
    env, _, data = collected
    actor = training.make_residual_actor(env, (16,), bound=BOUND)
    td = data[:, 0].select(training.OBSERVATION, training.PRIOR_ACTION).clone()
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        out = actor(td)
    torch.testing.assert_close(out["agents", "action"], td[training.PRIOR_ACTION])


def test_the_next_prior_action_is_the_next_frames_or_recomputed_on_the_stored_next_state(
    collected,
):
    _, policy, data = collected
    data = data.clone()
    assert data["next", "done"][:, 3].all() and not data["next", "done"][:, :3].any()
    torch.manual_seed(3)
    training.with_next_prior(data, policy[0])
    prior, moved = data[training.PRIOR_ACTION], data[training.NEXT_PRIOR_ACTION]
    inside = [0, 1, 2, 4, 5]  # frames followed by a frame of the same episode
    torch.testing.assert_close(moved[:, inside], prior[:, [t + 1 for t in inside]])
    own = torch.zeros(2, 7, dtype=torch.bool)
    own[:, [3, 6]] = True  # the episode's last frame and the batch's last frame
    torch.manual_seed(3)
    expected = policy[0](data["next"][own].select(*policy[0].in_keys).copy())
    torch.testing.assert_close(moved[own], expected[training.PRIOR_ACTION])
    assert not torch.allclose(moved[:, 3], prior[:, 4])  # not the reset state's action
    with pytest.raises(ValueError, match="prior's action"):
        training.with_next_prior(data.exclude(training.PRIOR_ACTION), policy[0])


def _sac_config(**residual) -> OmegaConf:
    return OmegaConf.create(
        {
            "optim": {
                "gamma": 0.99,
                "loss_function": "l2",
                "actor_lr": 1e-2,
                "critic_lr": 1e-3,
                "alpha_lr": 1e-3,
                "alpha_init": 1.0,
                "tau": 0.005,
            },
            "network": {"hidden": [16], "critics": 2},
            "device": "cpu",
            "selection": {"backup": "candidates", "anchor": "medoid"},
            "residual": residual,
        }
    )


def test_sac_trains_the_actor_that_acts_and_pulls_it_toward_the_prior(collected):
    env, policy, data = collected
    data = training.with_next_prior(data.clone(), policy[0])
    keys = training.next_state_keys(_sac_config(bound=BOUND, coef=3.0))
    assert keys == training.RESIDUAL_KEYS
    frames = training.select_for_replay(data, keys)
    actor = training.make_residual_actor(env, (16,), bound=BOUND)
    last = [m for m in actor.modules() if isinstance(m, torch.nn.Linear)][-1]
    torch.nn.init.normal_(last.weight, std=0.5)  # a trained actor: residuals away from 0
    learner = training.sac_from_config(_sac_config(bound=BOUND, coef=3.0), env, actor)
    assert learner.loss.backup == "actor"  # the actor acts: SAC's own backup, not candidates
    out = learner.loss(frames.clone())
    # closed form: coef x the mean squared offset of the deterministic action, in bounds
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        mode = actor(frames.clone())["agents", "action"]
    offset = (mode - frames[training.PRIOR_ACTION]) / BOUND
    torch.testing.assert_close(out["loss_residual"], 3.0 * offset.pow(2).mean())
    # with the critics' and temperature's losses off the actor, the pull alone moves it to 0
    learner.loss.coef = 1e3
    first = out["residual"].item()
    assert first > 0.1
    for _ in range(30):
        learner.step(frames.clone())  # a fresh batch each step, as the buffer samples
    assert learner.loss(frames.clone())["residual"].item() < 0.5 * first
    assert "train/residual" in learner.metrics(learner.step(frames.clone()))


def test_without_a_residual_the_recipes_store_what_the_selection_needs():
    assert training.next_state_keys(_sac_config(bound=0.0)) == training.CANDIDATE_KEYS
    assert training.next_state_keys({"selection": {"backup": "actor"}}) == ()


@pytest.mark.parametrize(
    ("values", "named"),
    [
        ({"residual": {"bound": -0.1}}, "residual.bound"),
        ({"residual": {"bound": True}}, "residual.bound"),
        ({"residual": {"bound": 0.2, "coef": -1}}, "residual.coef"),
        (
            {"residual": {"bound": 0.2}, "proposer": {"alone_replan_every": 4, "horizon": 8}},
            "proposer.alone_replan_every=1",
        ),
    ],
)
def test_a_bad_residual_value_is_named_before_any_work(values, named):
    with pytest.raises(ValueError, match=named):
        training.check_choices(values)


def test_a_bound_outside_the_action_range_is_refused(collected):
    env, _, _ = collected
    with pytest.raises(ValueError, match="bound must be a number in"):
        training.make_residual_actor(env, (16,), bound=0.0)


def test_a_residual_policy_is_evaluated_beside_its_prior_without_ranks(collected):
    _, policy, _ = collected
    cfg = {
        "proposer": {"alone_pick": "medoid", "alone_candidates": 4, "alone_replan_every": 1},
        "eval": {"ranks": True},
        "residual": {"bound": BOUND},
    }
    proposer = policy[0].proposer
    rows = training.evaluation_policies_from_config(cfg, "diffusion_rl", policy, None, proposer)
    assert list(rows) == ["diffusion_rl", "proposer alone", "expert", "idle", "random"]


def test_lac_trains_the_residual_actor_with_its_constraint_on_the_executed_action(collected):
    env, policy, data = collected
    data = training.with_next_prior(data.clone(), policy[0])
    frames = training.select_for_replay(data, training.RESIDUAL_KEYS)
    cfg = _sac_config(bound=BOUND, coef=2.0)
    cfg.optim.update({"lambda_max": 1.0, "dual_lr": 1e-3})
    cfg.update(
        {
            "lyapunov": {"form": "softplus", "stability_weight": 0.1, "cost": "stability"},
        }
    )
    actor = training.make_residual_actor(env, (16,), bound=BOUND)
    critic = training.make_lyapunov_critic(env, (16,))
    learner = training.lac_from_config(cfg, env, actor, critic)
    assert isinstance(learner.loss, ResidualLACLoss)
    assert learner.loss.backup == "actor"  # L bootstraps on the action the actor executes
    out = learner.step(frames.clone())
    assert out["loss_lyapunov"].isfinite() and out["loss_residual"] == 0  # it starts at 0
    assert {"train/residual", "train/violation_rate"} <= set(learner.metrics(out))


def test_the_lac_policy_scores_the_executed_action_with_the_losss_lyapunov_spec(collected):
    env, policy, data = collected
    proposer, actor = policy[0].proposer, policy[1]
    critic = training.make_lyapunov_critic(env, (16,))
    loss = training.make_lac_loss(actor, critic, env, cost="stability", hidden=(16,))
    scored = training.residual_policy(proposer, actor, num_candidates=4, lyapunov=(critic, loss))
    loss.set_lyapunov_spec(LyapunovSpec(form="squared", alpha=0.2))  # an advisor's new spec
    td = data[:, 0].select(*proposer.in_keys).clone()
    with set_exploration_type(ExplorationType.DETERMINISTIC), torch.no_grad():
        out = scored(td)
        raw = critic(out.select(training.OBSERVATION, training.ACTION).clone())
    expected = -lyapunov_value(raw[training.LYAPUNOV_RAW], LyapunovSpec(form="squared"))
    torch.testing.assert_close(out["agents", "selector", "scores"], expected)
    assert (out["agents", "selector", "index"] == 0).all()
    offset = out["agents", "action"] - out[training.PRIOR_ACTION]
    assert offset.abs().max() < 1e-6  # the untrained residual: the prior's action, unchanged
