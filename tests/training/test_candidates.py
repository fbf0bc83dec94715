"""The recipes' candidate backup: the next state's candidates beside each collected frame, the
selection config, and both learners stepping on what the replay buffer stores."""

from __future__ import annotations

import pytest
import torch
from omegaconf import OmegaConf

from torchrl_auv import training
from torchrl_auv.modules import DiffusionProposer
from torchrl_auv.modules.consensus import medoid_index
from torchrl_auv.objectives import QEnsembleCritic


@pytest.fixture(scope="module")
def collected():
    """A selection policy's rollout over an episode end (max_steps 4, 7 frames, 2 scenes)."""
    env = training.make_history_env("ideal", history=2, seed=0, num_envs=2, max_steps=4)
    torch.manual_seed(0)
    proposer = DiffusionProposer.for_env(env, num_candidates=3, horizon=2, num_inference_steps=2)
    critic = training.make_lyapunov_critic(env, (16,))
    rule = training.selection_rule_from_config({"selection": {"anchor": "medoid"}})
    policy = training.make_selection_policy(
        proposer, critic, mode="lyapunov", rule=rule, critic_out_key=training.LYAPUNOV_RAW
    )
    data = env.rollout(7, policy, break_when_any_done=False)
    return env, proposer, critic, rule, data


def test_the_next_candidates_are_the_next_frames_or_proposed_on_the_stored_next_state(collected):
    _, proposer, _, _, data = collected
    data = data.clone()
    done = data["next", "done"][..., 0]
    assert done[:, 3].all() and not done[:, :3].any()  # the episodes end at frame 3
    torch.manual_seed(5)
    training.with_next_candidates(data, proposer)
    first = data["agents", "proposer", "candidates"][..., 0, :]
    nxt, anchor = data[training.NEXT_CANDIDATES], data[training.NEXT_ANCHOR]
    inside = [0, 1, 2, 4, 5]  # frames followed by a frame of the same episode
    torch.testing.assert_close(nxt[:, inside], first[:, [t + 1 for t in inside]])
    assert torch.equal(anchor[:, inside], data["agents", "selector", "anchor"][:, [1, 2, 3, 5, 6]])
    # the episode's last frame and the batch's last frame: proposed on the stored next state,
    # one call in the order of the frames (the same draws as this call)
    own = torch.zeros(2, 7, dtype=torch.bool)
    own[:, [3, 6]] = True
    torch.manual_seed(5)
    proposed = proposer(data["next"][own].select(*proposer.in_keys).copy())
    expected = proposed["agents", "proposer", "candidates"]
    torch.testing.assert_close(nxt[own], expected[..., 0, :])
    assert torch.equal(anchor[own], medoid_index(expected))
    assert not torch.allclose(nxt[:, 3], first[:, 4])  # not the reset state's candidates


def test_both_learners_step_on_the_frames_the_buffer_stores(collected):
    env, proposer, critic, rule, data = collected
    data = training.with_next_candidates(data.clone(), proposer)
    frames = training.select_for_replay(data, training.CANDIDATE_KEYS)
    assert set(training.CANDIDATE_KEYS) <= set(frames.keys(True, True))
    cfg = OmegaConf.create(
        {
            "optim": {
                "gamma": 0.97,
                "lambda_max": 1.0,
                "loss_function": "l2",
                "actor_lr": 1e-3,
                "critic_lr": 1e-3,
                "dual_lr": 1e-3,
                "alpha_lr": 1e-3,
                "alpha_init": 1.0,
                "tau": 0.005,
            },
            "lyapunov": {
                "form": "softplus",
                "stability_weight": 0.1,
                "cost": "stability",
                "gamma": 0.999,
            },
            "network": {"hidden": [16]},
            "device": "cpu",
            "selection": {"backup": "candidates", "anchor": "medoid"},
        }
    )
    actor = training.make_actor(env, (16,))
    lac = training.lac_from_config(cfg, env, actor, critic, rule=rule)
    sac = training.sac_from_config(cfg, env, actor, rule=rule)
    assert lac.loss.backup == sac.loss.backup == "candidates"
    assert (lac.loss.gamma, lac.loss.lyapunov_gamma) == (0.97, 0.999)  # lyapunov.gamma
    for learner, key in ((lac, "loss_lyapunov"), (sac, "loss_qvalue")):
        out = learner.step(frames[:8])
        assert out[key].isfinite()
    # the loss reads the rule the selector acts with: the warm-up switch reaches both
    training.start_deviating(rule, 100, {"selection": {"warmup_frames": 1000}})
    assert not lac.loss.rule.deviate and not sac.loss.rule.deviate
    training.start_deviating(rule, 1000, {"selection": {"warmup_frames": 1000}})
    assert lac.loss.rule.deviate


@pytest.mark.parametrize(
    ("selection", "named"),
    [
        ({"backup": "policy"}, "selection.backup"),
        ({"anchor": "mean"}, "selection.anchor"),
        ({"margin": -0.1}, "selection.margin"),
        ({"warmup_frames": -1}, "selection.warmup_frames"),
        ({"warmup_frames": 100}, "selection.anchor=medoid"),
    ],
)
def test_a_bad_selection_value_is_named_before_any_work(selection, named):
    with pytest.raises(ValueError, match=named):
        training.check_choices({"selection": {"include_actor": False, **selection}})


def test_the_network_keys_size_the_q_ensemble_and_norm_the_critics(collected):
    env, proposer, _, rule, data = collected
    data = training.with_next_candidates(data.clone(), proposer)
    frames = training.select_for_replay(data, training.CANDIDATE_KEYS)
    cfg = OmegaConf.create(
        {
            "optim": {
                "gamma": 0.99,
                "loss_function": "l2",
                "actor_lr": 1e-3,
                "critic_lr": 1e-3,
                "alpha_lr": 1e-3,
                "alpha_init": 1.0,
                "tau": 0.005,
            },
            "network": {"hidden": [16, 8], "critics": 5, "layer_norm": True},
            "device": "cpu",
            "selection": {"backup": "candidates", "anchor": "medoid"},
        }
    )
    sac = training.sac_from_config(cfg, env, training.make_actor(env, (16,)), rule=rule)
    scores = QEnsembleCritic.from_loss(sac.loss).members(frames[:4])
    assert scores.shape[0] == 5 and not torch.allclose(scores[0], scores[1])
    norms = [m for m in sac.loss.qvalue_network.modules() if isinstance(m, torch.nn.LayerNorm)]
    assert [m.normalized_shape for m in norms] == [(16,), (8,)]
    assert sac.step(frames[:8])["loss_qvalue"].isfinite()
    cfg.network.layer_norm = False
    cfg.network.pop("critics")  # absent: SAC's twin
    plain = training.sac_from_config(cfg, env, training.make_actor(env, (16,)), rule=rule)
    assert QEnsembleCritic.from_loss(plain.loss).members(frames[:4]).shape[0] == 2
    assert not any(isinstance(m, torch.nn.LayerNorm) for m in plain.loss.qvalue_network.modules())
