"""CandidateSelector: a critic that does not write ``critic_out_key`` gets a clear error.

TorchRL's ``ValueOperator`` names its output ``state_value`` (not ``state_action_value``) when
its action key is nested, e.g. ``("agents", "action")``.
"""

from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict
from torchrl.modules import MLP, ValueOperator

from torchrl_auv.objectives import CandidateSelector, LyapunovSpec

NESTED_ACTION = ("agents", "action")


def _nested_critic():
    torch.manual_seed(0)
    return ValueOperator(
        MLP(in_features=5, out_features=1, num_cells=[8]), in_keys=["observation", NESTED_ACTION]
    )


def _data():
    candidates = torch.rand(2, 5, 8, 2)
    return TensorDict(
        {"observation": torch.zeros(2, 3), ("proposer", "candidates"): candidates}, batch_size=[2]
    )


def test_value_operator_over_a_nested_action_writes_state_value():
    assert _nested_critic().out_keys == ["state_value"]


@pytest.mark.parametrize("mode", ["q", "lyapunov"])
def test_missing_critic_output_names_the_key_and_what_the_critic_wrote(mode):
    selector = CandidateSelector(
        _nested_critic(),
        mode=mode,
        spec=LyapunovSpec(form="squared"),
        critic_action_key=NESTED_ACTION,
    )
    with pytest.raises(KeyError) as info:
        selector(_data())
    message = str(info.value)
    assert "critic_out_key 'state_action_value'" in message
    assert "the keys it wrote are ['state_value']" in message


def test_the_right_critic_out_key_selects():
    selector = CandidateSelector(
        _nested_critic(), critic_action_key=NESTED_ACTION, critic_out_key="state_value"
    )
    td = selector(_data())
    assert td["action"].shape == (2, 2) and td["selector", "ranking"].shape == (2, 5)
