"""Scripted experts: simple TensorDictModule policies that read only the observation.

For :class:`~torchrl_auv.envs.AUVTrackingEnv` the expert moves the setpoints onto the
reference; for :class:`~torchrl_auv.envs.DataCollectionEnv` it goes to the assigned target at
cruise rpm, descends to its depth and steers away from the nearest other AUV
(:func:`torchrl_auv.iout.expert_setpoints`), all read back from the observation.
"""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase
from torchrl.envs import EnvBase

from torchrl_auv import iout
from torchrl_auv.control import wrap_angle
from torchrl_auv.envs.data_collection import AGENT_OBSERVATION_FEATURES, DataCollectionEnv
from torchrl_auv.envs.tracking import DEPTH_STEP, HEADING_STEP, RPM_SCALE, AUVTrackingEnv
from torchrl_auv.physics.remus100 import DEFAULT_PARAMS

__all__ = ["ScriptedExpert"]

# steady surge speed at full rpm from the model (m/s); rpm ~ proportional to speed
_FULL_SPEED = 2.5536


class ScriptedExpert(TensorDictModuleBase):
    r"""A scripted expert policy for either env; it reads only the observation.

    Key contract: reads the env's observation key and writes its action key, in [-1, 1]:
    ``"observation"`` -> ``"action"`` for :class:`~torchrl_auv.envs.AUVTrackingEnv` and
    flat :class:`~torchrl_auv.envs.DataCollectionEnv`, ``("agents", "observation")`` ->
    ``("agents", "action")`` for the multi-agent layout.

    * Tracking: moves the depth and heading setpoints onto the reference as fast as the
      action bounds allow and sets the propeller speed for the reference speed,
      :math:`n = 1525\,u_{ref}/2.55`.
    * Data collection: :func:`torchrl_auv.iout.expert_setpoints` (go to the target at cruise
      rpm, slow down near it, travel ``standoff_m`` above it and the seabed, steer away from
      the nearest other AUV, approach from downstream in a current), turned into setpoint
      changes. While an AUV is in service the env overrides its action (station keeping).

    Args:
        env: the env the expert acts in (its layout and task configuration).
        config: the data-collection expert's parameters (:class:`~torchrl_auv.iout.ExpertConfig`).

    Examples:
        >>> env = AUVTrackingEnv(batch_size=[2], seed=0)
        >>> td = env.rollout(3, ScriptedExpert(env))
        >>> bool((td["action"].abs() <= 1).all())
        True
        >>> env = DataCollectionEnv(batch_size=[2], seed=0)
        >>> td = env.rollout(3, ScriptedExpert(env))
        >>> td["agents", "action"].shape
        torch.Size([2, 3, 2, 3])
    """

    def __init__(self, env: EnvBase, config: iout.ExpertConfig | None = None) -> None:
        super().__init__()
        if isinstance(env, AUVTrackingEnv):
            self.in_keys, self.out_keys = ["observation"], ["action"]
            self._task = None
        elif isinstance(env, DataCollectionEnv):
            self.in_keys, self.out_keys = [env.observation_key], [env.agent_action_key]
            self._task = env.config
            self._num_auvs = env.num_auvs
            self._flat = env.flatten_agents
        else:
            raise ValueError(
                f"env must be an AUVTrackingEnv or a DataCollectionEnv, got {type(env).__name__}"
            )
        self.config = iout.ExpertConfig() if config is None else config

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        obs = tensordict[self.in_keys[0]]
        if self._task is None:
            action = _tracking_action(obs)
        else:
            if self._flat:
                obs = obs.unflatten(-1, (self._num_auvs, -1))
            action = self._collection_action(obs)
            if self._flat:
                action = action.flatten(-2)
        tensordict.set(self.out_keys[0], action.to(obs.dtype))
        return tensordict

    def _collection_action(self, obs: torch.Tensor) -> torch.Tensor:
        """Data collection: actions ``[*B, N, 3]`` from observations ``[*B, N, 38]``."""
        return _collection_action(obs, self._task, self.config)


