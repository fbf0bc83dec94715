"""The reference policies of every evaluation, by name: the scripted expert, the lazy expert,
the idle policy, random actions and the straight exit.

Examples:
    >>> from torchrl_auv.envs import DataCollectionEnv
    >>> env = DataCollectionEnv(batch_size=[1], seed=0, max_steps=5)
    >>> type(make_policy("expert", env)).__name__, make_policy("random", env)
    ('ScriptedExpert', None)
    >>> sorted(reference_policies())
    ['expert', 'idle', 'random']
"""

from __future__ import annotations

from collections.abc import Callable

import torch
from tensordict import TensorDictBase

from torchrl_auv.envs import DataCollectionEnv, IdlePolicy, LazyExpert, ScriptedExpert

__all__ = [
    "POLICIES",
    "exit_policy",
    "expert_policy",
    "idle_policy",
    "lazy_policy",
    "make_policy",
    "random_policy",
    "reference_policies",
]

POLICIES = ("expert", "lazy", "idle", "random", "exit")


def exit_policy(env: DataCollectionEnv) -> Callable[[TensorDictBase], TensorDictBase]:
    """Straight out at full speed: hold depth and heading, 1520 rpm (the cheapest way to end an
    episode early, which the termination cost must make expensive)."""

    def act(td: TensorDictBase) -> TensorDictBase:
        shape = (*td.batch_size, env.num_auvs, 3)
        action = torch.zeros(shape, device=env.device)
        action[..., 2] = 1.0
        td.set(env.agent_action_key, action.flatten(-2) if env.flatten_agents else action)
        return td

    return act


def make_policy(name: str, env: DataCollectionEnv):
    """A reference policy by name (:data:`POLICIES`): ``expert``
    (:class:`~torchrl_auv.envs.ScriptedExpert`), ``lazy`` (:class:`~torchrl_auv.envs.LazyExpert`),
    ``idle`` (:class:`~torchrl_auv.envs.IdlePolicy`), ``random`` (uniform actions; ``None`` for
    ``env.rollout``) or ``exit`` (:func:`exit_policy`)."""
    if name not in POLICIES:
        raise ValueError(f"policy must be one of {POLICIES}, got {name!r}")
    return {
        "expert": expert_policy,
        "lazy": lazy_policy,
        "idle": idle_policy,
        "random": random_policy,
        "exit": exit_policy,
    }[name](env)


def expert_policy(env: DataCollectionEnv) -> ScriptedExpert:
    """The scripted expert of ``env`` (of its base env when wrapped)."""
    return ScriptedExpert(getattr(env, "base_env", env))


def lazy_policy(env: DataCollectionEnv) -> LazyExpert:
    """The lazy expert of ``env`` (half the time at rest, :class:`~torchrl_auv.envs.LazyExpert`)."""
    return LazyExpert(env)


def idle_policy(env: DataCollectionEnv) -> IdlePolicy:
    """The idle policy of ``env`` (safe, serves no node, :class:`~torchrl_auv.envs.IdlePolicy`)."""
    return IdlePolicy(env)


def random_policy(env: DataCollectionEnv) -> None:
    """Uniform random actions (``None``: ``env.rollout``'s own)."""
    return None


def reference_policies() -> dict[str, Callable[[DataCollectionEnv], object]]:
    """The reference rows of every evaluation: the scripted expert, the idle policy (the
    cost of serving nothing) and random actions."""
    return {"expert": expert_policy, "idle": idle_policy, "random": random_policy}
