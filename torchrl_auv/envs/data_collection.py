"""``DataCollectionEnv``: a fleet of REMUS-100s collecting data from underwater sensor nodes.

The paper's evaluation task (``shared/spec/data_collection.md``). The env wires the layers
below together and stays thin: the sensor network, target rule, service, link, metrics and
cost live in :mod:`torchrl_auv.iout`; the vehicles, controllers, sea and Kalman filter in
:class:`~torchrl_auv.envs.vehicles.VehicleStack`.
"""

from __future__ import annotations

import dataclasses
import math

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from torchrl_auv import iout
from torchrl_auv.envs.specs import controller_from_name, unbounded_spec_like
from torchrl_auv.envs.tracking import DEPTH_STEP, HEADING_STEP, RPM_SCALE
from torchrl_auv.envs.vehicles import (
    TRACKING_SUMS,
    VehicleStack,
    add_tracking_sums,
    tracking_errors,
)
from torchrl_auv.estimation import usbl_fix
from torchrl_auv.physics import ocean
from torchrl_auv.physics.limits import diverged

__all__ = ["AGENT_OBSERVATION_FEATURES", "VEHICLE_FEATURES", "DataCollectionEnv"]

#: vehicle features appended to the task features (:data:`torchrl_auv.iout.OBSERVATION_FEATURES`)
VEHICLE_FEATURES = (
    "u",
    "v",
    "w",
    "p",
    "q",
    "r",
    "roll",
    "pitch",
    "sin_heading",
    "cos_heading",
    "depth_setpoint_offset",
    "sin_heading_setpoint_offset",
    "cos_heading_setpoint_offset",
    "rpm_setpoint",
)
#: names of the per-AUV observation entries, in order
AGENT_OBSERVATION_FEATURES = iout.OBSERVATION_FEATURES + VEHICLE_FEATURES

_HOVER_RPM = 760.0  # the action's (and the vehicle's) slowest propeller speed
_LOITER_LEAD = 0.5  # rad: while in service the heading setpoint leads the compass by this
_START_RPM = 1200.0
_EC_SPEED_LIMIT = 3.0  # m/s; the EC model's efficiency polynomial reaches 0 at 3.25 m/s
_START_SPEED = 1.5  # m/s
_ASV_SPEED = 2.0  # m/s, the ASV's top speed while it follows the fleet


