r"""Fine-tuning the proposer on its own candidates, weighted by the critic (issue [21/26]).

The selection executes one of the proposer's K candidates and the critics learn the value of
that policy (``selection.backup: candidates``). Fine-tuning moves the proposer itself toward the
candidates its critic prefers, so that what the proposer samples (and so its medoid, the
anchor the selection executes) improves, not only which sample is picked. Each collected
batch, after the critics' updates, ``finetune.steps`` gradient steps of the denoising loss
(:class:`~torchrl_auv.objectives.DenoisingLoss`) on the batch's own candidate chunks, each
weighted by a softmax of its score over the K candidates of its state:

.. math::

    w_k = K\,\frac{\exp(d_k / (\tau \sigma))}{\sum_j \exp(d_j / (\tau \sigma))}, \qquad
    d_k = q_k - \tfrac1K \textstyle\sum_j q_j,

with :math:`q_k` the selector's score of candidate :math:`k` at acting time (the Q ensemble's
minimum: pessimistic), :math:`\sigma` the standard deviation of :math:`d` over the batch (so the
temperature :math:`\tau` = ``finetune.temperature`` has no unit) and the mean weight 1 per
state. This is advantage-weighted regression on the proposer's own samples: with
:math:`\tau \to \infty` it is self-distillation (the proposer stays where it is in
expectation), with :math:`\tau \to 0` it imitates the critic's best candidate. With
``finetune.demo_fraction = f > 0`` a fraction ``f`` of each step's chunks are the first
stage's expert-labelled samples (its demonstrations and DAgger rounds, weight 1): the
denoising loss of the first stage, kept as an anchor (self-distillation alone drifts away from
the prior; recipes/README.md). Fine-tuning starts at ``finetune.start_frames`` (after the
critics have learnt the anchor's values); the first-stage proposer is untouched (the recipes
copy it first, for the "proposer alone" row).

Examples:
    >>> scores = torch.tensor([[0.0, 1.0, 2.0], [5.0, 5.0, 5.0]])
    >>> candidate_weights(scores, temperature=1.0).sum(-1)
    tensor([3., 3.])
    >>> candidate_weights(scores, temperature=1.0)[1]
    tensor([1., 1., 1.])
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import torch
from tensordict import TensorDict, TensorDictBase

from torchrl_auv.envs.demonstrations import load_demonstrations
from torchrl_auv.modules import DiffusionProposer
from torchrl_auv.objectives import DenoisingLoss
from torchrl_auv.training.candidates import CANDIDATES
from torchrl_auv.training.first_stage.build import demonstrations_with_env_keys
from torchrl_auv.training.keys import AGENTS

__all__ = [
    "SCORES",
    "ProposerFineTuning",
    "candidate_weights",
    "check_finetune",
    "demonstration_samples",
    "finetuning_from_config",
]

#: the selector's score of each candidate at acting time ``[*B, N, K]`` (higher is better)
SCORES = (AGENTS, "selector", "scores")


def candidate_weights(scores: torch.Tensor, temperature: float) -> torch.Tensor:
    """Weights ``[*B, K]`` of each state's K candidates from their ``scores`` ``[*B, K]``:
    ``K * softmax(d / (temperature * sigma))`` over the last dim, ``d`` the scores less their
    state's mean and ``sigma`` the standard deviation of ``d`` over all of ``scores`` (weights
    1 where every ``d`` is 0). Each state's weights sum to K."""
    if scores.ndim < 1 or scores.shape[-1] < 1:
        raise ValueError(f"scores must be shaped [*B, K] with K >= 1, got {list(scores.shape)}")
    centred = scores - scores.mean(-1, keepdim=True)
    sigma = centred.square().mean().sqrt()
    if not bool(sigma > 0):
        return torch.ones_like(scores)
    return scores.shape[-1] * torch.softmax(centred / (temperature * sigma), -1)


