"""Fine-tuning the proposer on its own candidates, weighted by their scores (issue [21/26])."""

from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict

from torchrl_auv.modules import DiffusionProposer
from torchrl_auv.objectives import DenoisingLoss
from torchrl_auv.training import (
    CANDIDATES,
    ProposerFineTuning,
    candidate_weights,
    check_config,
    demonstration_samples,
    finetuning_from_config,
    make_history_env,
    proposer_alone,
)
from torchrl_auv.training.proposer_finetuning import SCORES


def test_candidate_weights_are_a_softmax_of_the_centred_scores_in_units_of_their_spread():
    scores = torch.tensor([[0.0, 1.0, 2.0], [10.0, 10.0, 13.0]])
    centred = scores - scores.mean(-1, keepdim=True)
    sigma = centred.square().mean().sqrt()
    for tau in (0.5, 2.0):
        expected = 3 * torch.softmax(centred / (tau * sigma), -1)
        torch.testing.assert_close(candidate_weights(scores, tau), expected)
    # adding a constant to a state's scores, or scaling all of them, changes nothing
    torch.testing.assert_close(
        candidate_weights(scores * 7 + torch.tensor([[3.0], [-5.0]]), 1.0),
        candidate_weights(scores, 1.0),
    )
    # a large temperature: every weight 1 (self-distillation); a small one: the best takes K
    assert torch.allclose(candidate_weights(scores, 1e6), torch.ones(2, 3), atol=1e-4)
    assert torch.allclose(candidate_weights(scores, 1e-3)[:, -1], torch.full((2,), 3.0))
    assert torch.equal(candidate_weights(torch.zeros(4, 5), 1.0), torch.ones(4, 5))


def test_the_weighted_denoising_loss_is_the_loss_of_the_weighted_samples():
    proposer = DiffusionProposer(3, 2, horizon=4)
    chunks = torch.randn(2, 4, 2).clamp(-1, 1)
    data = TensorDict({"observation": torch.randn(2, 3), "action_chunk": chunks}, [2])

    def loss(td):
        return DenoisingLoss(proposer, generator=torch.Generator().manual_seed(0))(td)

    alone = loss(data[:1])["loss_denoising"]
    weighted = loss(data.set("sample_weight", torch.tensor([2.0, 0.0])))["loss_denoising"]
    # the same draws for sample 0 (its timestep and noise come first from the generator)
    two = loss(data.exclude("sample_weight"))
    assert not torch.isclose(two["loss_denoising"], alone)
    g = torch.Generator().manual_seed(0)
    t = torch.randint(0, proposer.schedule.num_train_steps, (2,), generator=g)
    eps = torch.randn(2, 4, 2, generator=g)
    x0 = proposer.normalize(chunks).clamp(-1, 1)
    error = (
        (
            proposer.predict_noise(proposer.schedule.add_noise(x0, eps, t), t, data["observation"])
            - eps
        )
        .square()
        .mean(-1)
    )
    torch.testing.assert_close(weighted, error[0].mean())
    with pytest.raises(ValueError, match=r"sample_weight.*one weight per chunk"):
        loss(data.set("sample_weight", torch.ones(2, 1)))


def _batch(seed: int = 0):
    env = make_history_env("ideal", seed=seed, num_envs=4, history=2, max_steps=20)
    torch.manual_seed(seed)
    proposer = DiffusionProposer.for_env(
        env, num_inference_steps=4, horizon=2, num_candidates=6, sampler="ddim"
    )
    data = env.rollout(8, proposer_alone(proposer), break_when_any_done=False)
    return proposer, data


def _mean_first_heading(proposer, data):
    with torch.no_grad():
        torch.manual_seed(123)
        candidates = proposer(data.select(*proposer.in_keys).copy()).get(CANDIDATES)
    return float(candidates[..., 0, 0].mean())


def _fine_tuned_shift(score) -> tuple[float, dict]:
    """How far 3 x 150 fine-tuning steps move the proposer's mean first setpoint when each
    candidate is scored ``score(candidates)``; and the last step's metrics."""
    proposer, data = _batch()
    before = _mean_first_heading(proposer, data)
    data.set(SCORES, score(data.get(CANDIDATES)))
    tuner = ProposerFineTuning(
        proposer,
        steps=150,
        batch_size=128,
        lr=1e-3,
        temperature=0.3,
        generator=torch.Generator().manual_seed(0),
    )
    for _ in range(3):
        metrics = tuner.step(data, frames=0)
    return _mean_first_heading(proposer, data) - before, metrics


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_fine_tuning_moves_the_proposer_toward_the_candidates_its_scores_prefer(sign):
    """Scores that prefer a larger (or smaller) first setpoint: the proposer's own samples
    move that way; scores that prefer nothing leave it about where it was."""
    moved, metrics = _fine_tuned_shift(lambda candidates: sign * candidates[..., 0, 0])
    assert sign * moved > 0.15, moved
    assert metrics["finetune/top_weight"] > 1.2  # 1: every candidate weighs the same
    unmoved, metrics = _fine_tuned_shift(lambda candidates: torch.zeros(candidates.shape[:-2]))
    assert abs(unmoved) < abs(moved) / 3
    assert metrics["finetune/top_weight"] == pytest.approx(1.0)


