"""Gymnasium ids for the environments.

``gymnasium.make("torchrl_auv/Tracking-v0")`` and
``gymnasium.make("torchrl_auv/DataCollection-v2")``. Importing :mod:`torchrl_auv.envs`
registers the ids once (guarded against double registration). The gymnasium view is a
single, unbatched episode on numpy arrays with float32 ``Box(-inf, inf)`` observations and
``Box(-1, 1)`` actions: 16 and 3 for tracking; for data collection the flat single-agent
layout (``flatten_agents=True``), ``38 N`` and ``3 N``, with the reward summed over the AUVs.
``info`` carries the ``cost`` of the decision (0 at reset) and the episode's metrics so far
(at its end: the episode's metrics), the same keys at reset and at every step. For batched
or multi-agent training use the TorchRL envs directly. An env never seeded draws its seed from
entropy at its first reset (gymnasium's convention; ``_GymView``). Unknown keyword arguments (and
``batch_size``) raise Python's usual ``TypeError: ... got an unexpected keyword argument
'<name>'``, so TorchRL's ``GymEnv("torchrl_auv.envs:<id>")``, which tries ``frameskip`` first
and drops it on exactly that error, builds these ids.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
import torch
from torchrl.envs import EnvBase

from torchrl_auv.envs.data_collection import DataCollectionEnv
from torchrl_auv.envs.render import top_view
from torchrl_auv.envs.tracking import AUVTrackingEnv

__all__ = ["DataCollectionGymEnv", "TrackingGymEnv", "register_gymnasium_ids"]

TRACKING_ID = "torchrl_auv/Tracking-v0"
DATA_COLLECTION_ID = "torchrl_auv/DataCollection-v2"


class _GymView(gymnasium.Env):
    """One unbatched TorchRL env (flat ``observation``/``action`` keys) as a gymnasium env.

    Seeding follows gymnasium's convention: ``reset(seed=s)`` (or a ``seed`` keyword at
    construction) fixes the episodes; an env never seeded draws its seed from the OS's entropy
    at its first reset, so two unseeded envs (e.g. a vector env's workers) differ, and later
    unseeded resets continue its stream. ``render_mode``: ``None`` (no rendering) or one of the
    class's ``metadata["render_modes"]``.
    """

    metadata = {"render_modes": []}  # noqa: RUF012 - gymnasium's convention

    def __init__(self, env: EnvBase, *, seeded: bool, render_mode: str | None = None) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode must be None or one of "
                f"{self.metadata['render_modes']}, got {render_mode!r}"
            )
        self.render_mode = render_mode
        self._seeded = seeded
        self._env = env
        obs_dim = env.observation_spec["observation"].shape[-1]
        act_dim = env.full_action_spec["action"].shape[-1]
        self.observation_space = gymnasium.spaces.Box(-np.inf, np.inf, (obs_dim,), np.float32)
        self.action_space = gymnasium.spaces.Box(-1.0, 1.0, (act_dim,), np.float32)
        self._td = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if seed is not None:
            self._env.set_seed(seed)
        elif not self._seeded:  # gymnasium's np_random, drawn from entropy when never seeded
            self._env.set_seed(int(self.np_random.integers(2**31 - 1)))
        self._seeded = True
        self._td = self._env.reset()
        self._on_step()
        return self._td["observation"].numpy().copy(), self._info(self._td, cost=0.0)

    def _on_step(self) -> None:
        """Called after reset and every step with the new ``self._td`` (for rendering)."""

    @staticmethod
    def _info(td, cost: float) -> dict[str, Any]:
        """The same keys at reset and at every step (Minari's ``record_infos`` needs them):
        the decision's ``cost`` (0 at reset, before any decision) and the episode's
        ``metrics`` so far (at its end: the episode's metrics)."""
        return {"cost": cost, "metrics": {k: float(v) for k, v in td["metrics"].items()}}

    def step(self, action):
        if self._td is None:
            raise RuntimeError("call reset() before step()")
        self._td["action"] = torch.as_tensor(np.asarray(action, dtype=np.float32))
        out = self._env.step(self._td)["next"]
        self._td = out
        self._on_step()
        info = self._info(out, cost=float(out["cost"]))
        terminated, truncated = bool(out["terminated"]), bool(out["truncated"])
        return (
            out["observation"].numpy().copy(),
            float(out["reward"]),
            terminated,
            truncated,
            info,
        )


def _reject_batch_size(cls: type, kwargs: dict[str, Any]) -> None:
    """The gymnasium view is unbatched: ``batch_size`` is not one of its keyword arguments.

    Raised as Python's usual ``TypeError`` (not "got multiple values"), like every other
    unknown keyword, which the wrapped env's own ``__init__`` rejects the same way.
    """
    if "batch_size" in kwargs:
        raise TypeError(
            f"{cls.__name__}.__init__() got an unexpected keyword argument 'batch_size' "
            "(the gymnasium view is a single, unbatched env)"
        )


class TrackingGymEnv(_GymView):
    """:class:`~torchrl_auv.envs.AUVTrackingEnv` behind the gymnasium API (one episode).

    >>> import gymnasium
    >>> env = gymnasium.make("torchrl_auv/Tracking-v0", sea_state="es")
    >>> obs, info = env.reset(seed=0)
    >>> obs.shape, obs.dtype
    ((16,), dtype('float32'))
    """

    def __init__(self, render_mode: str | None = None, **kwargs: Any) -> None:
        _reject_batch_size(TrackingGymEnv, kwargs)
        seeded = kwargs.get("seed") is not None
        env = AUVTrackingEnv(batch_size=[], **kwargs)
        super().__init__(env, seeded=seeded, render_mode=render_mode)


class DataCollectionGymEnv(_GymView):
    """:class:`~torchrl_auv.envs.DataCollectionEnv` (flat layout) behind the gymnasium API.

    ``render_mode="rgb_array"``: ``render()`` returns the top view of the scene
    (:func:`torchrl_auv.envs.render.top_view`, 400 x 400 pixels) with the AUVs' tracks since the
    reset, so gymnasium's ``RecordVideo`` records episodes (``metadata["render_fps"]`` 10
    decisions per second of video).

    >>> import gymnasium
    >>> env = gymnasium.make("torchrl_auv/DataCollection-v2", num_auvs=2)
    >>> obs, info = env.reset(seed=0)
    >>> obs.shape, env.action_space.shape
    ((76,), (6,))
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}  # noqa: RUF012

    def __init__(self, render_mode: str | None = None, **kwargs: Any) -> None:
        if "flatten_agents" in kwargs:
            raise ValueError("flatten_agents is always True in the gymnasium view; do not pass it")
        _reject_batch_size(DataCollectionGymEnv, kwargs)
        seeded = kwargs.get("seed") is not None
        env = DataCollectionEnv(batch_size=[], flatten_agents=True, **kwargs)
        super().__init__(env, seeded=seeded, render_mode=render_mode)
        self._tracks: list[np.ndarray] = []

    def _on_step(self) -> None:
        if self.render_mode is None:
            return
        if int(self._td["sim", "task", "decision"]) == 0:
            self._tracks = []
        self._tracks.append(self._td["sim", "truth", "eta"][:, :2].double().numpy())

    def render(self) -> np.ndarray | None:
        """The top view (``uint8 [400, 400, 3]``) in ``rgb_array`` mode, else ``None``."""
        if self.render_mode is None:
            return None
        if self._td is None:
            raise RuntimeError("call reset() before render()")
        tracks = np.stack(self._tracks)
        return top_view(self._td["sim"], self._env.config.area_m, tracks=tracks)


def register_gymnasium_ids() -> None:
    """Register the gymnasium ids (idempotent)."""
    for env_id, entry_point in (
        (TRACKING_ID, "torchrl_auv.envs.gym:TrackingGymEnv"),
        (DATA_COLLECTION_ID, "torchrl_auv.envs.gym:DataCollectionGymEnv"),
    ):
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point=entry_point)


register_gymnasium_ids()
