"""Expert demonstrations for diffusion pretraining: state history -> action chunk.

Each sample is one decision of one AUV in a scripted-expert episode: the observation, the last
``L`` (observation, action) pairs from :class:`~torchrl_auv.envs.StateActionHistory` and the
chunk of the next ``H`` expert actions of the same AUV in the same episode (padded with the
episode's last action past its end, with a mask). The data-collection env's AUVs become
separate samples (``agent`` says which). Datasets are written with TorchRL's own storage
(``TensorDictReplayBuffer`` over a ``LazyMemmapStorage``, ``dumps``/``loads``) so they load
straight back into a replay buffer.

Command line::

    python -m torchrl_auv.cli.demonstrations --env tracking --episodes 8 --out demos/
    python -m torchrl_auv.cli.demonstrations --env data_collection --episodes 4 --out demos_dc/

Keys of a sample: ``observation`` ``[obs]`` (16 tracking, 38 data collection);
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

import json
from pathlib import Path

import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModuleBase
from torchrl.data import LazyMemmapStorage, TensorDictReplayBuffer
from torchrl.envs import EnvBase, TransformedEnv

from torchrl_auv.envs.data_collection import DataCollectionEnv
from torchrl_auv.envs.experts import ScriptedExpert
from torchrl_auv.envs.history import StateActionHistory, history_key_for
from torchrl_auv.envs.tracking import AUVTrackingEnv

__all__ = [
    "batch_seed",
    "collect_demonstration_batches",
    "collect_demonstrations",
    "load_demonstrations",
    "save_demonstrations",
]

ENVS = ("tracking", "data_collection")
#: Seeds of the batches of :func:`collect_demonstration_batches`: ``seed + SEED_STRIDE * b``.
SEED_STRIDE = 1000


def _make_env(env: str, episodes: int, max_steps: int, **options: object) -> EnvBase:
    if env == "tracking":
        return AUVTrackingEnv(batch_size=[episodes], max_steps=max_steps, **options)
    return DataCollectionEnv(batch_size=[episodes], max_steps=max_steps, **options)


def _label_key(action_key):
    """Where :class:`_Labelled` writes the expert's action (next to the action key)."""
    key = (action_key,) if isinstance(action_key, str) else tuple(action_key)
    return (*key[:-1], "expert_action")


