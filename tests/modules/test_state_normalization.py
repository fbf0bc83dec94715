"""The proposer's state standardisation: fitted on data, used by the loss and by sampling,
kept by checkpoints; configure_sampling changes K, steps and sampler, not the weights."""

from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict

from torchrl_auv.modules import DiffusionProposer
from torchrl_auv.objectives import DenoisingLoss, pretrain_proposer


def _states(n=400, seed=0):
    g = torch.Generator().manual_seed(seed)
    scale = torch.tensor([0.01, 1.0, 50.0, 3.0])
    return torch.randn(n, 4, generator=g) * scale + torch.tensor([0.0, 2.0, -100.0, 0.5])


def test_fit_standardises_each_feature_and_floors_the_scale():
    proposer = DiffusionProposer(5, 2)
    states = torch.cat([_states(), torch.full((400, 1), 7.0)], -1)  # last feature constant
    proposer.fit_state_normalization(states, min_scale=0.005)
    z = proposer.normalize_state(states)
    torch.testing.assert_close(z.mean(0)[:4], torch.zeros(4), atol=1e-4, rtol=0)
    torch.testing.assert_close(z.std(0)[:4], torch.ones(4), atol=1e-4, rtol=0)
    assert proposer.state_scale[-1].item() == pytest.approx(0.005)  # floored, not 0
    assert z[:, -1].abs().max().item() < 1e-4


def test_the_loss_and_sampling_see_the_standardised_state():
    """A proposer with loc/scale fed raw states equals one without fed standardised states
    (same weights, same noise): the loss and the candidates agree."""
    states = _states(64)
    loc, scale = states.mean(0), states.std(0)
    normalised = DiffusionProposer(4, 2, horizon=4, num_inference_steps=3)
    plain = DiffusionProposer(4, 2, horizon=4, num_inference_steps=3)
    plain.noise_model.load_state_dict(normalised.noise_model.state_dict())
    normalised.set_state_normalization(loc, scale)
    chunk = torch.rand(64, 4, 2) * 2 - 1
    raw = TensorDict({"observation": states, "action_chunk": chunk}, [64])
    std = TensorDict({"observation": (states - loc) / scale, "action_chunk": chunk}, [64])
    a = DenoisingLoss(normalised, generator=torch.Generator().manual_seed(1))(raw)
    b = DenoisingLoss(plain, generator=torch.Generator().manual_seed(1))(std)
    torch.testing.assert_close(a["loss_denoising"], b["loss_denoising"])
    ca, _ = normalised.sample(states[:5], generator=torch.Generator().manual_seed(2))
    cb, _ = plain.sample((states[:5] - loc) / scale, generator=torch.Generator().manual_seed(2))
    torch.testing.assert_close(ca, cb)
    cc, _ = plain.sample(states[:5], generator=torch.Generator().manual_seed(2))
    assert not torch.allclose(ca, cc)  # the standardisation changes what is proposed


def test_checkpoints_keep_the_standardisation(tmp_path):
    proposer = DiffusionProposer(4, 2)
    proposer.fit_state_normalization(_states())
    loaded = DiffusionProposer.load(proposer.save(tmp_path / "p.pt"))
    torch.testing.assert_close(loaded.state_loc, proposer.state_loc)
    torch.testing.assert_close(loaded.state_scale, proposer.state_scale)


def test_pretraining_fits_the_standardisation_on_its_training_split():
    states = _states(300)
    data = TensorDict({"observation": states, "action_chunk": torch.zeros(300, 8, 2)}, [300])
    proposer = DiffusionProposer(4, 2)
    pretrain_proposer(proposer, data, steps=2, heldout_fraction=0.2, log_every=1, eval_every=1)
    # within the spread of a 240-of-300 split of the data
    gap = (proposer.state_loc.float() - states.mean(0)).abs()
    assert bool((gap < 0.2 * states.std(0)).all())
    assert (proposer.state_scale / states.std(0)).sub(1).abs().max() < 0.15
    untouched = DiffusionProposer(4, 2)
    pretrain_proposer(untouched, data, steps=2, normalize_state=False, log_every=1)
    assert bool((untouched.state_loc == 0).all() and (untouched.state_scale == 1).all())


def test_the_cosine_schedule_anneals_the_learning_rate_to_zero():
    data = TensorDict(
        {"observation": torch.randn(64, 4), "action_chunk": torch.rand(64, 8, 2) * 2 - 1}, [64]
    )
    proposer = DiffusionProposer(4, 2)
    before = [p.detach().clone() for p in proposer.noise_model.parameters()]
    pretrain_proposer(proposer, data, steps=1, lr=1e-2, lr_schedule="cosine", log_every=1)
    # one step: the first step runs at the full rate (the schedule applies after it)
    moved = sum(
        (p - q).abs().sum().item()
        for p, q in zip(proposer.noise_model.parameters(), before, strict=True)
    )
    assert moved > 0
    with pytest.raises(ValueError, match="lr_schedule"):
        pretrain_proposer(proposer, data, steps=1, lr_schedule="step")
    with pytest.raises(ValueError, match="weight_decay"):
        pretrain_proposer(proposer, data, steps=1, weight_decay=-1.0)


def test_set_state_normalization_checks_its_input():
    proposer = DiffusionProposer(4, 2)
    with pytest.raises(ValueError, match=r"loc must be shaped \[4\]"):
        proposer.set_state_normalization(torch.zeros(3), torch.ones(4))
    with pytest.raises(ValueError, match="scale must be finite and > 0"):
        proposer.set_state_normalization(torch.zeros(4), torch.zeros(4))
    with pytest.raises(ValueError, match="states must be shaped"):
        proposer.fit_state_normalization(torch.zeros(1, 4))


def test_configure_sampling_changes_how_it_samples_not_its_weights():
    proposer = DiffusionProposer(4, 2, horizon=4, num_inference_steps=5)
    weights = {k: v.clone() for k, v in proposer.noise_model.state_dict().items()}
    proposer.configure_sampling(num_candidates=7, num_inference_steps=3, sampler="ddim")
    candidates, _ = proposer.sample(torch.zeros(2, 4))
    assert candidates.shape == (2, 7, 4, 2)
    assert all(torch.equal(v, proposer.noise_model.state_dict()[k]) for k, v in weights.items())
    with pytest.raises(ValueError, match="num_candidates"):
        proposer.configure_sampling(num_candidates=0)
    with pytest.raises(ValueError, match="num_inference_steps"):
        proposer.configure_sampling(num_inference_steps=5000)
    with pytest.raises(ValueError, match="sampler"):
        proposer.configure_sampling(sampler="euler")
