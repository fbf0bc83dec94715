"""Where an env's simulation runs: on the CPU, whatever the env's ``device``.

The envs draw every random number from one CPU ``torch.Generator`` (scenes, noise, arrivals)
and step a small batch of vehicles through many short 20 Hz physics steps: work that is
bound by the number of operations, not their size, and that a GPU would not speed up at the
batch sizes used here (8 scenes x 2 AUVs). An env made with ``device="cuda"`` therefore keeps
its simulation on the CPU and lives on the GPU at its boundary: its reset and step outputs
(observations, rewards, the carried simulator state) are on ``device``, where the policy and
the learner are: :func:`on_env_device` moves a reset's output there and :func:`step_on_cpu`
brings a step's inputs to the CPU and its outputs back. A CUDA env thus sees the same scenes
as a CPU env of the same seed (``tests/test_cuda.py``).

Examples:
    >>> from torchrl_auv.envs import DataCollectionEnv
    >>> env = DataCollectionEnv(batch_size=[2], seed=0, device="cpu")
    >>> env.rollout(2)["next", "agents", "cost"].device
    device(type='cpu')
"""

from __future__ import annotations

from collections.abc import Callable

import torch
from tensordict import TensorDictBase
from torchrl.envs import EnvBase

__all__ = ["SIMULATION_DEVICE", "on_env_device", "step_on_cpu"]

#: Where the envs' simulation runs (the module docstring says why).
SIMULATION_DEVICE = torch.device("cpu")


def _on_cpu(env: EnvBase) -> bool:
    return env.device is None or torch.device(env.device) == SIMULATION_DEVICE


def on_env_device(env: EnvBase, tensordict: TensorDictBase) -> TensorDictBase:
    """``tensordict`` (simulated on the CPU) on ``env.device``; itself for a CPU env."""
    return tensordict if _on_cpu(env) else tensordict.to(env.device)


def step_on_cpu(
    env: EnvBase,
    tensordict: TensorDictBase,
    simulate: Callable[[TensorDictBase], TensorDictBase],
) -> TensorDictBase:
    """``simulate(tensordict)`` on the CPU for an env on another device: the env's state and
    action entries of ``tensordict`` go to the CPU, the step's output comes back to
    ``env.device``. A CPU env (or one without a device) calls ``simulate`` directly."""
    if _on_cpu(env):
        return simulate(tensordict)
    keys = [*env.state_spec.keys(True, True), *env.action_keys]
    inputs = tensordict.select(*keys, strict=False).to(SIMULATION_DEVICE)
    return simulate(inputs).to(env.device)
