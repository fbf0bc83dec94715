"""QEnsembleCritic: a Q critic trained by TorchRL's SACLoss / TD3Loss filters candidates."""

from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import NormalParamExtractor, TensorDictModule
from torch import nn
from torchrl.data import Bounded
from torchrl.modules import MLP, ProbabilisticActor, TanhNormal, ValueOperator
from torchrl.objectives import SACLoss, TD3Loss

from torchrl_auv.objectives import CandidateSelector, LyapunovActorCriticLoss, QEnsembleCritic

OBS = 3
SPEC = Bounded(-1.0, 1.0, shape=(1,))


def _best_action(observation):
    return 0.8 * torch.tanh(2 * observation[..., :1])


def _bandit_batch(n, generator):
    """One-step episodes: reward -(a - a*(s))^2, terminated, so Q(s, a) = r."""
    obs = torch.randn(n, OBS, generator=generator)
    action = torch.rand(n, 1, generator=generator) * 2 - 1
    reward = -(action - _best_action(obs)).square()
    next_ = {
        "observation": torch.randn(n, OBS, generator=generator),
        "reward": reward,
        "done": torch.ones(n, 1, dtype=torch.bool),
        "terminated": torch.ones(n, 1, dtype=torch.bool),
    }
    return TensorDict({"observation": obs, "action": action, "next": next_}, [n])


def _q():
    return ValueOperator(
        MLP(in_features=OBS + 1, out_features=1, num_cells=[64, 64]),
        in_keys=["observation", "action"],
    )


def _stochastic_actor():
    net = nn.Sequential(
        MLP(in_features=OBS, out_features=2, num_cells=[16]), NormalParamExtractor()
    )
    return ProbabilisticActor(
        TensorDictModule(net, in_keys=["observation"], out_keys=["loc", "scale"]),
        in_keys=["loc", "scale"],
        distribution_class=TanhNormal,
        distribution_kwargs={"low": -1.0, "high": 1.0},
        return_log_prob=True,
    )


def _deterministic_actor():
    return TensorDictModule(
        nn.Sequential(MLP(in_features=OBS, out_features=1, num_cells=[16]), nn.Tanh()),
        in_keys=["observation"],
        out_keys=["action"],
    )


def _train(loss, steps=400):
    optim = torch.optim.Adam(loss.parameters(), lr=3e-3)
    g = torch.Generator().manual_seed(0)
    for _ in range(steps):
        out = loss(_bandit_batch(128, g))
        total = sum(v for k, v in out.items() if k.startswith("loss"))
        optim.zero_grad()
        total.backward()
        optim.step()
    return optim


def _selection_accuracy(critic):
    """Fraction of states where the chosen candidate's true reward is within 0.05 of the best
    candidate's (near the midpoint between two candidates both are nearly as good)."""
    g = torch.Generator().manual_seed(1)
    obs = torch.randn(200, OBS, generator=g)
    grid = torch.linspace(-1, 1, 5)
    candidates = grid.view(1, 5, 1, 1).expand(200, 5, 4, 1)
    td = TensorDict({"observation": obs, ("proposer", "candidates"): candidates}, [200])
    CandidateSelector(critic, mode="q")(td)
    rewards = -(grid.view(1, 5) - _best_action(obs)).square()
    chosen = rewards.gather(-1, td["selector", "index"][:, None]).squeeze(-1)
    return (rewards.max(-1).values - chosen < 0.05).float().mean().item()


@pytest.mark.parametrize("algorithm", ["sac", "td3"])
def test_q_trained_by_torchrl_loss_filters_candidates(algorithm):
    torch.manual_seed(0)
    if algorithm == "sac":
        loss = SACLoss(_stochastic_actor(), _q(), num_qvalue_nets=2, action_spec=SPEC)
    else:
        loss = TD3Loss(_deterministic_actor(), _q(), action_spec=SPEC)
    critic = QEnsembleCritic.from_loss(loss)
    untrained = _selection_accuracy(critic)
    _train(loss)
    trained = _selection_accuracy(critic)  # same critic object: it follows the loss's params
    assert critic.num_nets == 2
    assert trained >= 0.9, (untrained, trained)
    assert trained > untrained + 0.3


def test_min_and_mean_reduce_the_ensemble():
    torch.manual_seed(0)
    loss = TD3Loss(_deterministic_actor(), _q(), action_spec=SPEC)
    td = _bandit_batch(16, torch.Generator().manual_seed(2)).exclude("next")
    values = []
    for i in range(2):
        with loss.qvalue_network_params[i].to_module(loss.qvalue_network):
            values.append(loss.qvalue_network(td.copy())["state_action_value"])
    low = QEnsembleCritic.from_loss(loss)(td.copy())["state_action_value"]
    mean = QEnsembleCritic.from_loss(loss, reduce="mean")(td.copy())["state_action_value"]
    torch.testing.assert_close(low, torch.minimum(*values))
    torch.testing.assert_close(mean, (values[0] + values[1]) / 2)


def test_bad_input_names_the_argument():
    lac = LyapunovActorCriticLoss(_stochastic_actor(), _q())
    with pytest.raises(ValueError, match="loss must own qvalue_network"):
        QEnsembleCritic.from_loss(lac)
    loss = TD3Loss(_deterministic_actor(), _q(), action_spec=SPEC)
    with pytest.raises(ValueError, match="reduce must be one of"):
        QEnsembleCritic.from_loss(loss, reduce="max")
    with pytest.raises(ValueError, match="params must be stacked"):
        QEnsembleCritic(loss.qvalue_network, loss.qvalue_network_params[0])
