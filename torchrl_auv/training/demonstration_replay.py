"""SAC that sees the demonstrations the diffusion frameworks start from: the scripted expert's
transitions in a buffer of their own, sampled beside the online buffer in every update
(symmetric sampling, after RLPD: Ball, Smith, Kostrikov and Levine 2023, half of each batch
from each buffer), through TorchRL's ``ReplayBufferEnsemble``.

``cfg.demonstrations.frames`` expert frames (scene-decisions, every AUV included) are collected
before training on their own scenes (seed ``cfg.seed + DEMONSTRATION_SEED_OFFSET``, never the
training or the held-out scenes) with the training env's settings; ``0`` is plain SAC. The
diffusion frameworks' first stage collects ``demo_batches x demo_episodes x demo_steps``
expert frames (plus its DAgger rounds): demonstrations are not free, so a run reports them
(``demonstration frames`` in its summary) beside its training frames.

Examples:
    >>> from torchrl_auv.training import make_replay_buffer, make_env, select_for_replay
    >>> online = make_replay_buffer(100, batch_size=8)
    >>> _ = online.extend(select_for_replay(make_env("ideal", seed=0, num_envs=2).rollout(3)))
    >>> demos = select_for_replay(make_env("ideal", seed=1, num_envs=2).rollout(5))
    >>> sample = symmetric_sampler(online, demos, batch_size=8)
    >>> sample().batch_size
    torch.Size([8])
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import torch
from tensordict import TensorDictBase
from torchrl.data import LazyTensorStorage, ReplayBufferEnsemble, TensorDictReplayBuffer

from torchrl_auv.evaluation import expert_policy
from torchrl_auv.training.collectors import make_collector
from torchrl_auv.training.env import env_factory
from torchrl_auv.training.n_step import n_step_from_config
from torchrl_auv.training.replay import select_for_replay

__all__ = [
    "DEMONSTRATION_SEED_OFFSET",
    "collect_demonstrations",
    "demonstration_frames",
    "sampler_from_config",
    "symmetric_sampler",
]

#: the demonstration scenes' seed is the run's plus this (held-out scenes start at 100000)
DEMONSTRATION_SEED_OFFSET = 7_000_000


def demonstration_frames(cfg: Mapping) -> int:
    """``cfg.demonstrations.frames`` (``0`` where absent), checked."""
    frames = (cfg.get("demonstrations") or {}).get("frames", 0)
    if isinstance(frames, bool) or not isinstance(frames, int) or frames < 0:
        raise ValueError(f"demonstrations.frames must be an integer >= 0, got {frames!r}")
    return frames


@torch.no_grad()
def collect_demonstrations(cfg: Mapping, frames: int) -> TensorDictBase:
    """``frames`` frames of the scripted expert on the training env's settings (scenes seeded
    ``cfg.seed + DEMONSTRATION_SEED_OFFSET``), as the replay buffer stores them
    (:func:`~torchrl_auv.training.select_for_replay`), ``[frames']`` with ``frames'`` the
    collector's batches covering ``frames``; with ``cfg.optim.n_steps > 1`` as n-step returns
    like the online frames (each scene's last ``n_steps`` decisions then not stored)."""
    env = env_factory(cfg)(seed=cfg["seed"] + DEMONSTRATION_SEED_OFFSET)
    batch = cfg["collector"]["frames_per_batch"]
    collector = make_collector(
        env, expert_policy(env), frames_per_batch=batch, total_frames=frames, device=cfg["device"]
    )
    n_step = n_step_from_config(cfg)  # its own window: the demonstrations' scenes
    try:
        stored = (select_for_replay(data, n_step=n_step) for data in collector)
        return torch.cat([chunk for chunk in stored if chunk is not None])
    finally:
        collector.shutdown()


def symmetric_sampler(
    online: TensorDictReplayBuffer, demonstrations: TensorDictBase, *, batch_size: int
) -> Callable[[], TensorDictBase]:
    """A function returning batches of ``batch_size`` frames, half from ``online`` and half
    from ``demonstrations`` (uniform within each; ``batch_size`` even)."""
    if batch_size % 2:
        raise ValueError(
            f"replay_buffer.batch_size must be even to sample half of it from the "
            f"demonstrations, got {batch_size}"
        )
    demos = TensorDictReplayBuffer(storage=LazyTensorStorage(len(demonstrations)))
    demos.extend(demonstrations)
    both = ReplayBufferEnsemble(online, demos, sample_from_all=True, batch_size=batch_size)

    def sample() -> TensorDictBase:
        return both.sample().exclude("index").reshape(-1)

    return sample


def sampler_from_config(
    cfg: Mapping, online: TensorDictReplayBuffer
) -> tuple[Callable[[], TensorDictBase], int]:
    """The update's batch source of a SAC config and the demonstration frames it holds:
    ``online.sample`` without demonstrations, else :func:`symmetric_sampler` over the
    expert frames :func:`collect_demonstrations` gathers."""
    frames = demonstration_frames(cfg)
    if frames == 0:
        return online.sample, 0
    demonstrations = collect_demonstrations(cfg, frames)
    batch = cfg["replay_buffer"]["batch_size"]
    return symmetric_sampler(online, demonstrations, batch_size=batch), len(demonstrations)
