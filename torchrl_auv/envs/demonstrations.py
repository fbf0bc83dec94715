"""Expert demonstrations for diffusion pretraining: state history -> action chunk.

Each sample is one decision of one AUV in a scripted-expert episode: the observation, the last
``L`` (observation, action) pairs from :class:`~torchrl_auv.envs.StateActionHistory` and the
chunk of the next ``H`` expert actions of the same AUV in the same episode (padded with the
episode's last action past its end, with a mask). The data-collection env's AUVs become
separate samples (``agent`` says which). Datasets are written with TorchRL's own storage
(``TensorDictReplayBuffer`` over a ``LazyMemmapStorage``, ``dumps``/``loads``) so they load
straight back into a replay buffer.

Command line::

    python -m torchrl_auv.envs.demonstrations --env tracking --episodes 8 --out demos/
    python -m torchrl_auv.envs.demonstrations --env data_collection --episodes 4 --out demos_dc/

Keys of a sample: ``observation`` ``[obs]`` (16 tracking, 37 data collection);
``("history", "observation")`` ``[L, obs]``; ``("history", "action")`` ``[L, 3]``;
``("history", "mask")`` ``[L]``; ``action`` ``[3]`` (the expert's action now);
``action_chunk`` ``[H, 3]``; ``action_chunk_mask`` ``[H]``; ``overridden`` (bool: the env
replaced this decision's action, an AUV holding station in service: the expert's action there
was never executed); ``episode`` (the env batch row), ``agent`` and ``step`` (int64). A chunk
stops (its mask turns false) at the first overridden decision after the sample's own, as at
an episode's end. :func:`~torchrl_auv.objectives.pretrain_proposer` leaves overridden samples
out by default.
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
from torchrl.envs import EnvBase, TransformedEnv

from torchrl_auv.envs.data_collection import DataCollectionEnv
from torchrl_auv.envs.experts import ScriptedExpert
from torchrl_auv.envs.history import StateActionHistory, history_key_for
from torchrl_auv.envs.tracking import AUVTrackingEnv

__all__ = ["collect_demonstrations", "load_demonstrations", "save_demonstrations"]

ENVS = ("tracking", "data_collection")


def _make_env(env: str, episodes: int, max_steps: int, **options: object) -> EnvBase:
    if env == "tracking":
        return AUVTrackingEnv(batch_size=[episodes], max_steps=max_steps, **options)
    return DataCollectionEnv(batch_size=[episodes], max_steps=max_steps, **options)


def _chunks(actions: torch.Tensor, done: torch.Tensor, horizon: int):
    """Action chunks ``[R, T, H, 3]`` and masks ``[R, T, H]`` that never cross an episode end.

    ``actions`` ``[R, T, 3]`` and ``done`` ``[R, T]`` (``done[t]``: the episode ended after
    action ``t``); a rollout row may hold several episodes (auto-reset).
    """
    rows, steps = done.shape
    episode_of = done.long().cumsum(1) - done.long()  # episode number of each step in its row
    t = torch.arange(steps).unsqueeze(-1) + torch.arange(horizon)  # [T, H]
    inside = t < steps
    t_clamped = t.clamp_max(steps - 1)
    same = episode_of[:, t_clamped] == episode_of.unsqueeze(-1)
    valid = inside & same  # [R, T, H], a prefix in h
    last = torch.arange(steps).unsqueeze(-1) + valid.sum(-1, keepdim=True) - 1  # [R, T, 1]
    index = torch.where(valid, t_clamped.expand_as(valid), last)  # [R, T, H]
    return actions[torch.arange(rows)[:, None, None], index], valid


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
    **env_options: object,
) -> TensorDict:
    """Roll the scripted expert out in ``episodes`` parallel scenes; return a flat batch.

    Args:
        env: ``"tracking"`` or ``"data_collection"``.
        episodes: scenes run side by side (the env batch); a scene that ends early restarts.
        max_steps: decisions per scene.
        horizon: chunk length ``H``.
        history: history length ``L``.
        sea_state, controller, seed: passed to the env.
        env_options: further env arguments (e.g. ``rate_model="paper"`` for data collection).

    Returns:
        ``episodes * max_steps`` samples (times the number of AUVs), keys in the module docs.

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
    base = _make_env(
        env, episodes, max_steps, sea_state=sea_state, controller=controller, seed=seed,
        **env_options,
    )  # fmt: skip
    obs_key = getattr(base, "observation_key", "observation")
    act_key = getattr(base, "agent_action_key", "action")
    tenv = TransformedEnv(
        base, StateActionHistory(history, observation_key=obs_key, action_key=act_key)
    )
    rollout = tenv.rollout(max_steps, ScriptedExpert(base), break_when_any_done=False)
    data = TensorDict(
        {
            "observation": rollout[obs_key],
            "history": rollout[history_key_for(obs_key)].clone(),
            "action": rollout[act_key],
        },
        batch_size=rollout[obs_key].shape[:-1],
    )
    done = rollout["next", "done"].squeeze(-1)  # [E, T]
    overridden = rollout.get(("next", "overridden"), None)
    if overridden is None:
        overridden = torch.zeros(data.batch_size, dtype=torch.bool)
    data["overridden"] = overridden
    if data.batch_dims == 3:  # [E, T, N]: AUVs become rows of their own
        n = data.batch_size[-1]
        data = data.permute(0, 2, 1).contiguous().reshape(episodes * n, max_steps)
        done = done.repeat_interleave(n, 0)
        agent = torch.arange(n).repeat(episodes)
    else:
        agent = torch.zeros(episodes, dtype=torch.int64)
    rows = data.batch_size[0]
    chunks, chunk_mask = _chunks(data["action"], done, horizon)
    # a chunk stops at the first later decision the env overrode (its action never ran)
    later = _chunks(data["overridden"].unsqueeze(-1).float(), done, horizon)[0][..., 0] > 0
    later[..., 0] = False
    chunk_mask = chunk_mask & (later.long().cumsum(-1) == 0)
    data["action_chunk"] = chunks.contiguous()
    data["action_chunk_mask"] = chunk_mask.contiguous()
    episode = torch.arange(episodes).repeat_interleave(rows // episodes)
    data["episode"] = episode.unsqueeze(-1).expand(rows, max_steps).clone()
    data["agent"] = agent.unsqueeze(-1).expand(rows, max_steps).clone()
    data["step"] = torch.arange(max_steps).expand(rows, max_steps).clone()
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
    """``python -m torchrl_auv.envs.demonstrations --env {tracking,data_collection} --episodes N
    --out DIR``."""
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
