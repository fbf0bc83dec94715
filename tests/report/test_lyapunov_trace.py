"""The Lyapunov value along episodes (Fig. 10/11): the executed candidate's L, first episode."""

from __future__ import annotations

import math

import torch
from tensordict import TensorDict

from torchrl_auv.report import executed_lyapunov, lyapunov_trace


def _rollout():
    # 2 scenes, 3 decisions, 2 AUVs, K = 3 candidates; scores are -L
    L = torch.arange(36, dtype=torch.float32).reshape(2, 3, 2, 3)
    index = torch.tensor([[[0, 2], [1, 1], [2, 0]], [[2, 2], [0, 1], [1, 0]]])
    done = torch.tensor([[False, True, False], [False, False, False]])[..., None]
    return (
        TensorDict(
            {
                ("agents", "selector", "scores"): -L,
                ("agents", "selector", "index"): index,
                ("next", "done"): done,
            },
            batch_size=[2, 3],
        ),
        L,
        index,
    )


def test_the_executed_candidates_value_until_the_first_episode_ends():
    rollout, L, index = _rollout()
    value = executed_lyapunov(rollout)  # [scene * AUV, T]
    assert value.shape == (4, 3)
    for scene in range(2):
        for auv in range(2):
            for t in range(3):
                expected = L[scene, t, auv, index[scene, t, auv]].item()
                got = value[scene * 2 + auv, t].item()
                if scene == 0 and t == 2:  # after scene 0's done
                    assert math.isnan(got)
                else:
                    assert got == expected


def test_the_trace_averages_the_running_episodes():
    rollout, _, _ = _rollout()
    value = executed_lyapunov(rollout)
    trace = lyapunov_trace(rollout)
    assert trace["episodes"].tolist() == [4, 4, 2]
    assert torch.allclose(trace["mean"][:2], value[:, :2].mean(0))
    assert torch.allclose(trace["std"][:2], value[:, :2].std(0))
    assert torch.allclose(trace["mean"][2], value[2:, 2].mean())


def test_a_rollout_without_a_lyapunov_selector_is_named():
    rollout = TensorDict({("next", "done"): torch.zeros(1, 2, 1, dtype=torch.bool)}, [1, 2])
    try:
        executed_lyapunov(rollout)
    except KeyError as error:
        assert "CandidateSelector" in str(error)
    else:
        raise AssertionError("no error")


def test_the_written_trace_is_seeded_by_the_evaluation_seed_and_leaves_the_rng(tmp_path):
    """The trace's rollout (the proposer's noise) draws from torch's generator seeded with
    ``eval.seed``, forked: the same file whatever the generator's state before (a resumed
    run's trace is an uninterrupted run's), and the caller's generator untouched."""
    from omegaconf import OmegaConf

    from torchrl_auv import training
    from torchrl_auv.modules import DiffusionProposer
    from torchrl_auv.report import write_lyapunov_trace

    cfg = OmegaConf.create(
        {
            "env": {
                "sea_state": "ideal",
                "controller": "pid",
                "rate_model": "shannon",
                "history": 2,
            },
            "eval": {"num_envs": 1, "steps": 4, "seed": 100_000, "sea_states": ["ideal"]},
        }
    )
    env = training.held_out_env(cfg, 1, 4)("ideal", 0)
    torch.manual_seed(0)
    proposer = DiffusionProposer.for_env(env, num_candidates=3, horizon=2, num_inference_steps=2)
    critic = training.make_lyapunov_critic(env, (8,))
    policy = training.make_selection_policy(
        proposer, critic, mode="lyapunov", critic_out_key=training.LYAPUNOV_RAW
    )
    texts = []
    for state in (1, 2):
        torch.manual_seed(state)
        before = torch.random.get_rng_state()
        (tmp_path / str(state)).mkdir()
        texts.append(write_lyapunov_trace(cfg, tmp_path / str(state), policy).read_text())
        assert torch.equal(torch.random.get_rng_state(), before)
    assert texts[0] == texts[1] and len(texts[0].splitlines()) == 5
