"""DiffusionProposer: multimodality, shapes and layouts, bounds, reproducibility, bad input."""

from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict
from torchrl.envs import TransformedEnv

from torchrl_auv.envs import AUVTrackingEnv, DataCollectionEnv, StateActionHistory
from torchrl_auv.modules import DiffusionProposer
from torchrl_auv.objectives import DenoisingLoss


def _bimodal_batch(n, generator, horizon=1):
    """Two modes per state: +-(0.6, 0.4 s0) with 0.05 noise, equally likely."""
    state = torch.rand(n, 4, generator=generator) * 2 - 1
    sign = torch.where(torch.rand(n, generator=generator) < 0.5, 1.0, -1.0)
    centre = torch.stack((0.6 * sign, 0.4 * state[:, 0] * sign), -1)
    action = centre + 0.05 * torch.randn(n, 2, generator=generator)
    return TensorDict(
        {"observation": state, "action_chunk": action.unsqueeze(1).expand(n, horizon, 2)},
        batch_size=[n],
    )


def _train_bimodal(schedule, steps=1500):
    g = torch.Generator().manual_seed(0)
    proposer = DiffusionProposer(4, 2, horizon=1, schedule=schedule, num_candidates=1000)
    loss = DenoisingLoss(proposer, generator=g)
    optim = torch.optim.Adam(loss.parameters(), lr=1e-3)
    for _ in range(steps):
        value = loss(_bimodal_batch(256, g))["loss_denoising"]
        optim.zero_grad()
        value.backward()
        optim.step()
    return proposer


def _mode_fractions(proposer):
    state = torch.tensor([[0.5, 0.0, 0.0, 0.0]])
    candidates, _ = proposer.sample(state, generator=torch.Generator().manual_seed(1))
    x = candidates[0, :, 0, 0]  # first coordinate of 1000 candidates; modes at +-0.6
    return (x >= 0.3).float().mean().item(), (x <= -0.3).float().mean().item()


@pytest.mark.parametrize(
    ("schedule", "samplers"),
    [("linear", [("ddpm", 50)]), ("cosine", [("ddpm", 50), ("ddim", 10)])],
)
def test_the_proposer_is_multimodal_not_a_mean_regressor(schedule, samplers):
    proposer = _train_bimodal(schedule)
    for sampler, steps in samplers:
        proposer.sampler, proposer.num_inference_steps = sampler, steps
        positive, negative = _mode_fractions(proposer)
        between = 1 - positive - negative
        assert 0.3 <= positive <= 0.7 and 0.3 <= negative <= 0.7, (sampler, positive, negative)
        assert between < 0.05, (sampler, between)


def test_shapes_for_single_agent_and_multi_agent_layouts():
    env = TransformedEnv(AUVTrackingEnv(batch_size=[4], seed=0), StateActionHistory(10))
    proposer = DiffusionProposer.for_env(env, num_inference_steps=3)
    td = proposer(env.reset())
    assert td["proposer", "candidates"].shape == (4, 5, 8, 3)
    assert td["proposer", "first_actions"].shape == (4, 5, 3)
    single = TransformedEnv(AUVTrackingEnv(batch_size=[], seed=0), StateActionHistory(10))
    assert proposer(single.reset())["proposer", "candidates"].shape == (5, 8, 3)
    fleet = DataCollectionEnv(batch_size=[4], seed=0, num_auvs=2)
    fleet = TransformedEnv(
        fleet,
        StateActionHistory(
            10, observation_key=("agents", "observation"), action_key=("agents", "action")
        ),
    )
    proposer = DiffusionProposer.for_env(fleet, num_candidates=3, num_inference_steps=3)
    td = proposer(fleet.reset())
    assert td["agents", "proposer", "candidates"].shape == (4, 2, 3, 8, 3)


