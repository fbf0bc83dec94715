"""Reference policies of the data-collection task beside the scripted expert: idle and lazy.

They fix the two ends of what a learner can do without serving every node it could: an
:class:`IdlePolicy` serves none (it stays safe inside the area, so what it pays is the cost of
doing nothing for the mission), a :class:`LazyExpert` serves about half of what the expert
serves. Both are built like :class:`~torchrl_auv.envs.ScriptedExpert` (``IdlePolicy(env)``,
``LazyExpert(env)``), read only the observation, and act in the multi-agent and the flat
layout.
"""

from __future__ import annotations

import torch
from torchrl.envs import EnvBase

from torchrl_auv import iout
from torchrl_auv.envs.data_collection import AGENT_OBSERVATION_FEATURES, DataCollectionEnv
from torchrl_auv.envs.experts import ScriptedExpert, setpoint_action

__all__ = ["IdlePolicy", "LazyExpert"]

_F = {name: i for i, name in enumerate(AGENT_OBSERVATION_FEATURES)}
_STILL_MPS = 0.1  # below this current estimate the patrol legs run east-west


def _collection_env(env: EnvBase, name: str) -> DataCollectionEnv:
    base = getattr(env, "base_env", env)
    if not isinstance(base, DataCollectionEnv):
        raise ValueError(
            f"env must be a DataCollectionEnv (or wrap one) for {name}, got {type(base).__name__}"
        )
    return base


class IdlePolicy(ScriptedExpert):
    r"""Patrols inside the area at a safe depth and never approaches a node (the task's zero).

    Each AUV runs back and forth on its own lane across the current (east-west in still
    water), crabbing into the current so that it holds its lane, and turns back when the edge
    ahead is ``turn_m`` away; it reverses by turning into the current, and uses its bow as
    the memory of which way it is going (no state). AUV :math:`j` of :math:`N` keeps the lane
    ``(j - (N - 1) / 2) lane_spacing_m`` from the area's centre along the current and the
    depth ``depths_m[0] + j (depths_m[1] - depths_m[0]) / (N - 1)``: different depths, so the
    AUVs cannot collide while they settle on their lanes, and all shallower than the
    shallowest seabed minus the service radius, so no node ever comes within it. It cruises
    at ``rpm`` (the expert's cruise speed by default: the idle AUV spends the expert's energy
    in transit, and what separates their costs is the mission).

    Args:
        env: the :class:`~torchrl_auv.envs.DataCollectionEnv` it acts in (or a wrapper of one).
        depths_m: the shallowest and deepest patrol depth (m).
        lane_spacing_m: distance between neighbouring lanes, along the current (m).
        turn_m: distance to the edge ahead at which an AUV turns back (m).
        rpm: propeller speed (rpm, 760-1520).
        lane_gain: heading toward the lane per metre off it (1/m, a lookahead of its inverse).

    Examples:
        >>> env = DataCollectionEnv(batch_size=[2], seed=0)
        >>> td = env.rollout(5, IdlePolicy(env))
        >>> int(td["next", "metrics", "ssn"][:, -1].sum())
        0
    """

    def __init__(
        self,
        env: EnvBase,
        depths_m: tuple[float, float] = (8.0, 16.0),
        lane_spacing_m: float = 60.0,
        turn_m: float = 60.0,
        rpm: float = 1200.0,
        lane_gain: float = 1.0 / 30.0,
    ) -> None:
        base = _collection_env(env, "IdlePolicy")
        super().__init__(base)
        cfg, n = base.config, base.num_auvs
        deepest = cfg.seabed_depth_range_m[0] - cfg.service_radius_m
        low, high = (float(v) for v in depths_m)
        if not cfg.clearance_m < low <= high < deepest:
            raise ValueError(
                f"depths_m must lie in ({cfg.clearance_m}, {deepest}) m (below the "
                f"surface clearance, out of every node's service radius) with "
                f"depths_m[0] <= depths_m[1], got {depths_m}"
            )
        half = min(cfg.area_m) / 2.0
        if not 0.0 <= lane_spacing_m * (n - 1) / 2 < half:
            raise ValueError(
                f"lane_spacing_m must be >= 0 and keep {n} lanes inside the area "
                f"(< {2 * half / max(n - 1, 1)} m), got {lane_spacing_m}"
            )
        if not 0.0 < turn_m < half:
            raise ValueError(f"turn_m must be in (0, {half}) m, got {turn_m}")
        if not 760.0 <= rpm <= 1520.0:
            raise ValueError(f"rpm must be in [760, 1520] (the action's range), got {rpm}")
        if not lane_gain >= 0:
            raise ValueError(f"lane_gain must be >= 0 (1/m), got {lane_gain}")
        j = torch.arange(n, dtype=torch.float32)
        self.register_buffer("lanes", (j - (n - 1) / 2) * lane_spacing_m)  # [N] m
        self.register_buffer("depths", low + j * (high - low) / max(n - 1, 1))  # [N] m
        self.turn_m, self.rpm, self.lane_gain = float(turn_m), float(rpm), float(lane_gain)
        # steady speed through the water at `rpm` (m/s; 1525 rpm give 2.5536 m/s)
        self.speed = 2.5536 * self.rpm / 1525.0

    def _collection_action(self, obs: torch.Tensor) -> torch.Tensor:
        task = self._task
        size = obs.new_tensor(task.area_m)
        here = torch.stack((obs[..., _F["edge_x_low"]], obs[..., _F["edge_y_low"]]), -1) * size
        heading = torch.atan2(obs[..., _F["sin_heading"]], obs[..., _F["cos_heading"]])
        bow = torch.stack((torch.cos(heading), torch.sin(heading)), -1)
        current = obs[..., _F["current_north"] : _F["current_north"] + 2]
        flow = torch.linalg.vector_norm(current, dim=-1, keepdim=True)
        still = flow < _STILL_MPS
        down = torch.where(still, obs.new_tensor([1.0, 0.0]), current / flow.clamp_min(1e-6))
        across = torch.stack((-down[..., 1], down[..., 0]), -1)  # legs run across the flow
        leg = torch.where((bow * across).sum(-1, keepdim=True) >= 0, across, -across)
        leg = torch.where(_ahead_of_edge(here, leg, size) < self.turn_m, -leg, leg)
        off_lane = self.lanes - ((here - size / 2) * down).sum(-1)  # m, along the flow
        ground = leg + self.lane_gain * off_lane[..., None] * down
        ground = ground / torch.linalg.vector_norm(ground, dim=-1, keepdim=True)
        water = self.speed * ground - current  # crab into the current
        heading_d = torch.atan2(water[..., 1], water[..., 0])
        depth = self.depths.to(obs.dtype).expand_as(heading_d)
        return setpoint_action(obs, task, depth, heading_d, torch.full_like(depth, self.rpm))


