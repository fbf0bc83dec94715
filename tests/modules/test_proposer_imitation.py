"""Trained on the tracking expert's demonstrations, the proposer alone nearly matches it."""

from __future__ import annotations

import pytest
import torch
from torchrl.envs import TransformedEnv

from torchrl_auv.envs import AUVTrackingEnv, ScriptedExpert, StateActionHistory
from torchrl_auv.envs.demonstrations import collect_demonstrations
from torchrl_auv.modules import DiffusionProposer
from torchrl_auv.objectives import pretrain_proposer


@pytest.mark.slow
def test_proposer_acting_alone_is_within_25_percent_of_the_expert_on_held_out_seeds():
    data = collect_demonstrations("tracking", episodes=16, max_steps=300, seed=0)
    env = TransformedEnv(AUVTrackingEnv(batch_size=[8], seed=1000), StateActionHistory(10))
    # acting alone: the first action of candidate 0, re-planned every decision
    proposer = DiffusionProposer.for_env(env, action_key="action")
    torch.manual_seed(0)
    result = pretrain_proposer(proposer, data, steps=3000, batch_size=256, lr=1e-3,
                               log_every=500, eval_every=1000)  # fmt: skip
    assert result.heldout_loss < 0.5 * result.heldout_losses[0]
    env.set_seed(1000)  # held-out scenes: the demonstrations used seed 0
    alone = env.rollout(300, proposer, break_when_any_done=False)
    env.set_seed(1000)
    expert = env.rollout(300, ScriptedExpert(env.base_env), break_when_any_done=False)
    ratio = alone["next", "cost"].mean() / expert["next", "cost"].mean()
    assert ratio <= 1.25, ratio.item()