def test_candidates_stay_inside_the_action_bounds():
    low, high = torch.tensor([-2.0, 0.0, 10.0]), torch.tensor([-1.0, 0.5, 30.0])
    proposer = DiffusionProposer(5, 3, action_low=low, action_high=high, num_inference_steps=5)
    with torch.no_grad():  # an untrained model with large weights still stays inside
        for p in proposer.parameters():
            p.mul_(5.0)
    candidates, _ = proposer.sample(torch.randn(64, 5) * 10)
    assert (candidates >= low).all() and (candidates <= high).all()


@pytest.mark.parametrize("sampler", ["ddpm", "ddim"])
def test_same_generator_seed_gives_identical_candidates(sampler):
    proposer = DiffusionProposer(5, 3, sampler=sampler, num_inference_steps=5, num_stages=3)
    state = torch.randn(2, 5)

    def draw(seed):
        return proposer.sample(state, generator=torch.Generator().manual_seed(seed))

    (a, stages_a), (b, stages_b), (c, _) = draw(7), draw(7), draw(8)
    assert torch.equal(a, b) and torch.equal(stages_a, stages_b) and not torch.equal(a, c)
    assert stages_a.shape == (2, 3, 5, 8, 3)
    torch.testing.assert_close(stages_a[:, -1], a)  # the last stage is the result


def test_acting_alone_writes_the_first_action_of_candidate_zero():
    proposer = DiffusionProposer(4, 2, num_inference_steps=2, action_key="action")
    td = proposer(TensorDict({"observation": torch.zeros(3, 4)}, batch_size=[3]))
    torch.testing.assert_close(td["action"], td["proposer", "candidates"][:, 0, 0])


def test_checkpoint_round_trip(tmp_path):
    proposer = DiffusionProposer(4, 2, num_inference_steps=4, noise_model="unet", horizon=8)
    proposer.enable_ema(0.9)
    path = proposer.save(tmp_path / "proposer.pt")
    loaded = DiffusionProposer.load(path)
    state = torch.randn(3, 4)
    a, _ = proposer.sample(state, generator=torch.Generator().manual_seed(0))
    b, _ = loaded.sample(state, generator=torch.Generator().manual_seed(0))
    assert torch.equal(a, b) and loaded.config() == proposer.config()
    with pytest.raises(ValueError, match="exists"):
        proposer.save(path)  # never overwrites


CALLED = []


def _record_call():
    CALLED.append(True)
    return {}


class _RunsCodeWhenUnpickled:
    def __reduce__(self):
        return (_record_call, ())


def test_load_refuses_a_file_that_would_run_code(tmp_path):
    # a proposer file is loaded with weights_only=True: tensors and plain containers only
    proposer = DiffusionProposer(4, 2, num_inference_steps=2)
    data = {"config": proposer.config(), "payload": _RunsCodeWhenUnpickled()}
    torch.save(data, tmp_path / "proposer.pt")
    with pytest.raises(Exception, match="Weights only load failed"):
        DiffusionProposer.load(tmp_path / "proposer.pt")
    assert not CALLED


def test_a_pickled_proposer_leaves_its_compiled_steps_behind():
    # worker processes and Ray actors receive the policy pickled; compiled functions are not
    # picklable, and each worker compiles its own
    import pickle

    proposer = DiffusionProposer(4, 2, num_inference_steps=2, compile=True)
    proposer._compiled[0] = lambda x: x  # stands in for a torch.compile'd step
    copy = pickle.loads(pickle.dumps(proposer))
    assert copy._compiled == {} and copy.compile and proposer._compiled
    state = torch.randn(3, 4)
    a, _ = proposer.sample(state, generator=torch.Generator().manual_seed(0))
    b, _ = copy.sample(state, generator=torch.Generator().manual_seed(0))
    assert torch.equal(a, b)


def _perturb(module, generator, scale=0.05):
    with torch.no_grad():
        for p in module.parameters():
            p.add_(scale * torch.randn(p.shape, generator=generator))