def test_fine_tuning_waits_for_its_start_and_reads_the_selectors_scores():
    proposer, data = _batch()
    tuner = ProposerFineTuning(proposer, steps=1, batch_size=4, start_frames=100)
    weights = [p.detach().clone() for p in proposer.noise_model.parameters()]
    assert tuner.step(data, frames=99) == {}
    assert all(
        torch.equal(a, b) for a, b in zip(weights, proposer.noise_model.parameters(), strict=True)
    )
    with pytest.raises(ValueError, match=r"selector.*scores"):
        tuner.step(data, frames=100)
    proposer.enable_ema(0.9)
    proposer.use_ema = True
    with pytest.raises(ValueError, match="use_ema"):
        ProposerFineTuning(proposer, steps=1)


@pytest.mark.parametrize(
    ("finetune", "match"),
    [
        ({"steps": -1}, "finetune.steps must be an integer >= 0"),
        ({"steps": 2.5}, "finetune.steps must be an integer >= 0"),
        ({"steps": 1, "batch_size": 0}, "finetune.batch_size must be an integer >= 1"),
        ({"steps": 1, "lr": 0}, "finetune.lr must be a number > 0"),
        ({"steps": 1, "temperature": -1.0}, "finetune.temperature must be a number > 0"),
        ({"steps": 1, "start_frames": True}, "finetune.start_frames must be an integer >= 0"),
    ],
)
def test_bad_finetune_values_name_the_key(finetune, match):
    with pytest.raises(ValueError, match=match):
        check_config({"finetune": finetune})


def test_finetuning_needs_the_selection_and_is_off_at_zero_steps():
    with pytest.raises(ValueError, match=r"finetune.steps > 0.*residual.bound=0"):
        check_config({"finetune": {"steps": 5}, "residual": {"bound": 0.2}})
    proposer, _ = _batch()
    assert finetuning_from_config({"finetune": {"steps": 0}}, proposer) is None
    assert finetuning_from_config({}, proposer) is None
    tuner = finetuning_from_config({"seed": 3, "finetune": {"steps": 4, "lr": 3e-4}}, proposer)
    assert tuner.steps == 4 and tuner.optimizer.param_groups[0]["lr"] == 3e-4


def test_the_first_stages_samples_are_mixed_into_every_step_as_the_anchor(tmp_path):
    """demo_fraction: the share of each step's chunks from the first stage's expert-labelled
    data (demonstrations and DAgger rounds), weight 1, their state the proposer's own."""
    from torchrl_auv.envs.demonstrations import collect_demonstrations, save_demonstrations

    proposer, data = _batch()
    options = dict(env="data_collection", episodes=1, max_steps=6, horizon=2, history=2)
    save_demonstrations(collect_demonstrations(seed=0, **options), tmp_path / "demonstrations")
    save_demonstrations(collect_demonstrations(seed=1, **options), tmp_path / "dagger1")
    demos = demonstration_samples(tmp_path, proposer, size=1000)
    assert demos.shape[0] == 2 * 6 * 2  # both datasets, all of them (fewer than asked)
    assert demos["state"].shape[-1] == proposer.state_dim
    assert demonstration_samples(tmp_path, proposer, size=5).shape[0] == 5
    data.set(SCORES, torch.zeros(data.get(CANDIDATES).shape[:-2]))
    tuner = ProposerFineTuning(
        proposer, steps=1, batch_size=10, demonstrations=demos, demo_fraction=0.3
    )
    batch = tuner._minibatch(tuner.samples(data))
    assert batch.shape[0] == 10 and batch["sample_weight"].tolist() == [1.0] * 10
    states = {tuple(row.tolist()) for row in demos["state"]}
    assert sum(tuple(row.tolist()) in states for row in batch["state"]) == 3
    assert tuner.step(data, frames=0)["finetune/loss"] > 0
    with pytest.raises(ValueError, match="demo_fraction > 0 needs demonstrations"):
        ProposerFineTuning(proposer, steps=1, demo_fraction=0.5)
    with pytest.raises(ValueError, match="no first-stage demonstrations"):
        demonstration_samples(tmp_path / "none", proposer, size=5)
    with pytest.raises(ValueError, match=r"finetune.demo_fraction must be a number in \[0, 1\)"):
        check_config({"finetune": {"steps": 1, "demo_fraction": 1.0}})
