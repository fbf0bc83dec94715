"""Trained on the tracking expert's demonstrations, the proposer alone nearly matches it.

The fast test is the reduced-budget learning check of the default suite (about 25 s): it must
close most of the gap between random actions and the expert on held-out scenes; the slow test
is the full-budget version.
"""

from __future__ import annotations

import pytest
import torch
from torchrl.envs import TransformedEnv

from torchrl_auv.envs import AUVTrackingEnv, ScriptedExpert, StateActionHistory
from torchrl_auv.envs.demonstrations import collect_demonstrations
from torchrl_auv.modules import DiffusionProposer
from torchrl_auv.objectives import pretrain_proposer


def _mean_cost(env, policy, steps: int, seed: int) -> float:
    env.set_seed(seed)
    return env.rollout(steps, policy, break_when_any_done=False)["next", "cost"].mean().item()


@pytest.mark.slow  # minutes: kept out of the default suite's 20-minute budget
def test_a_briefly_trained_proposer_closes_most_of_the_gap_from_random_to_the_expert():
    """1,600 demonstration samples, 1,500 Adam steps; 100 held-out decisions in 8 scenes.
    Measured: cost per decision random 1.31, proposer 0.44, expert 0.36 (92 % of the gap
    closed); asserted: at least 70 %."""
    data = collect_demonstrations("tracking", episodes=16, max_steps=100, seed=0)
    env = TransformedEnv(
        AUVTrackingEnv(batch_size=[8], seed=1000, max_steps=100), StateActionHistory(10)
    )
    proposer = DiffusionProposer.for_env(env, action_key="action")
    torch.manual_seed(0)
    result = pretrain_proposer(
        proposer, data, steps=1500, batch_size=256, lr=1e-3, log_every=500, eval_every=500
    )
    assert result.heldout_loss < 0.1 * result.heldout_losses[0]
    alone = _mean_cost(env, proposer, 100, seed=1000)
    expert = _mean_cost(env, ScriptedExpert(env.base_env), 100, seed=1000)
    random = _mean_cost(env, None, 100, seed=1000)  # uniform actions from the action spec
    assert expert < random
    closed = (random - alone) / (random - expert)
    assert closed >= 0.7, (random, alone, expert)


@pytest.mark.slow
def test_proposer_acting_alone_is_within_25_percent_of_the_expert_on_held_out_seeds():
    data = collect_demonstrations("tracking", episodes=16, max_steps=300, seed=0)
    env = TransformedEnv(AUVTrackingEnv(batch_size=[8], seed=1000), StateActionHistory(10))
    # acting alone: the first action of candidate 0, re-planned every decision
    proposer = DiffusionProposer.for_env(env, action_key="action")
    torch.manual_seed(0)
    result = pretrain_proposer(
        proposer, data, steps=3000, batch_size=256, lr=1e-3, log_every=500, eval_every=1000
    )
    assert result.heldout_loss < 0.5 * result.heldout_losses[0]
    env.set_seed(1000)  # held-out scenes: the demonstrations used seed 0
    alone = env.rollout(300, proposer, break_when_any_done=False)
    env.set_seed(1000)
    expert = env.rollout(300, ScriptedExpert(env.base_env), break_when_any_done=False)
    ratio = alone["next", "cost"].mean() / expert["next", "cost"].mean()
    assert ratio <= 1.25, ratio.item()