def _ahead_of_edge(here: torch.Tensor, direction: torch.Tensor, size: torch.Tensor) -> torch.Tensor:
    """Distance (m, ``[*B, N, 1]``) from ``here`` along the unit ``direction`` to the area's
    boundary."""
    to_high = (size - here) / direction.clamp_min(1e-6)
    to_low = here / (-direction).clamp_min(1e-6)
    along = torch.where(direction > 0, to_high, to_low)
    return along.amin(-1, keepdim=True)


class LazyExpert(ScriptedExpert):
    """The scripted expert that works ``duty`` of the time: each period of ``period``
    decisions starts with ``(1 - duty) * period`` decisions of rest, as :class:`IdlePolicy`,
    and ends with the rest as :class:`~torchrl_auv.envs.ScriptedExpert` (it reads the decision
    from the observation's ``time_fraction``). A service the env holds it in runs to its end
    either way (station keeping overrides the action), so the lazy expert serves fewer nodes
    rather than shorter services. It rests first so that it is lazy from the start too, where a
    discounted cost looks most.

    Args:
        env: the :class:`~torchrl_auv.envs.DataCollectionEnv` it acts in (or a wrapper of one).
        period: decisions per work-rest cycle.
        duty: the working fraction of each cycle, in (0, 1).
        config: the expert's parameters.

    Examples:
        >>> env = DataCollectionEnv(batch_size=[2], seed=0)
        >>> td = env.rollout(3, LazyExpert(env))
        >>> td["agents", "action"].shape
        torch.Size([2, 3, 2, 3])
    """

    def __init__(
        self,
        env: EnvBase,
        period: int = 200,
        duty: float = 0.5,
        config: iout.ExpertConfig | None = None,
    ) -> None:
        base = _collection_env(env, "LazyExpert")
        super().__init__(base, config)
        if isinstance(period, bool) or not isinstance(period, int) or period < 2:
            raise ValueError(f"period must be an int >= 2 (decisions), got {period!r}")
        if not 0.0 < duty < 1.0:
            raise ValueError(f"duty must be in (0, 1), got {duty}")
        self.period, self.duty, self.max_steps = period, float(duty), base.max_steps
        self.idle = IdlePolicy(base)

    def _collection_action(self, obs: torch.Tensor) -> torch.Tensor:
        decision = torch.round(obs[..., _F["time_fraction"]] * self.max_steps)
        working = torch.remainder(decision, self.period) >= (1.0 - self.duty) * self.period
        work = super()._collection_action(obs)
        rest = self.idle._collection_action(obs)
        return torch.where(working[..., None], work, rest)