class DataCollectionEnv(EnvBase):
    r"""Multi-AUV data collection from underwater sensor nodes (env card).

    **Description.** ``num_auvs`` REMUS-100s (default 2) collect data from ``num_sensors``
    (default 60) sensor nodes on a random seabed, 39-58 m deep, in a 200 m x 200 m area. Each
    node fills its buffer with Poisson data (rate 4, 6, 9 or 12 packets per decision, capacity
    5000). The env assigns every AUV the unserved node of highest priority
    :math:`\lambda_i b_i / C_{max} - 0.05 d_i` (two AUVs never share one); within 18 m (3-D)
    service starts and the AUV hovers for :math:`Q (b_i/C_{max}) / R(d)` s (Q = 2 Mbit,
    :math:`R` the acoustic link rate, ``rate_model`` "shannon" or "paper"), after which the
    node's buffer is empty and the node counts as served (once per episode). An ASV at the
    surface follows the fleet's centroid (at most 2 m/s) and gives each AUV a USBL fix per
    decision; the AUVs navigate on a Kalman filter fusing USBL, DVL, depth and compass.
    Physics and the low-level controller run at 20 Hz, the agent decides at 1 Hz.

    *Hovering.* The REMUS-100 cannot hover (its propeller does not run below 760 rpm here), so
    while an AUV is in service the env overrides its action: the propeller runs at 760 rpm,
    the heading setpoint leads the compass heading by 0.5 rad (a steady turn at full rudder,
    toward the side of the area's centre, chosen when the service starts) and the depth
    setpoint is held. The AUV loiters on a circle of about 17 m radius near the node; the link
    rate is frozen at the start of the service (``torchrl_auv.iout.service``).

    **Action** ``("agents", "action")`` ``[*B, N, 3]`` in [-1, 1] (``"action"`` ``[*B, 3 N]``
    with ``flatten_agents=True``), per AUV:

    ====  ==============================  ===================================
    idx   meaning                         effect
    ====  ==============================  ===================================
    0     depth setpoint change           ``z_sp += 0.8 a0`` m (kept in [0, seabed])
    1     heading setpoint change         ``psi_sp += 0.15 a1`` rad
    2     propeller speed                 ``n_sp = 380 (a2 + 3)`` rpm (760-1520)
    ====  ==============================  ===================================

    **Observation** ``("agents", "observation")`` ``[*B, N, 31]`` float32 (``"observation"``
    ``[*B, 31 N]`` flat), computed from the Kalman estimate, never the true pose. Entries 0-16
    are the task features of :mod:`torchrl_auv.iout.observation` (target offset and distance,
    target fill and rate, has-target, in-service, hover time left, altitude, depth, nearest
    AUV offset and distance, served fraction, time fraction); entries 17-30 are
    :data:`VEHICLE_FEATURES`: body velocity ``u^, v^, w^`` (m/s), rates ``p, q, r`` (rad/s),
    roll and pitch (rad), ``sin``/``cos`` of the compass heading, ``(z_sp - z^)/10``,
    ``sin``/``cos`` of ``psi_sp - psi^`` and ``n_sp / 1525``.

    **Cost and reward** ``("agents", "cost" | "reward")`` ``[*B, N, 1]``, per AUV
    (:func:`torchrl_auv.iout.task_cost`, weights :class:`~torchrl_auv.iout.CostWeights`):

    .. math::

        c_j = w_d \min(1, d_j/D) + w_p \frac{\max(0, -\Delta_j)}{2\,\mathrm{m/s}\cdot 1\,\mathrm{s}}
            + w_e \frac{P_j}{500\,\mathrm{W}} + w_c 1[\text{collision}_j]
            + w_v 1[\text{violation}_j] + w_o \frac{N_{DO}}{\sum_i \lambda_i}
            \;(+\ c_{term} \text{ for the AUV that ends the episode}),

    with :math:`P_j` the EC model's power at the AUV's mean speed through the water over the
    decision (capped at 3 m/s, inside the model's domain: its efficiency polynomial reaches 0
    at 3.25 m/s, which wave orbital velocities in ``ves`` can approach), or 105 W in service;
    defaults :math:`w_d = 1, w_p = 1, w_e = 0.2, w_c = 5, w_v = 5, w_o = 0.5` and
    ``termination_cost`` :math:`c_{term} = 50`; ``reward = -cost + 5 * [service completed]``.
    The cost is non-negative (LAC's convention). Flat: the sums over AUVs, ``[*B, 1]``.

    **Start state.** Per scene a new seabed, node positions, rates and initial fills
    (U(0, 1000) packets), a new ocean, the AUVs 20 m apart on a circle around a random point
    20 m or more inside the area, 5-10 m deep, random heading, cruising at 1.5 m/s and 1200 rpm
    with the setpoints on the current pose; first targets assigned.

    **Episode end.** ``terminated`` when an AUV's state diverges (non-finite or absurd) or it
    is more than ``exit_margin_m`` (default 50 m, about three minimum turning radii: a
    REMUS-100 serving a node at the edge loiters on a 17 m circle) outside the area (being
    outside at all is a violation); ``truncated`` after ``max_steps`` decisions (default
    1000 = 1000 s).
    ``done = terminated | truncated``; the flags exist per scene (``[*B, 1]``) and per AUV
    (``("agents", ...)`` ``[*B, N, 1]``, the scene's flag for every AUV).

    **Other keys.** ``("truth", "eta" | "nu" | "actuators")`` ``[*B, N, .]`` (the true state,
    for metrics and plots; policies must not read it), ``("kf", "mean" | "cov" | "heading")``,
    ``"setpoint"`` ``[*B, N, 3]``, ``"controller"``, ``"ocean"``, ``"asv"`` ``[*B, 3]``,
    ``"loiter_turn"`` ``[*B, N]`` (+1/-1 while in service),
    ``"task"`` (sensor-network state), ``"accumulators"``, ``"tracking"``, ``"step_count"``
    and ``("metrics", name)`` ``[*B]``: ``sdr`` (Mbit/s summed), ``ssn``, ``ec`` (W, 0 until
    an AUV has moved), ``ec_with_hover`` (W), ``shaft_power`` (W), ``collisions``,
    ``violations``, ``overflow`` (packets), ``heading_error_mean``/``_std`` (rad),
    ``depth_error_mean``/``_std`` (m), running values that are the episode's when ``done``.

    **Arguments.** ``batch_size``; ``num_auvs``; ``num_sensors``; ``sea_state`` ("ideal",
    "es", "ves" or a ``SeaState``); ``controller`` ("s_surface", "pid", "smc");
    ``rate_model`` ("shannon", "paper"); ``seed``; ``max_steps`` (default
    ``episode_decisions`` = 1000); ``flatten_agents`` (single-agent layout);
    ``cost_weights``; ``termination_cost``; ``exit_margin_m``; ``compile_physics`` (run the
    physics step through ``torch.compile``: one compilation per batch shape, then faster;
    TorchRL's own ``compile=`` env argument compiles the whole step instead); any other
    :class:`~torchrl_auv.iout.IoUTConfig` field by keyword (e.g. ``area_m=(300.0, 300.0)``).

    **Version history.** v0: first release.

    Examples:
        >>> env = DataCollectionEnv(batch_size=[2], seed=0)
        >>> td = env.rollout(3)
        >>> td["agents", "observation"].shape, td["next", "agents", "cost"].shape
        (torch.Size([2, 3, 2, 31]), torch.Size([2, 3, 2, 1]))
        >>> flat = DataCollectionEnv(batch_size=[2], seed=0, flatten_agents=True)
        >>> flat.rollout(3)["observation"].shape
        torch.Size([2, 3, 62])
    """

    batch_locked = True

    def __init__(
        self,
        batch_size: torch.Size | list[int] | tuple[int, ...] = (),
        *,
        num_auvs: int = 2,
        num_sensors: int = 60,
        sea_state: str | ocean.SeaState = "ideal",
        controller: str = "s_surface",
        rate_model: str = "shannon",
        seed: int | None = None,
        max_steps: int | None = None,
        flatten_agents: bool = False,
        cost_weights: iout.CostWeights | None = None,
        termination_cost: float = 50.0,
        exit_margin_m: float = 50.0,
        compile_physics: bool = False,
        device: torch.device | str | None = None,
        **config_fields: object,
    ) -> None:
        known = {f.name for f in dataclasses.fields(iout.IoUTConfig)}
        unknown = sorted(set(config_fields) - known)
        if unknown:
            raise ValueError(
                f"unknown argument(s) {unknown}: expected DataCollectionEnv's own arguments or "
                "IoUTConfig fields"
            )
        self.config = iout.IoUTConfig(
            num_auvs=num_auvs, num_sensors=num_sensors, rate_model=rate_model, **config_fields
        )
        self.sea = ocean.get_sea_state(sea_state)
        self.controller = controller_from_name(controller)
        self.max_steps = self.config.episode_decisions if max_steps is None else max_steps
        if self.max_steps < 1:
            raise ValueError(f"max_steps must be >= 1, got {max_steps}")
        if not termination_cost >= 0:
            raise ValueError(f"termination_cost must be >= 0, got {termination_cost}")
        super().__init__(batch_size=torch.Size(batch_size), device=device)
        self.num_auvs = num_auvs
        self.flatten_agents = bool(flatten_agents)
        self.cost_weights = iout.CostWeights() if cost_weights is None else cost_weights
        self.termination_cost = float(termination_cost)
        if not exit_margin_m >= 0:
            raise ValueError(f"exit_margin_m must be >= 0, got {exit_margin_m}")
        self.exit_margin_m = float(exit_margin_m)
        self.vehicles = VehicleStack(
            self.sea,
            self.controller,
            dt=self.config.decision_dt_s / 20,
            decision_steps=20,
            compile=compile_physics,
        )
        self.task_metrics = iout.TaskMetrics(self.config)
        self.rng = torch.Generator()
        self.set_seed(0 if seed is None else seed)
        self._make_specs()

    # -- keys ----------------------------------------------------------------------------
    @property
    def observation_dim(self) -> int:
        """Features per AUV (31)."""
        return len(AGENT_OBSERVATION_FEATURES)

    @property
    def observation_key(self) -> tuple[str, ...] | str:
        """Where policies read: ``("agents", "observation")``, or ``"observation"`` if flat."""
        return "observation" if self.flatten_agents else ("agents", "observation")

    @property
    def agent_action_key(self) -> tuple[str, ...] | str:
        """Where policies write: ``("agents", "action")``, or ``"action"`` if flat."""
        return "action" if self.flatten_agents else ("agents", "action")

    # -- specs ---------------------------------------------------------------------------
    def _make_specs(self) -> None:
        rng_state = self.rng.get_state()  # the spec sample must not consume the seed's draws
        sample = self._initial_state(self.batch_size)
        self.rng.set_state(rng_state)
        shape, n, d = self.batch_size, self.num_auvs, self.observation_dim
        agent_shape = (*shape, n)
        state = sample.exclude("agents", "observation")
        state_spec = unbounded_spec_like(state)
        flags = ("done", "terminated", "truncated")

        def bool_flags(flag_shape: tuple[int, ...]) -> dict[str, Categorical]:
            return {k: Categorical(2, shape=(*flag_shape, 1), dtype=torch.bool) for k in flags}

        if self.flatten_agents:
            observation = {"observation": Unbounded(shape=(*shape, n * d), dtype=torch.float32)}
            action = Bounded(low=-1.0, high=1.0, shape=(*shape, 3 * n), dtype=torch.float32)
            self.full_action_spec = Composite(action=action, shape=shape)
            self.full_reward_spec = Composite(
                reward=Unbounded(shape=(*shape, 1), dtype=torch.float32),
                cost=Unbounded(shape=(*shape, 1), dtype=torch.float32),
                shape=shape,
            )
            self.full_done_spec = Composite(bool_flags(shape), shape=shape)
        else:
            observation = {
                "agents": Composite(
                    observation=Unbounded(shape=(*agent_shape, d), dtype=torch.float32),
                    shape=agent_shape,
                )
            }
            action = Bounded(low=-1.0, high=1.0, shape=(*agent_shape, 3), dtype=torch.float32)
            self.full_action_spec = Composite(
                agents=Composite(action=action, shape=agent_shape), shape=shape
            )
            self.full_reward_spec = Composite(
                agents=Composite(
                    reward=Unbounded(shape=(*agent_shape, 1), dtype=torch.float32),
                    cost=Unbounded(shape=(*agent_shape, 1), dtype=torch.float32),
                    shape=agent_shape,
                ),
                shape=shape,
            )
            self.full_done_spec = Composite(
                agents=Composite(bool_flags(agent_shape), shape=agent_shape),
                **bool_flags(shape),
                shape=shape,
            )
        self.observation_spec = Composite(
            **observation, **{k: v for k, v in state_spec.items()}, shape=shape
        )
        self.state_spec = state_spec.clone()

    def _set_seed(self, seed: int | None) -> None:
        self.rng = torch.Generator().manual_seed(int(seed) if seed is not None else 0)

    # -- reset ---------------------------------------------------------------------------
    def _initial_state(self, shape: torch.Size) -> TensorDict:
        g, cfg, n = self.rng, self.config, self.num_auvs
        task, positions = iout.reset_state(cfg, shape, generator=g)
        heading = (2 * torch.rand((*shape, n), generator=g) - 1) * math.pi
        eta = torch.cat([positions, torch.zeros(*shape, n, 2), heading[..., None]], -1)
        nu = torch.zeros(*shape, n, 6)
        nu[..., 0] = _START_SPEED
        actuators = torch.zeros(*shape, n, 3)
        actuators[..., 2] = _START_RPM
        td = self.vehicles.init(eta, nu, actuators)  # batch [*B, N]
        tracking = TensorDict(
            {k: torch.zeros(*shape, n) for k in TRACKING_SUMS}, batch_size=(*shape, n)
        )
        asv = torch.cat([positions[..., :2].mean(-2), torch.zeros(*shape, 1)], -1)
        accumulators = self.task_metrics.init(shape)
        state = TensorDict(
            {
                "truth": td["truth"],
                "kf": td["kf"],
                "controller": td["controller"],
                "setpoint": torch.stack((eta[..., 2], heading, actuators[..., 2]), -1),
                "ocean": ocean.reset_ocean(self.sea, shape, generator=g),
                "asv": asv,
                "loiter_turn": torch.zeros(*shape, n),
                "task": task,
                "accumulators": accumulators,
                "tracking": tracking,
                "step_count": torch.zeros(*shape, 1, dtype=torch.int64),
            },
            batch_size=shape,
        )
        state["metrics"] = self._metrics(accumulators, tracking)
        self._write_observation(state, state)
        return state

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        return self._initial_state(self.batch_size)

    # -- helpers -------------------------------------------------------------------------
    def _metrics(self, accumulators: TensorDictBase, tracking: TensorDictBase) -> TensorDict:
        metrics = self.task_metrics.finalize(accumulators)
        for name in ("ec", "ec_with_hover", "shaft_power"):  # 0/0 before the first decision
            metrics[name] = torch.nan_to_num(metrics[name], nan=0.0)
        for name, value in tracking_errors(tracking).items():
            metrics[name] = value.mean(-1)  # mean over the AUVs
        return metrics

    def _observe(self, state: TensorDictBase) -> torch.Tensor:
        """Per-AUV observation ``[*B, N, 31]`` from the filter's estimate."""
        eta_hat, nu_hat = self.vehicles.estimate(state)
        task_features = iout.task_observation(state["task"], eta_hat[..., :3], self.config)
        sp = state["setpoint"]
        e_sp = sp[..., 1] - eta_hat[..., 5]
        vehicle = torch.stack(
            (*nu_hat.unbind(-1), eta_hat[..., 3], eta_hat[..., 4], torch.sin(eta_hat[..., 5]),
             torch.cos(eta_hat[..., 5]), (sp[..., 0] - eta_hat[..., 2]) / 10.0,
             torch.sin(e_sp), torch.cos(e_sp), sp[..., 2] / 1525.0), -1
        )  # fmt: skip
        obs = torch.cat([task_features, vehicle], -1).to(torch.float32)
        return torch.nan_to_num(obs, nan=0.0, posinf=0.0, neginf=0.0)

    def _write_observation(self, state: TensorDictBase, out: TensorDictBase) -> None:
        obs = self._observe(state)
        if self.flatten_agents:
            out["observation"] = obs.flatten(-2)
        else:
            out["agents"] = TensorDict({"observation": obs}, batch_size=obs.shape[:-1])

    def _agent_action(self, tensordict: TensorDictBase) -> torch.Tensor:
        if self.flatten_agents:
            action = tensordict["action"].unflatten(-1, (self.num_auvs, 3))
        else:
            action = tensordict["agents", "action"]
        return action.clamp(-1.0, 1.0)

    def _loiter_turn(
        self, td: TensorDictBase, hovering: torch.Tensor, heading_hat: torch.Tensor
    ) -> torch.Tensor:
        """+1 (starboard) or -1 (port) per AUV: the turn whose circle lies toward the area's
        centre, chosen when a service starts and kept until it ends; 0 when not in service."""
        turn = td["loiter_turn"]
        position = td["kf", "mean"][..., :2]
        centre = position.new_tensor([self.config.area_m[0] / 2, self.config.area_m[1] / 2])
        starboard = torch.stack((-torch.sin(heading_hat), torch.cos(heading_hat)), -1)
        inward = ((centre - position) * starboard).sum(-1)
        new = torch.where(inward >= 0, 1.0, -1.0).to(turn.dtype)
        turn = torch.where(turn == 0, new, turn)
        return torch.where(hovering, turn, torch.zeros_like(turn))

    # -- step ----------------------------------------------------------------------------
    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        g, cfg = self.rng, self.config
        td = tensordict.select(*self.state_spec.keys(True, True), strict=True)
        shape = td.batch_size
        action = self._agent_action(tensordict)
        task = td["task"]
        hovering = task["auvs", "in_service"]
        eta = td["truth", "eta"]
        heading_hat = td["kf", "heading"]
        loiter_turn = self._loiter_turn(td, hovering, heading_hat)
        seabed = iout.seabed_depth(task["terrain"], eta[..., 0], eta[..., 1], cfg)
        sp = td["setpoint"]
        depth_sp = (sp[..., 0] + DEPTH_STEP * action[..., 0]).clamp(0.0, None)
        depth_sp = torch.minimum(depth_sp, seabed)
        heading_sp = sp[..., 1] + HEADING_STEP * action[..., 1]
        setpoint = torch.stack(
            (torch.where(hovering, sp[..., 0], depth_sp),
             torch.where(hovering, heading_hat + _LOITER_LEAD * loiter_turn, heading_sp),
             torch.where(hovering, _HOVER_RPM, RPM_SCALE * (action[..., 2] + 3.0))), -1
        )  # fmt: skip
        fleet = TensorDict(
            {k: td[k] for k in ("truth", "kf", "controller")}, batch_size=(*shape, self.num_auvs)
        )
        vehicles, sea_td, decision = self.vehicles.decide(
            fleet, setpoint, td["ocean"], seabed, generator=g
        )
        eta, nu, act = (vehicles["truth", k] for k in ("eta", "nu", "actuators"))
        position = eta[..., :3]
        steps = decision["steps"]
        # mean speed through the water over the decision, inside the EC model's domain
        speed = (decision["speed_sum"] / steps).clamp(max=_EC_SPEED_LIMIT)
        task, events = iout.step(task, position, cfg, generator=g)
        accumulators = self.task_metrics.update(
            td["accumulators"], events, speed, decision["shaft_power_sum"] / steps
        )
        cost, reward, _ = iout.task_cost(
            events, speed, task["nodes", "rate"], cfg, self.cost_weights
        )

        # the ASV follows the fleet's centroid and gives every AUV a USBL fix
        gap = position[..., :2].mean(-2) - td["asv"][..., :2]
        reach = _ASV_SPEED * cfg.decision_dt_s
        scale = reach / torch.linalg.vector_norm(gap, dim=-1, keepdim=True).clamp_min(reach)
        asv = td["asv"] + torch.cat([gap * scale, torch.zeros(*shape, 1)], -1)
        fix, fix_cov, valid = usbl_fix(
            position, asv[..., None, :].expand_as(position), self.sea.usbl_noise_fraction,
            self.sea.usbl_bearing_sigma, g,
        )  # fmt: skip
        mean, cov = self.vehicles.localiser.update_usbl(
            vehicles["kf", "mean"], vehicles["kf", "cov"], fix, fix_cov, valid
        )
        vehicles["kf", "mean"], vehicles["kf", "cov"] = mean, cov

        tracking = add_tracking_sums(td["tracking"], decision)
        x, y, m = eta[..., 0], eta[..., 1], self.exit_margin_m
        outside = (x < -m) | (x > cfg.area_m[0] + m) | (y < -m) | (y > cfg.area_m[1] + m)
        ending = diverged(eta, nu, act) | outside  # [*B, N]
        extra = torch.where(ending, self.termination_cost, 0.0)
        cost = torch.nan_to_num(cost + extra, nan=self.termination_cost)
        reward = torch.nan_to_num(reward - extra, nan=-self.termination_cost)
        step_count = td["step_count"] + 1
        terminated = ending.any(-1, keepdim=True)
        truncated = (step_count >= self.max_steps) & ~terminated

        out = TensorDict(
            {
                "truth": vehicles["truth"],
                "kf": vehicles["kf"],
                "controller": vehicles["controller"],
                "setpoint": setpoint,
                "ocean": sea_td,
                "asv": asv,
                "loiter_turn": loiter_turn,
                "task": task,
                "accumulators": accumulators,
                "tracking": tracking,
                "step_count": step_count,
                "metrics": self._metrics(accumulators, tracking),
                "terminated": terminated,
                "truncated": truncated,
                "done": terminated | truncated,
            },
            batch_size=shape,
        )
        self._write_observation(out, out)
        cost, reward = cost.to(torch.float32)[..., None], reward.to(torch.float32)[..., None]
        if self.flatten_agents:
            out["cost"], out["reward"] = cost.sum(-2), reward.sum(-2)
        else:
            agents = (*shape, self.num_auvs, 1)
            out["agents"] = TensorDict(
                {
                    "observation": out["agents", "observation"],
                    "cost": cost,
                    "reward": reward,
                    "terminated": terminated[..., None, :].expand(agents).clone(),
                    "truncated": truncated[..., None, :].expand(agents).clone(),
                    "done": (terminated | truncated)[..., None, :].expand(agents).clone(),
                },
                batch_size=(*shape, self.num_auvs),
            )
        return out
