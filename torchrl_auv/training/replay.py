"""The replay buffer of the recipes: what a learner reads of each collected frame, stored in
RAM or on disk.

Examples:
    >>> from torchrl_auv.training import make_env
    >>> frames = select_for_replay(make_env("ideal", seed=0, num_envs=2).rollout(3))
    >>> frames.batch_size, bytes_per_frame(frames[0]) < 1024
    (torch.Size([6]), True)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

from tensordict import TensorDictBase
from torchrl.data import LazyMemmapStorage, LazyTensorStorage, TensorDictReplayBuffer

from torchrl_auv.envs.keys import AGENT_COST, AGENT_REWARD, AGENT_STABILITY_COST
from torchrl_auv.training.keys import ACTION, AGENTS, OBSERVATION
from torchrl_auv.training.n_step import EPISODE_DONE, N_STEP_KEYS, NStepReturns

__all__ = [
    "REPLAY_KEYS",
    "buffer_from_config",
    "bytes_per_frame",
    "make_replay_buffer",
    "select_for_replay",
]


#: What the losses read. The env keeps its simulator state (terrain, waves, nodes: about 30 KB
#: per scene and step) under ``"sim"``, which excluding alone leaves under 1 KB per frame; the
#: recipes store less still (no metrics, cost terms or history: 644 bytes per frame).
REPLAY_KEYS = (
    OBSERVATION,
    ACTION,
    *(("next", *key) for key in (OBSERVATION, AGENT_REWARD, AGENT_COST, AGENT_STABILITY_COST)),
    ("next", AGENTS, "done"),
    ("next", AGENTS, "terminated"),
)


def select_for_replay(
    data: TensorDictBase, extra_keys: Sequence = (), *, n_step: NStepReturns | None = None
) -> TensorDictBase | None:
    """The frames of a collected batch with only :data:`REPLAY_KEYS` (and ``extra_keys``, e.g.
    :data:`~torchrl_auv.training.CANDIDATE_KEYS`), flattened to ``[frames]``.

    With ``n_step`` (a batch ``[*B, T]``, time last) the frames carry n-step returns
    (:class:`~torchrl_auv.training.NStepReturns`, which keeps the last frames of each scene
    for the next batch) and :data:`~torchrl_auv.training.N_STEP_KEYS`; ``None`` while it has
    seen too few decisions to return any."""
    if n_step is None:
        return data.select(*REPLAY_KEYS, *extra_keys).reshape(-1)
    out = n_step(data.select(*REPLAY_KEYS, *extra_keys, ("next", EPISODE_DONE)))
    if out is None:
        return None
    return out.select(*REPLAY_KEYS, *extra_keys, *N_STEP_KEYS).reshape(-1)


def bytes_per_frame(frame: TensorDictBase) -> int:
    """Bytes one stored frame takes (the sum over its leaves; ``frame`` has batch ``[]``)."""
    return sum(t.numel() * t.element_size() for t in frame.values(True, True))


def make_replay_buffer(
    size: int,
    *,
    batch_size: int,
    storage: str = "memory",
    scratch_dir: str | Path | None = None,
) -> TensorDictReplayBuffer:
    """Uniform replay of ``size`` frames in RAM (``storage="memory"``) or on disk
    (``"memmap"``, under ``scratch_dir``)."""
    if storage == "memory":
        backing = LazyTensorStorage(size)
    elif storage == "memmap":
        backing = LazyMemmapStorage(size, scratch_dir=scratch_dir)
    else:
        raise ValueError(f"replay_buffer.storage must be 'memory' or 'memmap', got {storage!r}")
    return TensorDictReplayBuffer(storage=backing, batch_size=batch_size)


def buffer_from_config(cfg: Mapping, run_dir: str | Path) -> TensorDictReplayBuffer:
    """The replay buffer of ``cfg.replay_buffer`` (memmap under ``run_dir/replay``)."""
    rb = cfg["replay_buffer"]
    return make_replay_buffer(
        rb["size"],
        batch_size=rb["batch_size"],
        storage=rb["storage"],
        scratch_dir=Path(run_dir) / "replay",
    )
