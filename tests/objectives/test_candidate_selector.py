"""CandidateSelector: argmax Q, argmin L, the actor's candidate, exploration, ranking."""

from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torch import nn

from torchrl_auv.objectives import CandidateSelector, LyapunovSpec


class _ActionScore(nn.Module):
    """A critic whose output is the first action entry: Q(s, a) = a_0 (raw L = a_0 too)."""

    def forward(self, observation, action):
        return action[..., :1] + 0 * observation[..., :1]


def _critic():
    return TensorDictModule(
        _ActionScore(), in_keys=["observation", "action"], out_keys=["state_action_value"]
    )


def _data():
    candidates = torch.zeros(2, 5, 8, 2)
    candidates[..., 0, 0] = torch.tensor([[0.1, 0.9, -0.5, 0.3, 0.0], [-0.2, -0.9, 0.4, 0.8, 0.5]])
    return TensorDict(
        {"observation": torch.zeros(2, 3), ("proposer", "candidates"): candidates}, batch_size=[2]
    )


def test_q_mode_picks_the_argmax_and_ranks_best_first():
    td = CandidateSelector(_critic(), mode="q")(_data())
    assert td["selector", "index"].tolist() == [1, 3]
    assert td["selector", "ranking"][0].tolist() == [1, 3, 0, 4, 2]
    torch.testing.assert_close(td["action"], td["proposer", "candidates"][[0, 1], [1, 3], 0])


def test_lyapunov_mode_picks_the_argmin_of_l():
    # squared form: L = a_0^2, so the candidate nearest zero wins
    selector = CandidateSelector(_critic(), mode="lyapunov", spec=LyapunovSpec(form="squared"))
    td = selector(_data())
    assert td["selector", "index"].tolist() == [4, 0]


def test_the_lyapunov_form_travels_with_the_weights_a_collector_copies():
    # TorchRL's collectors copy TensorDict.from_module(policy) into their workers' copies
    from tensordict import TensorDict as TD

    learner = CandidateSelector(_critic(), mode="lyapunov")  # softplus: argmin a_0
    worker = CandidateSelector(_critic(), mode="lyapunov")
    assert worker(_data())["selector", "index"].tolist() == [2, 1]
    learner.spec = LyapunovSpec(form="squared", alpha=0.3, prior="position", prior_weight=2.0)
    TD.from_module(learner).to_module(worker)
    assert worker.spec == learner.spec
    assert worker(_data())["selector", "index"].tolist() == [4, 0]  # argmin a_0^2


def test_the_actors_action_joins_as_one_more_candidate():
    data = _data()
    data["actor", "action"] = torch.tensor([[2.0, 0.0], [-3.0, 0.0]])
    td = CandidateSelector(_critic(), include_actor_action=True)(data)
    assert td["selector", "scores"].shape == (2, 6)
    assert td["selector", "index"].tolist() == [5, 3]


def test_exploration_draws_from_the_generator():
    def choose(seed, exploration, **kw):
        g = torch.Generator().manual_seed(seed)
        selector = CandidateSelector(_critic(), exploration=exploration, generator=g, **kw)
        return torch.stack([selector(_data())["selector", "index"] for _ in range(200)])

    greedy = choose(0, None)
    assert (greedy == greedy[0]).all()
    soft = choose(0, "softmax", temperature=0.2)
    assert torch.equal(soft, choose(0, "softmax", temperature=0.2))
    assert len(set(soft[:, 0].tolist())) > 1 and (soft[:, 0] == 1).float().mean() > 0.3
    eps = choose(1, "epsilon", epsilon=0.5)
    assert 0.3 < (eps != greedy).float().mean() < 0.5  # half explore, 4/5 of those differ: 0.4


@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"mode": "random"}, "mode"),
        ({"exploration": "ucb"}, "exploration"),
        ({"temperature": 0.0}, "temperature"),
        ({"epsilon": 1.5}, "epsilon"),
    ],
)
def test_bad_input_names_the_argument(kwargs, argument):
    with pytest.raises(ValueError, match=argument):
        CandidateSelector(_critic(), **kwargs)
    with pytest.raises(ValueError, match="candidates_key"):
        CandidateSelector(_critic())(TensorDict({"observation": torch.zeros(2, 3)}, [2]))
