"""Offline datasets of the gymnasium ids in Minari's format.

:func:`create_minari_dataset` rolls a policy out in a batched TorchRL env, one scene per
episode, and writes the episodes with :func:`minari.create_dataset_from_buffers` (hdf5), so that
``minari.load_dataset(dataset_id)`` and TorchRL's
``MinariExperienceReplay(dataset_id, batch_size, load_from_local_minari=True)`` read them. The
layout is the gymnasium view's (:mod:`torchrl_auv.envs.gym`): flat float32 observations and
actions in ``[-1, 1]``, the reward summed over the AUVs, and per step the infos the view returns
(``cost``, 0 at reset, and the episode's ``metrics`` so far). ``ref_min_score`` and
``ref_max_score`` are the mean returns of random actions and of the scripted expert over
``ref_episodes`` other scenes (seeded ``seed +`` :data:`REFERENCE_SEED_OFFSET`; D4RL's
convention), so ``minari.get_normalized_score`` reads 0 for random and 1 for the expert.

Why batched rollouts and not Minari's ``DataCollector``: the collector steps one gymnasium env
at a time and needs ``jax`` (``minari[create]``); a batch of scenes is one TorchRL rollout.

Policies by name (:data:`POLICIES`): ``expert`` (:class:`~torchrl_auv.envs.ScriptedExpert`),
``random`` (uniform actions), and for data collection ``lazy``
(:class:`~torchrl_auv.envs.LazyExpert`, about half the expert's service: a medium-level
scripted policy) and ``idle`` (:class:`~torchrl_auv.envs.IdlePolicy`). Any policy module
(e.g. a trained actor reading ``"observation"`` and writing ``"action"``) may be passed instead
of a name.

Reading a dataset into a TorchRL replay buffer: :class:`MinariReplay`, TorchRL's
``MinariExperienceReplay`` with one bug fixed. TorchRL 0.14.1 (and its main branch of August 2026)
fills the transitions in memory and then calls ``memmap_like``, which makes a *contentless*
memory-mapped copy: every sample it returns is zeros. :class:`MinariReplay` runs TorchRL's own
conversion with ``memmap_like`` copying the content for that call only;
``tests/envs/test_minari_datasets.py`` checks the upstream class still has the bug, so the
workaround goes when TorchRL fixes it.

Example (a small dataset under ``MINARI_DATASETS_PATH``, default ``~/.minari/datasets``)::

    ds = create_minari_dataset("torchrl_auv/datacollection/expert-v0", episodes=4, max_steps=50)
    ds.total_episodes  # 4
    buffer = MinariReplay("torchrl_auv/datacollection/expert-v0", batch_size=256)
    buffer.sample()["observation"].shape  # torch.Size([256, 76])
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import gymnasium
import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data.datasets import MinariExperienceReplay
from torchrl.envs import EnvBase

from torchrl_auv.envs.data_collection import DataCollectionEnv
from torchrl_auv.envs.experts import ScriptedExpert
from torchrl_auv.envs.gym import DATA_COLLECTION_ID, TRACKING_ID
from torchrl_auv.envs.reference_policies import IdlePolicy, LazyExpert
from torchrl_auv.envs.tracking import AUVTrackingEnv

__all__ = [
    "DATASET_ENVS",
    "POLICIES",
    "REFERENCE_SEED_OFFSET",
    "MinariReplay",
    "create_minari_dataset",
    "episode_buffers",
    "mean_return",
]

#: env name -> (gymnasium id, TorchRL env class)
DATASET_ENVS: dict[str, tuple[str, type[EnvBase]]] = {
    "data_collection": (DATA_COLLECTION_ID, DataCollectionEnv),
    "tracking": (TRACKING_ID, AUVTrackingEnv),
}

#: policy name -> (builder from the env, or None for uniform random actions; envs it acts in)
POLICIES: dict[str, tuple[Callable[[EnvBase], Any] | None, tuple[str, ...]]] = {
    "expert": (ScriptedExpert, ("data_collection", "tracking")),
    "random": (None, ("data_collection", "tracking")),
    "lazy": (LazyExpert, ("data_collection",)),
    "idle": (IdlePolicy, ("data_collection",)),
}

#: the reference scores' scenes are seeded ``seed + REFERENCE_SEED_OFFSET``: far from any
#: dataset's own
REFERENCE_SEED_OFFSET = 1_000_003


def _make_env(env: str, episodes: int, seed: int, options: dict[str, Any]) -> EnvBase:
    if env not in DATASET_ENVS:
        raise ValueError(f"env must be one of {sorted(DATASET_ENVS)}, got {env!r}")
    if not (isinstance(episodes, int) and episodes >= 1):
        raise ValueError(f"episodes must be an int >= 1, got {episodes!r}")
    cls = DATASET_ENVS[env][1]
    layout = {"flatten_agents": True} if cls is DataCollectionEnv else {}
    return cls(batch_size=[episodes], seed=seed, **layout, **options)


def _policy(policy: str | Callable | None, env_name: str, env: EnvBase):
    if not isinstance(policy, str):
        return policy
    if policy not in POLICIES:
        raise ValueError(f"policy must be one of {sorted(POLICIES)} or a module, got {policy!r}")
    build, envs = POLICIES[policy]
    if env_name not in envs:
        raise ValueError(f"policy {policy!r} acts in {list(envs)} only, not in env {env_name!r}")
    return None if build is None else build(env)


def _first_episodes(
    env_name: str, policy, episodes: int, seed: int, options: dict
) -> Iterator[tuple[TensorDictBase, int]]:
    """Each scene's rollout and the length of its first episode: a scene that has ended stops
    stepping, and the rollout stops once every scene has ended (TorchRL's partial steps)."""
    env = _make_env(env_name, episodes, seed, options)
    with torch.no_grad():
        data = env.rollout(env.max_steps, _policy(policy, env_name, env), break_when_all_done=True)
    done = data["next", "done"].reshape(episodes, -1)
    for i in range(episodes):
        yield data[i], int(done[i].nonzero()[0, 0]) + 1


def _infos(data: TensorDictBase, end: int) -> dict[str, Any]:
    """The gymnasium view's infos of one episode's ``end + 1`` observations (reset included)."""
    cost = np.concatenate([[0.0], data["next", "cost"][:end].reshape(end).double().numpy()])
    metrics = {
        key: np.concatenate(
            [
                data["metrics", key][:1].reshape(1).double().numpy(),
                data["next", "metrics", key][:end].reshape(end).double().numpy(),
            ]
        )
        for key in data["metrics"].keys()
    }
    return {"cost": cost, "metrics": metrics}


def episode_buffers(
    env: str = "data_collection",
    policy: str | Callable = "expert",
    *,
    episodes: int,
    seed: int = 0,
    **options: Any,
) -> list:
    """One :class:`minari.data_collector.EpisodeBuffer` per scene of a batched rollout.

    Each episode runs to its first end (terminated, or truncated at the env's ``max_steps``);
    observations hold the reset's and every step's (``T + 1`` rows), actions, rewards and the
    flags ``T`` rows. ``options`` go to the env (``max_steps``, ``sea_state``, ``num_auvs``, ...).
    """
    from minari.data_collector import EpisodeBuffer

    buffers = []
    for i, (ep, end) in enumerate(_first_episodes(env, policy, episodes, seed, options)):
        obs = torch.cat([ep["observation"][:1], ep["next", "observation"][:end]])
        buffers.append(
            EpisodeBuffer(
                id=i,
                observations=obs.float().numpy(),
                actions=ep["action"][:end].float().numpy(),
                rewards=ep["next", "reward"][:end].reshape(end).double().numpy(),
                terminations=ep["next", "terminated"][:end].reshape(end).numpy(),
                truncations=ep["next", "truncated"][:end].reshape(end).numpy(),
                infos=_infos(ep, end),
            )
        )
    return buffers


def mean_return(env: str, policy: str | Callable, *, episodes: int, seed: int, **options) -> float:
    """The mean undiscounted return of ``policy`` over ``episodes`` scenes (each to its end)."""
    returns = [
        float(ep["next", "reward"][:end].double().sum())
        for ep, end in _first_episodes(env, policy, episodes, seed, options)
    ]
    return float(np.mean(returns))


def create_minari_dataset(
    dataset_id: str,
    *,
    env: str = "data_collection",
    policy: str | Callable = "expert",
    episodes: int = 100,
    seed: int = 0,
    ref_episodes: int = 16,
    description: str | None = None,
    author: str | None = None,
    author_email: str | None = None,
    code_permalink: str | None = None,
    **options: Any,
):
    """Roll ``policy`` out on ``episodes`` scenes of ``env`` and write a Minari dataset.

    Args:
        dataset_id: Minari's id, ``(namespace/)(env_name/)name-v<version>``; refused if it exists.
        env: ``"data_collection"`` or ``"tracking"``.
        policy: a name of :data:`POLICIES` or a policy module (``"observation"`` -> ``"action"``).
        episodes: scenes (one episode each), ``seed`` their env seed.
        ref_episodes: scenes of the reference scores (random actions and the expert).
        description, author, author_email, code_permalink: Minari's metadata (it warns where
            one is missing).
        options: env keyword arguments (``max_steps``, ``sea_state``, ...), recorded in the
            dataset's env spec so that ``dataset.recover_environment()`` makes the same env.

    Returns:
        the :class:`minari.MinariDataset`.
    """
    import minari

    if dataset_id in minari.list_local_datasets():
        raise ValueError(f"dataset_id {dataset_id!r} exists locally; choose another id or version")
    buffers = episode_buffers(env, policy, episodes=episodes, seed=seed, **options)
    reference = {"episodes": ref_episodes, "seed": seed + REFERENCE_SEED_OFFSET, **options}
    spec = gymnasium.spec(DATASET_ENVS[env][0])
    spec = gymnasium.envs.registration.EnvSpec(
        id=spec.id, entry_point=spec.entry_point, kwargs=dict(options)
    )
    name = policy if isinstance(policy, str) else type(policy).__name__
    return minari.create_dataset_from_buffers(
        dataset_id=dataset_id,
        buffer=buffers,
        env=spec,
        eval_env=spec,
        algorithm_name=name,
        author=author,
        author_email=author_email,
        code_permalink=code_permalink,
        ref_min_score=mean_return(env, "random", **reference),
        ref_max_score=mean_return(env, "expert", **reference),
        description=description
        or f"{episodes} episodes of the {name} policy in {spec.id} (env seed {seed}, "
        f"options {options}); infos: the decision's cost and the episode's metrics so far",
        data_format="hdf5",
    )


@contextmanager
def _memmap_like_keeps_content() -> Iterator[None]:
    """For the ``with`` block, ``TensorDict.memmap_like(prefix)`` is ``memmap(prefix)``: a
    memory-mapped copy *with* the content (see the module docstring)."""

    def memmap_with_content(self, prefix=None, *args, **kwargs):
        return self.memmap(prefix)

    TensorDict.memmap_like = memmap_with_content
    try:
        yield
    finally:
        del TensorDict.memmap_like  # TensorDictBase's own again


class MinariReplay(MinariExperienceReplay):
    """TorchRL's ``MinariExperienceReplay`` that keeps the data it converts.

    Same arguments as the parent; ``load_from_local_minari`` defaults to True (a dataset made by
    :func:`create_minari_dataset` is local). The transitions are TorchRL's layout:
    ``observation``, ``action``, ``("next", "observation" | "reward" | "terminated" |
    "truncated" | "done")``, ``episode`` and the infos under ``info`` / ``("next", "info")``.
    """

    def __init__(self, dataset_id: str, batch_size: int, **kwargs: Any) -> None:
        kwargs.setdefault("load_from_local_minari", True)
        super().__init__(dataset_id, batch_size, **kwargs)

    def _download_and_preproc(self):
        with _memmap_like_keeps_content():
            return super()._download_and_preproc()