class _Labelled(TensorDictModuleBase):
    """Runs the expert (its action kept under ``expert_action``), then the acting policy."""

    def __init__(self, policy, expert, action_key) -> None:
        super().__init__()
        self.policy, self.expert, self.action_key = policy, expert, action_key
        self.in_keys = list(expert.in_keys)
        self.out_keys = [action_key, _label_key(action_key)]

    def forward(self, tensordict):
        self.expert(tensordict)
        tensordict.set(_label_key(self.action_key), tensordict.get(self.action_key).clone())
        return self.policy(tensordict)


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
    policy=None,
    **env_options: object,
) -> TensorDict:
    """Roll the scripted expert out in ``episodes`` parallel scenes; return a flat batch.

    With ``policy`` another policy acts (e.g. the proposer itself: DAgger, Ross et al. 2011)
    and the expert only labels: each sample's ``action`` and chunk are the expert's actions at
    the states the policy visited, its history the policy's own (executed) actions, and
    ``executed`` the policy's action.

    Args:
        env: ``"tracking"`` or ``"data_collection"``.
        episodes: scenes run side by side (the env batch); a scene that ends early restarts.
        max_steps: decisions per scene.
        horizon: chunk length ``H``.
        history: history length ``L``.
        sea_state, controller, seed: passed to the env.
        policy: ``env -> policy`` (called with the history-wrapped env; the policy writes the
            env's action key), or ``None``: the expert acts.
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
        env,
        episodes,
        max_steps,
        sea_state=sea_state,
        controller=controller,
        seed=seed,
        **env_options,
    )
    obs_key = getattr(base, "observation_key", "observation")
    act_key = getattr(base, "agent_action_key", "action")
    tenv = TransformedEnv(
        base, StateActionHistory(history, observation_key=obs_key, action_key=act_key)
    )
    expert = ScriptedExpert(base)
    actor = expert if policy is None else _Labelled(policy(tenv), expert, act_key)
    rollout = tenv.rollout(max_steps, actor, break_when_any_done=False)
    label_key = act_key if policy is None else _label_key(act_key)
    data = TensorDict(
        {
            "observation": rollout[obs_key],
            "history": rollout[history_key_for(obs_key)].clone(),
            "action": rollout[label_key],
        },
        batch_size=rollout[obs_key].shape[:-1],
    )
    if policy is not None:
        data["executed"] = rollout[act_key]
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


def batch_seed(seed: int, batch: int) -> int:
    """The env seed of demonstration batch ``batch`` (batch 0: ``seed`` itself).

    >>> batch_seed(3, 0), batch_seed(3, 2)
    (3, 2003)
    """
    return seed + SEED_STRIDE * batch


def _collect_batch(batch: int, seed: int, options: dict) -> TensorDict:
    torch.set_num_threads(1)
    # a policy that samples (the proposer in a DAgger round) draws from the global RNG: seed
    # it per batch, so the batch depends on (seed, batch) alone, not on which process ran it
    with torch.random.fork_rng():
        torch.manual_seed(batch_seed(seed, batch))
        data = collect_demonstrations(seed=batch_seed(seed, batch), **options)
    data["batch"] = torch.full(data.batch_size, batch, dtype=torch.int64)
    return data


def collect_demonstration_batches(
    batches: int = 1,
    *,
    workers: int = 1,
    seed: int = 0,
    first_batch: int = 0,
    **options: object,
) -> TensorDict:
    """:func:`collect_demonstrations` ``batches`` times on new scenes, in ``workers`` processes.

    Batch ``b`` (numbered from ``first_batch``: a later call continues on new scenes) runs
    ``options["episodes"]`` scenes seeded :func:`batch_seed` ``(seed, b)``, so
    the data depends on ``batches`` and ``seed`` but not on ``workers``; ``episode`` is
    numbered across batches and ``batch`` says which batch a sample came from. One env batch
    of many scenes is faster per decision than several small ones, and a second process uses
    the idle second core of a 2-core machine.

    Args:
        batches: how many batches (``>= 1``).
        workers: processes (1: in this process; more: spawned worker processes, each with one
            torch thread).
        seed: the seed of batch 0.
        first_batch: the number of the first batch (``>= 0``).
        options: the other arguments of :func:`collect_demonstrations`.

    >>> data = collect_demonstration_batches(2, episodes=1, max_steps=3, horizon=2, history=2)
    >>> data["batch"].tolist(), data["episode"].tolist()
    ([0, 0, 0, 1, 1, 1], [0, 0, 0, 1, 1, 1])
    """
    if not (isinstance(batches, int) and batches >= 1):
        raise ValueError(f"batches must be an int >= 1, got {batches!r}")
    if not (isinstance(workers, int) and workers >= 1):
        raise ValueError(f"workers must be an int >= 1, got {workers!r}")
    if not (isinstance(first_batch, int) and first_batch >= 0):
        raise ValueError(f"first_batch must be an int >= 0, got {first_batch!r}")
    numbers = range(first_batch, first_batch + batches)
    if workers == 1 or batches == 1:
        parts = [_collect_batch(b, seed, options) for b in numbers]
    else:
        import multiprocessing
        import os
        from concurrent.futures import ProcessPoolExecutor

        from torchrl_auv.envs.processes import end_with_parent

        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(
            min(workers, batches),
            mp_context=context,
            initializer=end_with_parent,  # a killed build leaves none
            initargs=(os.getpid(),),
        ) as pool:
            futures = [pool.submit(_collect_batch, b, seed, options) for b in numbers]
            parts = [future.result() for future in futures]
    episodes = 0
    for part in parts:  # number the episodes across batches
        part["episode"] = part["episode"] + episodes
        episodes = int(part["episode"].max()) + 1
    return torch.cat(parts)


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
