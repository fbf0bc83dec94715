"""The envs a recipe builds, all from ``cfg.env``: training scenes, worker factories, held-out
evaluation scenes.

``cfg.env.history`` (0 when absent) is the length of the state-action history the proposer
conditions on: with it > 0 every env here is wrapped in
:class:`~torchrl_auv.envs.StateActionHistory` (the diffusion presets set it to
``${proposer.history}``, so the first stage and the envs cannot disagree).

Examples:
    >>> from omegaconf import OmegaConf
    >>> cfg = OmegaConf.create({"seed": 0, "device": "cpu", "env": {"sea_state": "ideal",
    ...     "num_envs": 2, "controller": "pid", "rate_model": "shannon", "max_steps": 5,
    ...     "history": 3}})
    >>> env = env_from_config(cfg)
    >>> env.reset()["agents", "history", "observation"].shape
    torch.Size([2, 2, 3, 38])
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from functools import partial

import torch
from torchrl.envs import TransformedEnv

from torchrl_auv.envs import DataCollectionEnv, StateActionHistory
from torchrl_auv.training.keys import ACTION, OBSERVATION

__all__ = [
    "env_factory",
    "env_from_config",
    "env_history",
    "held_out_env",
    "make_env",
    "make_history_env",
]


def make_env(
    sea_state: str = "ideal",
    *,
    seed: int,
    num_envs: int = 4,
    controller: str = "s_surface",
    rate_model: str = "shannon",
    max_steps: int | None = None,
    device: str | torch.device = "cpu",
    compile_physics: bool = False,
) -> DataCollectionEnv:
    """A batch of ``num_envs`` data-collection scenes on the ``("agents", ...)`` layout.

    Args:
        sea_state: ``ideal``, ``es`` or ``ves``.
        seed: seeds the env's generator (scenes, noise).
        num_envs: scenes simulated in one batch.
        controller: low-level controller, ``s_surface``, ``pid`` or ``smc``.
        rate_model: ``shannon`` or ``paper`` link rate.
        max_steps: decisions per episode (default the env's, 1000).
        device: where the env's tensors live.
        compile_physics: run the decision through ``torch.compile`` (the 20 Hz physics and
            the code around it; minutes of compilation per batch shape on a fresh machine,
            seconds from the on-disk cache; then about 10x faster at batch 1, see
            ``benchmarks/bench_speed.py``).
    """
    if num_envs < 1:
        raise ValueError(f"num_envs must be >= 1, got {num_envs}")
    return DataCollectionEnv(
        batch_size=[num_envs],
        sea_state=sea_state,
        controller=controller,
        rate_model=rate_model,
        seed=seed,
        max_steps=max_steps,
        device=device,
        compile_physics=compile_physics,
    )


def make_history_env(sea_state: str = "ideal", *, history: int = 10, **env_kwargs):
    """:func:`make_env` with :class:`~torchrl_auv.envs.StateActionHistory` (the last
    ``history`` observation-action pairs per AUV, the proposer's conditioning)."""
    env = make_env(sea_state, **env_kwargs)
    return TransformedEnv(
        env, StateActionHistory(history, observation_key=OBSERVATION, action_key=ACTION)
    )


def _scene_env(sea_state: str, history: int, **kwargs):
    """:func:`make_env`, wrapped with a ``history``-long state-action history when > 0."""
    if history:
        return make_history_env(sea_state, history=history, **kwargs)
    return make_env(sea_state, **kwargs)


def env_history(cfg: Mapping) -> int:
    """``cfg.env.history``: the state-action history length of the run's envs (0: none)."""
    history = cfg["env"].get("history", 0) or 0
    if isinstance(history, bool) or not isinstance(history, int) or history < 0:
        raise ValueError(f"env.history must be an int >= 0, got {history!r}")
    return history


def env_factory(cfg: Mapping) -> partial:
    """A picklable factory of the training env of ``cfg.env`` (``cfg.device``), called with
    ``seed=``: what worker processes and Ray actors build their envs with."""
    env = cfg["env"]
    return partial(
        _scene_env,
        env["sea_state"],
        env_history(cfg),
        num_envs=env["num_envs"],
        controller=env["controller"],
        rate_model=env["rate_model"],
        max_steps=env["max_steps"],
        device=cfg["device"],
        compile_physics=bool(env.get("compile_physics", False)),
    )


def env_from_config(cfg: Mapping):
    """The training env of ``cfg.env`` (seed ``cfg.seed``, ``cfg.device``)."""
    return env_factory(cfg)(seed=cfg["seed"])


def held_out_env(cfg: Mapping, num_envs: int, steps: int) -> Callable:
    """``(sea_state, seed) -> env`` for :func:`~torchrl_auv.training.evaluate`: ``num_envs``
    scenes of ``steps`` decisions with the run's controller, rate model, history,
    ``env.compile_physics`` (the same numbers as eager, about 3x faster once compiled) and
    ``cfg.device`` (where the run's policies live; ``cpu`` when absent); a picklable
    ``functools.partial``, for evaluation workers."""
    env = cfg["env"]
    return partial(
        _held_out_scene,
        history=env_history(cfg),
        num_envs=num_envs,
        max_steps=steps,
        controller=env["controller"],
        device=cfg.get("device", "cpu"),
        rate_model=env["rate_model"],
        compile_physics=bool(env.get("compile_physics", False)),
    )


def _held_out_scene(sea_state: str, seed: int, *, history: int, **kwargs):
    """:func:`held_out_env`'s factory (module level: picklable for evaluation workers)."""
    return _scene_env(sea_state, history, seed=seed, **kwargs)
