"""Gymnasium ids for the environments: ``gymnasium.make("torchrl_auv/Tracking-v0")``.

Importing :mod:`torchrl_auv.envs` registers the ids once (guarded against double registration).
The gymnasium view is a single, unbatched episode on numpy arrays: observations are float32
``Box(-inf, inf, (16,))``, actions ``Box(-1, 1, (3,))``; ``info`` carries the ``cost`` and, at
the end of an episode, the episode metrics. For batched training use the TorchRL env directly.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
import torch

from torchrl_auv.envs.tracking import OBS_DIM, AUVTrackingEnv

__all__ = ["TrackingGymEnv", "register_gymnasium_ids"]

TRACKING_ID = "torchrl_auv/Tracking-v0"


class TrackingGymEnv(gymnasium.Env):
    """:class:`~torchrl_auv.envs.AUVTrackingEnv` behind the gymnasium API (one episode).

    >>> import gymnasium
    >>> env = gymnasium.make("torchrl_auv/Tracking-v0", sea_state="es")
    >>> obs, info = env.reset(seed=0)
    >>> obs.shape, obs.dtype
    ((16,), dtype('float32'))
    """

    metadata = {"render_modes": []}  # noqa: RUF012 - gymnasium's convention

    def __init__(self, **kwargs: Any) -> None:
        self._env = AUVTrackingEnv(batch_size=[], **kwargs)
        self.observation_space = gymnasium.spaces.Box(-np.inf, np.inf, (OBS_DIM,), np.float32)
        self.action_space = gymnasium.spaces.Box(-1.0, 1.0, (3,), np.float32)
        self._td = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if seed is not None:
            self._env.set_seed(seed)
        self._td = self._env.reset()
        return self._td["observation"].numpy().copy(), {}

    def step(self, action):
        if self._td is None:
            raise RuntimeError("call reset() before step()")
        self._td["action"] = torch.as_tensor(np.asarray(action, dtype=np.float32))
        out = self._env.step(self._td)["next"]
        self._td = out
        info: dict[str, Any] = {"cost": float(out["cost"])}
        terminated, truncated = bool(out["terminated"]), bool(out["truncated"])
        if terminated or truncated:
            info["metrics"] = {k: float(v) for k, v in out["metrics"].items()}
        return (
            out["observation"].numpy().copy(),
            float(out["reward"]),
            terminated,
            truncated,
            info,
        )


def register_gymnasium_ids() -> None:
    """Register the gymnasium ids (idempotent)."""
    if TRACKING_ID not in gymnasium.registry:
        gymnasium.register(id=TRACKING_ID, entry_point="torchrl_auv.envs.gym:TrackingGymEnv")


register_gymnasium_ids()
