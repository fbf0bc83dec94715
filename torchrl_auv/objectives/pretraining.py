"""Pretraining the diffusion proposer on demonstrations (the paper's offline stage, Fig. 4).

:func:`pretrain_proposer` trains a :class:`~torchrl_auv.modules.DiffusionProposer` with
:class:`~torchrl_auv.objectives.DenoisingLoss` on a dataset of demonstration samples (the
TensorDict written by ``python -m torchrl_auv.cli.demonstrations``), drawing minibatches from a
TorchRL replay buffer, holding out a fraction of the samples to report the held-out denoising
loss, logging the loss curve through any TorchRL logger and optionally keeping an EMA.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import torch
from tensordict import TensorDictBase
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.data.replay_buffers.samplers import RandomSampler

from torchrl_auv.modules import DiffusionProposer
from torchrl_auv.objectives.denoising import DenoisingLoss

__all__ = [
    "LR_SCHEDULES",
    "PretrainResult",
    "heldout_denoising_loss",
    "heldout_split",
    "pretrain_proposer",
]

LR_SCHEDULES = ("constant", "cosine")


@dataclass
class PretrainResult:
    """What a pretraining run measured.

    Attributes:
        steps: optimiser steps at which ``losses`` were recorded.
        losses: training denoising loss (mean over the steps since the previous record).
        heldout_steps, heldout_losses: the held-out loss curve (before training, then every
            ``eval_every`` steps and at the end).
        heldout_loss: held-out denoising loss after training (``nan`` without held-out data).
    """

    steps: list[int] = field(default_factory=list)
    losses: list[float] = field(default_factory=list)
    heldout_steps: list[int] = field(default_factory=list)
    heldout_losses: list[float] = field(default_factory=list)
    heldout_loss: float = float("nan")


@torch.no_grad()
def heldout_denoising_loss(
    loss: DenoisingLoss, data: TensorDictBase, *, batch_size: int = 1024, seed: int = 0
) -> float:
    """Mean denoising loss over ``data`` with fixed timesteps and noise (``seed``)."""
    previous = loss.generator
    loss.generator = torch.Generator().manual_seed(seed)
    try:
        total, count = 0.0, 0
        for start in range(0, len(data), batch_size):
            chunk = data[start : start + batch_size]
            total += loss(chunk)["loss_denoising"].item() * len(chunk)
            count += len(chunk)
    finally:
        loss.generator = previous
    return total / max(count, 1)


def heldout_split(data: TensorDictBase, fraction: float, generator: torch.Generator):
    """``(heldout, train)``: whole episodes held out when ``data`` has an ``episode`` entry
    (samples of one episode are near copies of each other, so a split of samples would
    measure the training fit), else random samples; about ``fraction`` of the samples."""
    if "episode" not in data.keys():
        order = torch.randperm(len(data), generator=generator)
        n = round(fraction * len(data))
        return data[order[:n]], data[order[n:]]
    episodes = data["episode"].unique()
    order = episodes[torch.randperm(len(episodes), generator=generator)]
    n = round(fraction * len(episodes))
    if fraction > 0 and n == 0 and len(episodes) > 1:
        n = 1
    held = torch.isin(data["episode"], order[:n])
    return data[held], data[~held]


def pretrain_proposer(
    proposer: DiffusionProposer,
    data: TensorDictBase,
    *,
    steps: int = 1000,
    batch_size: int = 32,
    lr: float = 1e-4,
    heldout_fraction: float = 0.1,
    ema_decay: float | None = None,
    log_every: int = 50,
    eval_every: int = 200,
    logger=None,
    seed: int = 0,
    skip_overridden: bool = True,
    normalize_state: bool = True,
    lr_schedule: str = "constant",
    weight_decay: float = 0.0,
) -> PretrainResult:
    """Train ``proposer`` on demonstration samples (Adam, the paper's batch 32 and lr 1e-4).

    Args:
        proposer: the proposer (its keys must match the data's).
        data: a flat batch of samples (``[N]``) with the proposer's state keys and the loss's
            action-chunk keys.
        steps: optimiser steps.
        batch_size, lr: minibatch size and Adam learning rate.
        heldout_fraction: fraction kept for the held-out loss: of the episodes when the data
            has an ``episode`` entry (whole scenes held out), else of the samples.
        ema_decay: keep an EMA of the weights (``proposer.enable_ema``) when given.
        log_every: record (and log) the mean training loss every so many steps.
        eval_every: record (and log) the held-out loss every so many steps.
        logger: a TorchRL logger (``log_scalar``) or ``None``.
        seed: seeds the split, the timesteps and the noise (the replay buffer's sampler
            draws minibatches from the global RNG, as TorchRL's samplers do).
        skip_overridden: leave out the samples whose ``overridden`` flag is set (decisions
            whose action the env replaced, e.g. while holding station in service: the
            demonstrated action there was never executed). Data without the key is kept whole.
        normalize_state: fit the proposer's state standardisation
            (:meth:`~torchrl_auv.modules.DiffusionProposer.fit_state_normalization`) on the
            training split before the first step.
        lr_schedule: ``"constant"`` or ``"cosine"`` (annealed to 0 over ``steps``).
        weight_decay: AdamW's decoupled weight decay (0: plain Adam).

    Returns:
        The loss curves and the final held-out loss.

    Examples:
        >>> from tensordict import TensorDict
        >>> data = TensorDict({"observation": torch.randn(64, 4),
        ...                    "action_chunk": torch.rand(64, 8, 2) * 2 - 1}, batch_size=[64])
        >>> result = pretrain_proposer(DiffusionProposer(4, 2), data, steps=20, log_every=10)
        >>> result.steps, len(result.losses)
        ([10, 20], 2)
    """
    for name, value in (
        ("steps", steps),
        ("batch_size", batch_size),
        ("log_every", log_every),
        ("eval_every", eval_every),
    ):
        if not (isinstance(value, int) and value >= 1):
            raise ValueError(f"{name} must be an int >= 1, got {value!r}")
    if not 0.0 <= heldout_fraction < 1.0:
        raise ValueError(f"heldout_fraction must be in [0, 1), got {heldout_fraction}")
    if data.batch_dims != 1 or len(data) < 2:
        raise ValueError(f"data must be a flat batch of >= 2 samples, got {data.batch_size}")
    if skip_overridden and "overridden" in data.keys():
        data = data[~data["overridden"]]
        if len(data) < 2:
            raise ValueError("data holds fewer than 2 samples that are not overridden")
    g = torch.Generator().manual_seed(seed)
    heldout, train = heldout_split(data, heldout_fraction, g)
    n_heldout = len(heldout)
    buffer = TensorDictReplayBuffer(
        storage=LazyTensorStorage(len(train)), sampler=RandomSampler(), batch_size=batch_size
    )
    buffer.extend(train)
    if lr_schedule not in LR_SCHEDULES:
        raise ValueError(f"lr_schedule must be one of {LR_SCHEDULES}, got {lr_schedule!r}")
    if not weight_decay >= 0:
        raise ValueError(f"weight_decay must be >= 0, got {weight_decay}")
    if normalize_state:
        with torch.no_grad():
            proposer.fit_state_normalization(proposer.build_state(train))
    loss = DenoisingLoss(proposer, generator=g, ema_decay=ema_decay)
    optimiser = torch.optim.AdamW(loss.parameters(), lr=lr, weight_decay=weight_decay)
    scheduler = (
        torch.optim.lr_scheduler.CosineAnnealingLR(optimiser, steps)
        if lr_schedule == "cosine"
        else None
    )
    result, running = PretrainResult(), []
    if n_heldout:  # the untrained model's held-out loss, step 0 of the curve
        result.heldout_steps.append(0)
        result.heldout_losses.append(heldout_denoising_loss(loss, heldout))
    for step in range(1, steps + 1):
        value = loss(buffer.sample())["loss_denoising"]
        optimiser.zero_grad()
        value.backward()
        optimiser.step()
        if scheduler is not None:
            scheduler.step()
        if ema_decay is not None:
            loss.update_ema()
        running.append(value.item())
        if step % log_every == 0:
            result.steps.append(step)
            result.losses.append(sum(running) / len(running))
            running = []
            if logger is not None:
                logger.log_scalar("pretrain/loss_denoising", result.losses[-1], step=step)
        if n_heldout and (step % eval_every == 0 or step == steps):
            result.heldout_steps.append(step)
            result.heldout_losses.append(heldout_denoising_loss(loss, heldout))
            if logger is not None:
                logger.log_scalar("pretrain/heldout_loss", result.heldout_losses[-1], step=step)
    if n_heldout:
        result.heldout_loss = result.heldout_losses[-1]
    return result
