"""DenoisingLoss: TorchRL key conventions, masking, shared parameters, bad input."""

from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict

from torchrl_auv.modules import DiffusionProposer
from torchrl_auv.objectives import DenoisingLoss


def _data(n=16, horizon=8):
    g = torch.Generator().manual_seed(0)
    return TensorDict(
        {
            "observation": torch.randn(n, 4, generator=g),
            "action_chunk": torch.rand(n, horizon, 2, generator=g) * 2 - 1,
            "action_chunk_mask": torch.ones(n, horizon, dtype=torch.bool),
        },
        batch_size=[n],
    )


def _loss_value(loss, td, seed=0):
    loss.generator = torch.Generator().manual_seed(seed)
    return loss(td)["loss_denoising"]


def test_set_keys_renames_the_inputs_and_the_input_is_not_modified():
    loss = DenoisingLoss(DiffusionProposer(4, 2))
    td = _data()
    reference = _loss_value(loss, td)
    renamed = td.rename_key_("action_chunk", "chunk").rename_key_("observation", "flat_state")
    loss.set_keys(action="chunk", state="flat_state")
    before = renamed.clone()
    torch.testing.assert_close(_loss_value(loss, renamed), reference)
    assert (renamed == before).all() and set(renamed.keys()) == set(before.keys())


def test_the_mask_selects_the_chunk_steps_that_count():
    loss = DenoisingLoss(DiffusionProposer(4, 2))
    td = _data()
    per_step = []
    for i in range(8):  # same seed: same timesteps and noise, one step counted at a time
        one = td.clone()
        one["action_chunk_mask"][:] = False
        one["action_chunk_mask"][:, i] = True
        per_step.append(_loss_value(loss, one))
    per_step = torch.stack(per_step)
    torch.testing.assert_close(_loss_value(loss, td), per_step.mean())
    half = td.clone()
    half["action_chunk_mask"][:, 4:] = False
    torch.testing.assert_close(_loss_value(loss, half), per_step[:4].mean())


def test_the_loss_trains_the_users_proposer():
    proposer = DiffusionProposer(4, 2)
    loss = DenoisingLoss(proposer)
    assert {id(p) for p in loss.parameters()} == {id(p) for p in proposer.parameters()}
    _loss_value(loss, _data()).backward()
    assert all(p.grad is not None for p in proposer.noise_model.parameters())
    assert list(loss(_data()).keys()) == ["loss_denoising"]


def test_bad_input():
    with pytest.raises(ValueError, match="proposer"):
        DenoisingLoss(torch.nn.Linear(2, 2))
    loss = DenoisingLoss(DiffusionProposer(4, 2))
    with pytest.raises(ValueError, match="action"):
        loss(_data(horizon=4))


def test_optional_ema_of_the_weights():
    proposer = DiffusionProposer(4, 2)
    loss = DenoisingLoss(proposer, ema_decay=0.9)
    optim = torch.optim.Adam(loss.parameters(), lr=1e-2)
    for _ in range(3):
        optim.zero_grad()
        _loss_value(loss, _data()).backward()
        optim.step()
        loss.update_ema()
    ema = dict(proposer.ema.module.named_parameters())
    moved = [not torch.equal(p, ema[n]) for n, p in proposer.noise_model.named_parameters()]
    assert any(moved)  # the average lags the trained weights
    assert {id(p) for p in loss.parameters()} == {id(p) for p in proposer.parameters()}