def test_ema_is_decay_times_old_plus_one_minus_decay_times_new():
    decay = 0.9
    proposer = DiffusionProposer(4, 2, num_inference_steps=3)
    proposer.enable_ema(decay)
    g = torch.Generator().manual_seed(0)
    proposer.update_ema()  # the first update copies the weights
    expected = {n: p.detach().clone() for n, p in proposer.noise_model.named_parameters()}
    for _ in range(3):
        _perturb(proposer.noise_model, g)
        proposer.update_ema()
        for n, p in proposer.noise_model.named_parameters():
            expected[n] = decay * expected[n] + (1 - decay) * p.detach()
    averaged = dict(proposer.ema.module.named_parameters())
    for n, value in expected.items():
        torch.testing.assert_close(averaged[n], value, rtol=1e-6, atol=1e-7)
        assert not torch.equal(averaged[n], dict(proposer.noise_model.named_parameters())[n])


def test_ema_is_used_only_when_enabled():
    proposer = DiffusionProposer(4, 2, num_inference_steps=3)
    proposer.enable_ema(0.5)
    proposer.update_ema()
    _perturb(proposer.noise_model, torch.Generator().manual_seed(0))
    proposer.update_ema()  # now halfway between the old and the new weights
    state, seed = torch.randn(2, 4), 3
    trained, _ = proposer.sample(state, generator=torch.Generator().manual_seed(seed))
    proposer.use_ema = True
    averaged, _ = proposer.sample(state, generator=torch.Generator().manual_seed(seed))
    assert not torch.equal(trained, averaged)
    # sampling with use_ema is sampling from a model that holds the averaged weights
    copy = DiffusionProposer(4, 2, num_inference_steps=3)
    copy.noise_model.load_state_dict(proposer.ema.module.state_dict())
    expected, _ = copy.sample(state, generator=torch.Generator().manual_seed(seed))
    torch.testing.assert_close(averaged, expected)


def test_ema_checkpoint_round_trip_keeps_weights_decay_and_use_ema(tmp_path):
    decay = 0.9
    proposer = DiffusionProposer(4, 2, num_inference_steps=3)
    proposer.enable_ema(decay)
    g = torch.Generator().manual_seed(0)
    for _ in range(2):
        _perturb(proposer.noise_model, g)
        proposer.update_ema()
    proposer.use_ema = True
    loaded = DiffusionProposer.load(proposer.save(tmp_path / "ema.pt"))
    assert loaded.ema_decay == decay and loaded.use_ema
    state, seed = torch.randn(3, 4), 5
    before, _ = proposer.sample(state, generator=torch.Generator().manual_seed(seed))
    after, _ = loaded.sample(state, generator=torch.Generator().manual_seed(seed))
    assert torch.equal(before, after)
    # training resumes with the saved decay: one more identical step on both copies
    for p in (proposer, loaded):
        _perturb(p.noise_model, torch.Generator().manual_seed(7))
    old = {n: p.detach().clone() for n, p in loaded.ema.module.named_parameters()}
    for p in (proposer, loaded):
        p.update_ema()
    for n, p in loaded.ema.module.named_parameters():
        new = dict(loaded.noise_model.named_parameters())[n].detach()
        torch.testing.assert_close(p, decay * old[n] + (1 - decay) * new, rtol=1e-6, atol=1e-7)
        torch.testing.assert_close(p, dict(proposer.ema.module.named_parameters())[n])


@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"num_candidates": 0}, "num_candidates"),
        ({"num_inference_steps": 0}, "num_inference_steps"),
        ({"num_inference_steps": 1001}, "num_inference_steps"),
        ({"noise_model": "unet", "horizon": 5}, "horizon"),
        ({"noise_model": "transformer"}, "noise_model"),
        ({"sampler": "euler"}, "sampler"),
        ({"action_low": 1.0, "action_high": 0.0}, "action_high"),
    ],
)
def test_bad_input_names_the_argument(kwargs, argument):
    with pytest.raises(ValueError, match=argument):
        DiffusionProposer(4, 2, **kwargs)


def test_missing_history_key_is_a_clear_error():
    env = AUVTrackingEnv(batch_size=[2], seed=0)  # not wrapped with StateActionHistory
    proposer = DiffusionProposer.for_env(env, num_inference_steps=2)
    with pytest.raises(ValueError, match="history_key"):
        proposer(env.reset())