class ProposerFineTuning:
    """Advantage-weighted denoising steps of ``proposer`` on the candidates of collected
    batches (the module docstring gives the weights).

    Args:
        proposer: the proposer that acts (trained in place).
        steps: gradient steps per batch (> 0).
        batch_size: candidate chunks per step.
        lr: Adam's step size.
        temperature: :math:`\\tau` (> 0, unitless).
        start_frames: frames collected before the first step.
        demonstrations: expert-labelled samples (``state`` ``[M, D]``, ``action_chunk``
            ``[M, H, A]``, ``action_chunk_mask`` ``[M, H]``, ``sample_weight`` ``[M]``;
            :func:`demonstration_samples`) mixed into every step, or ``None``.
        demo_fraction: the share of each step's chunks drawn from ``demonstrations``.
        generator: source of the minibatches, timesteps and noise.

    Examples:
        >>> from torchrl_auv.training import make_history_env, proposer_alone
        >>> env = make_history_env("ideal", seed=0, num_envs=2, history=3, max_steps=4)
        >>> proposer = DiffusionProposer.for_env(env, num_inference_steps=2, horizon=4)
        >>> data = env.rollout(3, proposer_alone(proposer), break_when_any_done=False)
        >>> _ = data.set(SCORES, torch.randn(2, 3, 2, 5))  # a selector's scores
        >>> tuner = ProposerFineTuning(proposer, steps=2, batch_size=8)
        >>> sorted(tuner.step(data, frames=6))
        ['finetune/loss', 'finetune/top_weight']
    """

    def __init__(
        self,
        proposer: DiffusionProposer,
        *,
        steps: int,
        batch_size: int = 256,
        lr: float = 1e-4,
        temperature: float = 1.0,
        start_frames: int = 0,
        demonstrations: TensorDictBase | None = None,
        demo_fraction: float = 0.0,
        generator: torch.Generator | None = None,
    ) -> None:
        check_finetune(
            {
                "steps": steps,
                "batch_size": batch_size,
                "lr": lr,
                "temperature": temperature,
                "start_frames": start_frames,
                "demo_fraction": demo_fraction,
            }
        )
        if demo_fraction and demonstrations is None:
            raise ValueError("demo_fraction > 0 needs demonstrations (demonstration_samples)")
        self.demonstrations = demonstrations
        self.demo_batch = round(batch_size * demo_fraction) if demonstrations is not None else 0
        if proposer.use_ema:
            raise ValueError(
                "proposer samples from its EMA weights (use_ema): fine-tuning trains the noise "
                "model it does not sample from; set proposer.use_ema = False first"
            )
        self.proposer = proposer
        self.steps, self.batch_size = int(steps), int(batch_size)
        self.temperature, self.start_frames = float(temperature), int(start_frames)
        self.generator = generator
        self.loss = DenoisingLoss(proposer, generator=generator)
        self.loss.set_keys(state="state", action="action_chunk")
        self.parameters = [p for p in proposer.noise_model.parameters()]
        self.optimizer = torch.optim.Adam(self.parameters, lr=float(lr))

    def samples(self, data: TensorDictBase) -> TensorDict:
        """The batch's candidate chunks ``[M * K]`` with their state and weight."""
        candidates = data.get(CANDIDATES, None)
        scores = data.get(SCORES, None)
        if candidates is None or scores is None:
            raise ValueError(
                f"data lack {CANDIDATES!r} or {SCORES!r}: collect with the selection policy "
                "(make_selection_policy), whose proposer and selector write them"
            )
        k = candidates.shape[-3]
        if scores.shape[-1] != k:  # the actor's own action competes: not a candidate
            scores = scores[..., :k]
        with torch.no_grad():
            state = self.proposer.build_state(data)  # [*B, N, D]
            weight = candidate_weights(scores, self.temperature)
        state = state.unsqueeze(-2).expand(*scores.shape, state.shape[-1])
        samples = TensorDict(
            {
                "state": state.reshape(-1, state.shape[-1]),
                "action_chunk": candidates.reshape(-1, *candidates.shape[-2:]),
                "sample_weight": weight.reshape(-1),
            },
            batch_size=[weight.numel()],
        )
        if self.demo_batch:  # the demonstrations' keys, to stack with them
            samples["action_chunk_mask"] = torch.ones(
                samples["action_chunk"].shape[:-1], dtype=torch.bool
            )
        return samples

    def step(self, data: TensorDictBase, frames: int) -> dict[str, float]:
        """Fine-tune on ``data`` (a collected batch) once ``frames`` (collected so far) reach
        ``start_frames``; returns the logged metrics (empty before)."""
        if frames < self.start_frames:
            return {}
        samples = self.samples(data)
        device = samples.device
        was_training = self.proposer.training
        self.proposer.train()
        for p in self.parameters:
            p.requires_grad_(True)
        total = 0.0
        for _ in range(self.steps):
            loss = self.loss(self._minibatch(samples).to(device))["loss_denoising"]
            self.optimizer.zero_grad(set_to_none=True)
            loss.backward()
            self.optimizer.step()
            total += float(loss.detach())
        self.proposer.train(was_training)
        top = samples["sample_weight"].reshape(-1, data.get(CANDIDATES).shape[-3]).amax(-1)
        return {"finetune/loss": total / self.steps, "finetune/top_weight": float(top.mean())}

    def _minibatch(self, samples: TensorDict) -> TensorDict:
        """``batch_size`` chunks: the batch's own and, with demonstrations, their share."""
        own = self.batch_size - self.demo_batch
        index = torch.randint(0, samples.shape[0], (own,), generator=self.generator)
        batch = samples[index]
        if not self.demo_batch:
            return batch
        demos = self.demonstrations
        pick = torch.randint(0, demos.shape[0], (self.demo_batch,), generator=self.generator)
        return torch.cat([batch, demos[pick].select(*batch.keys())])

    def state_dict(self) -> dict:
        """The optimiser's state (the proposer's weights are checkpointed as a module)."""
        return {"optimizer": self.optimizer.state_dict()}

    def load_state_dict(self, state: Mapping) -> None:
        self.optimizer.load_state_dict(state["optimizer"])


