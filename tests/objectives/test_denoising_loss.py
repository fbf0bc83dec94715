"""DenoisingLoss: TorchRL key conventions, masking, shared parameters, bad input."""

from __future__ import annotations

import math

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


class _Recorder(torch.nn.Module):
    """Wraps a noise model and keeps what it was called with."""

    def __init__(self, model):
        super().__init__()
        self.model, self.calls = model, []

    def forward(self, x_t, t, state):
        self.calls.append((x_t.detach().clone(), t.clone(), state.detach().clone()))
        return self.model(x_t, t, state)


def test_the_loss_is_the_masked_noise_prediction_error_by_hand():
    """eq. 9: x_t = sqrt(abar_t) x0 + sqrt(1 - abar_t) eps, loss = masked mean over chunk steps
    of mean_A (eps_theta(x_t, t, s) - eps)^2, with x0 the chunk normalised to [-1, 1]. The
    noise eps is recovered from the model's input, abar from the linear schedule's formula."""
    T, n, horizon = 10, 512, 8
    low, high = torch.tensor([-2.0, 0.0]), torch.tensor([2.0, 1.0])
    proposer = DiffusionProposer(
        4,
        2,
        horizon=horizon,
        num_train_steps=T,
        num_inference_steps=2,
        action_low=low,
        action_high=high,
    )
    model = proposer.noise_model
    proposer.noise_model = recorder = _Recorder(model)
    g = torch.Generator().manual_seed(0)
    action = low + (high - low) * (torch.rand(n, horizon, 2, generator=g) * 1.2 - 0.1)
    mask = torch.rand(n, horizon, generator=g) < 0.7
    td = TensorDict(
        {
            "observation": torch.randn(n, 4, generator=g),
            "action_chunk": action,
            "action_chunk_mask": mask,
        },
        batch_size=[n],
    )
    loss = DenoisingLoss(proposer, generator=torch.Generator().manual_seed(1))(td)
    ((x_t, t, state),) = recorder.calls
    betas = [1e-4 + (0.02 - 1e-4) * k / (T - 1) for k in range(T)]
    abar = torch.tensor([math.prod(1 - b for b in betas[: k + 1]) for k in range(T)])[t]
    abar = abar.reshape(n, 1, 1).float()
    x0 = (2 * (action - low) / (high - low) - 1).clamp(-1, 1)
    eps = (x_t - abar.sqrt() * x0) / (1 - abar).sqrt()
    with torch.no_grad():
        error = ((model(x_t, t, state) - eps) ** 2).mean(-1)
    expected = (error * mask).sum() / mask.sum()
    torch.testing.assert_close(loss["loss_denoising"].detach(), expected, rtol=1e-4, atol=1e-6)
    torch.testing.assert_close(state, td["observation"])
    # the noise is standard normal and the steps cover {0, ..., T-1}
    assert abs(eps.mean().item()) < 0.05 and abs(eps.std().item() - 1) < 0.05
    assert sorted(set(t.tolist())) == list(range(T))


def test_loss_update_ema_moves_the_average_by_the_decay():
    decay = 0.8
    proposer = DiffusionProposer(4, 2)
    loss = DenoisingLoss(proposer, ema_decay=decay)
    assert proposer.ema_decay == decay
    loss.update_ema()  # the first update copies the weights
    before = {n: p.detach().clone() for n, p in proposer.ema.module.named_parameters()}
    optim = torch.optim.SGD(loss.parameters(), lr=0.1)
    _loss_value(loss, _data()).backward()
    optim.step()
    loss.update_ema()
    trained = dict(proposer.noise_model.named_parameters())
    for n, p in proposer.ema.module.named_parameters():
        torch.testing.assert_close(p, decay * before[n] + (1 - decay) * trained[n].detach())


def test_the_unet_noise_model_learns():
    """80 Adam steps on a fixed set of chunks lower the U-Net's denoising loss (same timesteps
    and noise before and after) clearly below 1 = E[eps^2], the loss of the best input-blind
    predictor (eps_theta = 0); measured ~0.56 over four initialisations."""
    widths = {"channels": (16, 32), "cond_dim": 32}
    proposer = DiffusionProposer(
        4, 2, noise_model="unet", horizon=8, num_train_steps=100, noise_model_kwargs=widths
    )
    loss = DenoisingLoss(proposer)
    td = _data(n=64)
    before = _loss_value(loss, td, seed=123).item()
    optim = torch.optim.Adam(loss.parameters(), lr=3e-3)
    for step in range(80):
        optim.zero_grad()
        _loss_value(loss, td, seed=step).backward()
        optim.step()
    after = _loss_value(loss, td, seed=123).item()
    assert after < 0.7 and after < 0.75 * before, (before, after)


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
