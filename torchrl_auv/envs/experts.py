"""Scripted experts: simple TensorDictModule policies that read only the observation."""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase
from torchrl.envs import EnvBase

from torchrl_auv.envs.tracking import DEPTH_STEP, HEADING_STEP, RPM_SCALE, AUVTrackingEnv
from torchrl_auv.physics.remus100 import DEFAULT_PARAMS

__all__ = ["ScriptedExpert"]

# steady surge speed at full rpm from the model (m/s); rpm ~ proportional to speed
_FULL_SPEED = 2.5536


class ScriptedExpert(TensorDictModuleBase):
    """A scripted expert policy for :class:`~torchrl_auv.envs.AUVTrackingEnv`.

    Key contract: reads ``"observation"`` and writes ``"action"`` in [-1, 1]. It moves the depth
    and heading setpoints onto the reference as fast as the action bounds allow and sets the
    propeller speed for the reference speed, :math:`n = 1525\\,u_{ref}/2.55`.

    Examples:
        >>> env = AUVTrackingEnv(batch_size=[2], seed=0)
        >>> td = env.rollout(3, ScriptedExpert(env))
        >>> bool((td["action"].abs() <= 1).all())
        True
    """

    def __init__(self, env: EnvBase) -> None:
        super().__init__()
        self.in_keys = ["observation"]
        self.out_keys = ["action"]
        if not isinstance(env, AUVTrackingEnv):
            raise ValueError(f"env must be an AUVTrackingEnv, got {type(env).__name__}")

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        obs = tensordict["observation"]
        depth_gap = 10.0 * (obs[..., 0] - obs[..., 12])  # z_ref - z_sp (m)
        heading_gap = torch.atan2(obs[..., 1], obs[..., 2]) - torch.atan2(
            obs[..., 13], obs[..., 14]
        )
        heading_gap = torch.atan2(torch.sin(heading_gap), torch.cos(heading_gap))
        speed_ref = obs[..., 3] + obs[..., 4]
        rpm = (DEFAULT_PARAMS.n_max * speed_ref / _FULL_SPEED).clamp(0.0, DEFAULT_PARAMS.n_max)
        action = torch.stack(
            (depth_gap / DEPTH_STEP, heading_gap / HEADING_STEP, rpm / RPM_SCALE - 3.0), -1
        ).clamp(-1.0, 1.0)
        tensordict.set("action", action.to(obs.dtype))
        return tensordict