def _tracking_action(obs: torch.Tensor) -> torch.Tensor:
    depth_gap = 10.0 * (obs[..., 0] - obs[..., 12])  # z_ref - z_sp (m)
    heading_gap = torch.atan2(obs[..., 1], obs[..., 2]) - torch.atan2(obs[..., 13], obs[..., 14])
    heading_gap = torch.atan2(torch.sin(heading_gap), torch.cos(heading_gap))
    speed_ref = obs[..., 3] + obs[..., 4]
    rpm = (DEFAULT_PARAMS.n_max * speed_ref / _FULL_SPEED).clamp(0.0, DEFAULT_PARAMS.n_max)
    return torch.stack(
        (depth_gap / DEPTH_STEP, heading_gap / HEADING_STEP, rpm / RPM_SCALE - 3.0), -1
    ).clamp(-1.0, 1.0)


_FEATURE = {name: i for i, name in enumerate(AGENT_OBSERVATION_FEATURES)}


def _collection_action(
    obs: torch.Tensor, task: iout.IoUTConfig, config: iout.ExpertConfig
) -> torch.Tensor:
    """Actions ``[*B, N, 3]`` from per-AUV observations (env card layout, read by name)."""
    f = _FEATURE

    def read(name: str) -> torch.Tensor:
        return obs[..., f[name]]

    def span(first: str, count: int) -> torch.Tensor:
        return obs[..., f[first] : f[first] + count]

    h_max = task.seabed_depth_range_m[1]
    scale = obs.new_tensor([task.area_m[0], task.area_m[1], h_max])
    depth = read("depth") * h_max
    heading = torch.atan2(read("sin_heading"), read("cos_heading"))
    own = torch.stack((torch.zeros_like(depth), torch.zeros_like(depth), depth), -1)
    pose = torch.cat([own, torch.zeros_like(own[..., :2]), heading[..., None]], -1)
    target = own + span("target_offset_x", 3) * scale
    alone = read("nearest_auv_distance") >= 1.0  # beyond 10 collision distances (or none)
    nearest = own + span("nearest_auv_offset_x", 3) * task.area_diagonal_m
    nearest = torch.where(alone[..., None], own + 1e4, nearest)
    depth_d, heading_d, rpm = iout.expert_setpoints(
        pose,
        target,
        nearest[..., None, :],
        config,
        has_target=read("has_target") > 0.5,
        seabed_below=(read("altitude") + read("depth")) * h_max,
        current=span("current_north", 2),
        edges=span("edge_x_low", 4) * obs.new_tensor(task.area_m).repeat_interleave(2),
    )
    return setpoint_action(obs, task, depth_d, heading_d, rpm)


def setpoint_action(
    obs: torch.Tensor,
    task: iout.IoUTConfig,
    depth: torch.Tensor,
    heading: torch.Tensor,
    rpm: torch.Tensor,
) -> torch.Tensor:
    """The data-collection action ``[*B, N, 3]`` in [-1, 1] that moves each AUV's setpoints
    toward the wanted ``depth`` (m), ``heading`` (rad) and ``rpm`` (each ``[*B, N]``), read
    against the setpoints the observation shows (the env card's action table)."""
    f = _FEATURE
    h_max = task.seabed_depth_range_m[1]
    own_depth = obs[..., f["depth"]] * h_max
    own_heading = torch.atan2(obs[..., f["sin_heading"]], obs[..., f["cos_heading"]])
    depth_sp = own_depth + 10.0 * obs[..., f["depth_setpoint_offset"]]
    heading_sp = own_heading + torch.atan2(
        obs[..., f["sin_heading_setpoint_offset"]], obs[..., f["cos_heading_setpoint_offset"]]
    )
    return torch.stack(
        (
            (depth - depth_sp) / DEPTH_STEP,
            wrap_angle(heading - heading_sp) / HEADING_STEP,
            rpm / RPM_SCALE - 3.0,
        ),
        -1,
    ).clamp(-1.0, 1.0)