def check_finetune(finetune: Mapping) -> None:
    """A ``ValueError`` naming the first ``finetune.*`` value out of range."""
    for name in ("steps", "start_frames"):
        value = finetune.get(name, 0)
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise ValueError(f"finetune.{name} must be an integer >= 0, got {value!r}")
    samples = finetune.get("demo_samples", 50_000)
    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 1:
        raise ValueError(f"finetune.demo_samples must be an integer >= 1, got {samples!r}")
    size = finetune.get("batch_size", 256)
    if isinstance(size, bool) or not isinstance(size, int) or size < 1:
        raise ValueError(f"finetune.batch_size must be an integer >= 1, got {size!r}")
    fraction = finetune.get("demo_fraction", 0.0)
    if isinstance(fraction, bool) or not isinstance(fraction, int | float) or not 0 <= fraction < 1:
        raise ValueError(f"finetune.demo_fraction must be a number in [0, 1), got {fraction!r}")
    for name in ("lr", "temperature"):
        value = finetune.get(name, 1.0)
        if isinstance(value, bool) or not isinstance(value, int | float) or not value > 0:
            raise ValueError(f"finetune.{name} must be a number > 0, got {value!r}")


def demonstration_samples(
    folder: str | Path, proposer: DiffusionProposer, size: int, seed: int = 0
) -> TensorDict:
    """``size`` samples drawn at random (without replacement, ``seed``) from a first stage's
    expert-labelled data in ``folder`` (its ``demonstrations`` and ``dagger<r>`` datasets):
    ``state`` (the proposer's conditioning state), ``action_chunk``, ``action_chunk_mask`` and
    ``sample_weight`` (1)."""
    folder = Path(folder)
    parts = [folder / "demonstrations", *sorted(folder.glob("dagger*"))]
    parts = [path for path in parts if (path / "metadata.json").exists()]
    if not parts:
        raise ValueError(f"folder {folder} holds no first-stage demonstrations")
    keys = ("observation", "history", "action_chunk", "action_chunk_mask", "overridden", "episode")
    data = torch.cat([load_demonstrations(path)[:].select(*keys) for path in parts])
    pick = torch.randperm(len(data), generator=torch.Generator().manual_seed(seed))[:size]
    data = demonstrations_with_env_keys(data[pick])
    with torch.no_grad():
        state = proposer.build_state(data)
    return TensorDict(
        {
            "state": state,
            "action_chunk": data["action_chunk"],
            "action_chunk_mask": data["action_chunk_mask"],
            "sample_weight": torch.ones(data.batch_size),
        },
        batch_size=data.batch_size,
    )


def finetuning_from_config(
    cfg: Mapping, proposer: DiffusionProposer, first_stage: str | Path | None = None
) -> ProposerFineTuning | None:
    """The :class:`ProposerFineTuning` of ``cfg.finetune`` (checked), or ``None`` where
    ``finetune.steps`` is 0 or the config has no ``finetune`` group. With
    ``finetune.demo_fraction > 0`` the ``first_stage`` folder's samples
    (``finetune.demo_samples`` of them, :func:`demonstration_samples`) are mixed in."""
    finetune = cfg.get("finetune") or {}
    check_finetune(finetune)
    if not finetune.get("steps", 0):
        return None
    fraction = finetune.get("demo_fraction", 0.0)
    demonstrations = None
    if fraction:
        if first_stage is None:
            raise ValueError(
                "finetune.demo_fraction > 0 mixes in the first stage's demonstrations: "
                "it needs the first stage's folder (not a bare proposer.path file)"
            )
        size = finetune.get("demo_samples", 50_000)
        demonstrations = demonstration_samples(first_stage, proposer, size, cfg.get("seed", 0))
    return ProposerFineTuning(
        proposer,
        steps=finetune["steps"],
        batch_size=finetune.get("batch_size", 256),
        lr=finetune.get("lr", 1e-4),
        temperature=finetune.get("temperature", 1.0),
        start_frames=finetune.get("start_frames", 0),
        demonstrations=demonstrations,
        demo_fraction=fraction,
        generator=torch.Generator().manual_seed(int(cfg.get("seed", 0)) + 7919),
    )
