"""Expert demonstrations for diffusion pretraining: state history -> action chunk.

Each sample is one decision of a scripted-expert episode: the observation, the last ``L``
(observation, action) pairs from :class:`~torchrl_auv.envs.StateActionHistory` and the chunk of
the next ``H`` expert actions (padded with the episode's last action past its end, with a mask).
Datasets are written with TorchRL's own storage (``TensorDictReplayBuffer`` over a
``LazyMemmapStorage``, ``dumps``/``loads``) so they load straight back into a replay buffer.

Command line::

    python -m torchrl_auv.envs.demonstrations --env tracking --episodes 8 --out demos/

Keys of a sample: ``observation`` ``[obs]``; ``("history", "observation")`` ``[L, obs]``;
``("history", "action")`` ``[L, 3]``; ``("history", "mask")`` ``[L]``; ``action`` ``[3]``
(the expert's action now); ``action_chunk`` ``[H, 3]``; ``action_chunk_mask`` ``[H]``;
``episode`` and ``step`` (int64).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

import torch
from tensordict import TensorDict
from torchrl.data import LazyMemmapStorage, TensorDictReplayBuffer
from torchrl.envs import TransformedEnv

from torchrl_auv.envs.experts import ScriptedExpert
from torchrl_auv.envs.history import StateActionHistory
from torchrl_auv.envs.tracking import AUVTrackingEnv

__all__ = ["collect_demonstrations", "load_demonstrations", "save_demonstrations"]

ENVS = ("tracking",)


def collect_demonstrations(
    env: str = "tracking",
    *,
    episodes: int = 4,
    max_steps: int = 300,
    horizon: int = 8,
    history: int = 10,
    sea_state: str = "ideal",
    controller: str = "s_surface",
    seed: int = 0,
) -> TensorDict:
    """Roll the scripted expert out for ``episodes`` batched episodes; return ``[N]`` samples.

    >>> data = collect_demonstrations(episodes=2, max_steps=5, horizon=4, history=3)
    >>> data["action_chunk"].shape, data["history", "observation"].shape
    (torch.Size([10, 4, 3]), torch.Size([10, 3, 16]))
    """
    if env not in ENVS:
        raise ValueError(f"env must be one of {ENVS}, got {env!r}")
    for name, value in (
        ("episodes", episodes),
        ("max_steps", max_steps),
        ("horizon", horizon),
        ("history", history),
    ):
        if value < 1:
            raise ValueError(f"{name} must be >= 1, got {value}")
    base = AUVTrackingEnv(
        batch_size=[episodes],
        sea_state=sea_state,
        controller=controller,
        seed=seed,
        max_steps=max_steps,
    )
    tenv = TransformedEnv(base, StateActionHistory(history))
    rollout = tenv.rollout(max_steps, ScriptedExpert(base), break_when_any_done=False)
    actions = rollout["action"]  # [E, T, 3]
    steps = actions.shape[1]
    padded = torch.cat([actions, actions[:, -1:].expand(-1, horizon - 1, -1)], 1)
    chunks = padded.unfold(1, horizon, 1).permute(0, 1, 3, 2)  # [E, T, H, 3]
    t = torch.arange(steps).unsqueeze(-1) + torch.arange(horizon)
    chunk_mask = (t < steps).expand(episodes, steps, horizon)
    data = TensorDict(
        {
            "observation": rollout["observation"],
            "history": rollout["history"].clone(),
            "action": actions,
            "action_chunk": chunks.contiguous(),
            "action_chunk_mask": chunk_mask.contiguous(),
            "episode": torch.arange(episodes).unsqueeze(-1).expand(episodes, steps).clone(),
            "step": torch.arange(steps).expand(episodes, steps).clone(),
        },
        batch_size=[episodes, steps],
    )
    return data.reshape(-1)


def save_demonstrations(data: TensorDict, out: str | Path, *, metadata: dict | None = None) -> Path:
    """Write ``data`` with ``TensorDictReplayBuffer(LazyMemmapStorage).dumps`` under ``out``.

    Refuses to overwrite an existing non-empty folder (nothing the user made is lost).
    """
    out = Path(out)
    if out.exists() and any(out.iterdir()):
        raise ValueError(f"out folder {out} exists and is not empty; choose a new folder")
    out.mkdir(parents=True, exist_ok=True)
    buffer = TensorDictReplayBuffer(
        storage=LazyMemmapStorage(len(data), scratch_dir=str(out / "scratch"))
    )
    buffer.extend(data)
    buffer.dumps(str(out / "buffer"))
    (out / "metadata.json").write_text(
        json.dumps(
            {
                "samples": len(data),
                "keys": [str(k) for k in data.keys(True, True)],
                **(metadata or {}),
            },
            indent=2,
        )
    )
    return out


def load_demonstrations(path: str | Path) -> TensorDictReplayBuffer:
    """Load a dataset written by :func:`save_demonstrations` into a replay buffer."""
    path = Path(path)
    meta_path = path / "metadata.json"
    if not meta_path.exists():
        raise ValueError(f"path {path} holds no demonstrations (metadata.json missing)")
    meta = json.loads(meta_path.read_text())
    buffer = TensorDictReplayBuffer(storage=LazyMemmapStorage(meta["samples"]))
    buffer.loads(str(path / "buffer"))
    return buffer


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m torchrl_auv.envs.demonstrations --env tracking --episodes N --out DIR``."""
    parser = argparse.ArgumentParser(prog="python -m torchrl_auv.envs.demonstrations")
    parser.add_argument("--env", choices=ENVS, default="tracking")
    parser.add_argument("--episodes", type=int, required=True)
    parser.add_argument("--out", required=True)
    parser.add_argument("--max-steps", type=int, default=300)
    parser.add_argument("--horizon", type=int, default=8)
    parser.add_argument("--history", type=int, default=10)
    parser.add_argument("--sea-state", default="ideal")
    parser.add_argument("--controller", default="s_surface")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    options = {k: v for k, v in vars(args).items() if k != "out"}
    out = Path(args.out)
    if out.exists() and any(out.iterdir()):
        parser.error(f"--out {out} exists and is not empty; choose a new folder")
    try:
        data = collect_demonstrations(**options)
    except ValueError as err:
        parser.error(str(err))
    save_demonstrations(data, out, metadata=options)
    return 0


if __name__ == "__main__":
    sys.exit(main())
