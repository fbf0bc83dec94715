"""``DataCollectionEnv``: a fleet of REMUS-100s collecting data from underwater sensor nodes.

The paper's evaluation task (``docs/spec/data_collection.md``). The env wires the layers
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
from torchrl_auv.envs.device import on_env_device, step_on_cpu
from torchrl_auv.envs.keys import (
    AGENT_ACTION,
    AGENT_APPROACH,
    AGENT_COST,
    AGENT_OBSERVATION,
    AGENT_SERVICE_START,
    AGENT_STABILITY_COST,
    AGENTS,
)
from torchrl_auv.envs.specs import (
    checked_action,
    checked_batch_size,
    controller_from_name,
    scene_generator,
    unbounded_spec_like,
)
from torchrl_auv.envs.tracking import DEPTH_STEP, HEADING_STEP, RPM_SCALE
from torchrl_auv.envs.vehicles import (
    TRACKING_SUMS,
    VehicleStack,
    add_tracking_sums,
    tracking_errors,
)
from torchrl_auv.estimation import altimeter, asv_draws, asv_fixes, gnss_error_init
from torchrl_auv.physics import ocean

__all__ = ["AGENT_OBSERVATION_FEATURES", "SIM_KEY", "VEHICLE_FEATURES", "DataCollectionEnv"]

#: where the env keeps its simulator state (true state, filters, ocean, sensor network, running
#: sums): everything a learner does not need, excluded with one key
SIM_KEY = "sim"

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

_START_RPM = 1200.0
_EC_SPEED_LIMIT = 3.0  # m/s; the EC model's efficiency polynomial reaches 0 at 3.25 m/s
_START_SPEED = 1.5  # m/s
_ADCP_SIGMA = 0.05  # m/s per axis: the vehicle's estimate of the current (ours)
_ALTIMETER_SIGMA = 0.1  # m (ours)
_ALTIMETER_RANGE = 30.0  # m: the DVL's bottom-lock range, the altitude it measures (ours)


class DataCollectionEnv(EnvBase):
    r"""Multi-AUV data collection from underwater sensor nodes (env card, spec v2).

    **Description.** ``num_auvs`` REMUS-100s (default 2) collect data from ``num_sensors``
    (default 60) sensor nodes on a random seabed, 39-58 m deep, in a 200 m x 200 m area. Each
    node fills its buffer with Poisson data (rate 4, 6, 9 or 12 packets per decision, capacity
    5000). The env assigns every AUV a node of highest priority
    :math:`\lambda_i b_i / C_{max} - 0.05 d_i` among those filled to at least 10 % (two AUVs
    never share one; an AUV keeps its target until it is served,
    ``retarget_every_decision=False``); within 18 m (3-D) service starts and lasts
    :math:`Q (b_i/C_{max}) / R(d)` s (Q = 2 Mbit, :math:`R` the acoustic link rate at the start,
    ``rate_model`` "shannon" or "paper"), after which the node's buffer is empty; it becomes a
    target again once refilled above 10 %. An ASV at the surface follows the fleet's centroid
    (at most 2 m/s) and gives each AUV a USBL fix per decision, converted to NED from its
    GNSS position (Gauss-Markov error, 1 / 1.5 / 2 m in ideal / es / ves), with bearing noise
    growing with the waves and dropouts (0 / 5 / 20 %); the AUVs navigate on a Kalman filter
    fusing USBL, DVL (bottom lock within 30 m altitude), depth and compass. Finite-depth waves
    reach the vehicle with their vertical velocity. Physics and the low-level controller run at
    20 Hz, the agent decides at 1 Hz.

    *Station keeping.* The REMUS-100 cannot hover and turns on a circle of about 20 m radius,
    wider than the service radius, so while an AUV is in service the env overrides its action
    with :func:`~torchrl_auv.iout.station_keeping_setpoints`: bow into the current with the
    propeller matching it (stopped in still water), 8 m above the seabed the altimeter sees
    (``station_keeping``, :class:`~torchrl_auv.iout.StationKeepingConfig`). ``"overridden"``
    marks those AUV-decisions. An AUV that arrives bow downstream must turn round first and may
    drift out of the service radius; the expert plans its way to arrive from downstream.

    **Action** ``("agents", "action")`` ``[*B, N, 3]`` in [-1, 1] (``"action"`` ``[*B, 3 N]``
    with ``flatten_agents=True``), per AUV:

    ====  ==============================  ===================================================
    idx   meaning                         effect
    ====  ==============================  ===================================================
    0     depth setpoint change           ``z_sp += 0.8 a0`` m (>= 0, and at least 1 m above
                                          the seabed the altimeter sees, when it sees it)
    1     heading setpoint change         ``psi_sp += 0.15 a1`` rad
    2     propeller speed                 ``n_sp = 380 (a2 + 3)`` rpm (760-1520)
    ====  ==============================  ===================================================

    Values outside [-1, 1] are clipped to it (the spec's bounds, as a policy's squashing would);
    a NaN or infinite entry, or an action of another shape, is a ``ValueError`` naming the key
    and the expected shape (a NaN used to end the episode as "diverged" without a word).

    **Observation** ``("agents", "observation")`` ``[*B, N, 38]`` float32 (``"observation"``
    ``[*B, 38 N]`` flat), computed from the Kalman estimate and the vehicle's own sensors, never
    the true pose. Entries 0-23 are the task features of :mod:`torchrl_auv.iout.observation`
    (target offset and distance, target fill and rate, has-target, in-service, hover time
    left, altimeter altitude, depth, nearest AUV offset and distance, services so far, time
    fraction of ``max_steps``, the signed distances to the four edges, the current estimate
    north and east, and the age of the AUV's last delivery over ``age_scale``, at most 1);
    entries 24-37 are :data:`VEHICLE_FEATURES`: body velocity ``u^, v^, w^``
    (m/s), rates ``p, q, r`` (rad/s), roll and pitch (rad), ``sin``/``cos`` of the compass
    heading, ``(z_sp - z^)/10``, ``sin``/``cos`` of ``psi_sp - psi^`` and ``n_sp / 1525``.
    The altimeter reads the altitude with 0.1 m noise up to 30 m (beyond: 30); the current
    estimate is the scene's current with 0.05 m/s noise per axis (an ADCP, ours).

    **Cost and reward** ``("agents", "cost" | "reward")`` ``[*B, N, 1]``, per AUV, task v3
    (:func:`torchrl_auv.iout.task_cost`, weights :class:`~torchrl_auv.iout.CostWeights`, the
    design and its measurements in ``docs/spec/data_collection.md``), every term clipped to
    [0, 1] before its weight:

    .. math::

        c_j = {} & w_m \begin{cases} 1 - \min(1, \tfrac{R_j \tau_j}{R_{ref} \Delta t})
                       & \text{in service} \\
                   \min(1, \tfrac{a_j}{A}) & \text{otherwise} \end{cases}
            + w_e \min(1, \tfrac{P_j}{500\,\mathrm{W}}) \\
            & + w_c 1[\text{collision}_j] + w_v 1[\text{violation}_j]
            \ (+\ c_{term} \text{ for the AUV that ends the episode}),

    with :math:`R_j \tau_j` the bits AUV :math:`j` delivered in the decision, :math:`R_{ref}`
    the link's rate 8 m from a node, :math:`a_j` the decisions since it last delivered data
    (observation ``delivery_age``; :math:`A` at reset) and :math:`A` = ``age_scale`` (645
    decisions by default: the time an average node takes to fill an empty buffer),
    :math:`P_j` the EC model's power at the AUV's mean speed through the water (capped at
    3 m/s, inside the model's domain), or 105 W in service. Delivering data is what lowers an
    AUV's cost, and each AUV's cost is its own (only a collision involves another). Defaults
    :math:`w_m = 1, w_e = 0.2, w_c = 2, w_v = 1`, so :math:`0 \le c_j \le c_{max} = 4.2`;
    ``termination_cost`` :math:`c_{term} = N c_{max} / (1 - 0.99) = 840` for two AUVs (ending
    an episode is never cheaper than continuing it, for any discount up to 0.99).
    ``reward = -cost`` exactly (one learning signal for every framework). ``"cost_terms"``
    holds the weighted terms (``undelivered``, ``delivery_age``, ``energy``, ``collision``,
    ``violation``). ``env.reward_key`` is the reward, the one reward key (through any wrapper);
    ``cost`` and ``stability_cost`` are observation keys (``env.cost_keys``: 0 at reset, then the
    last decision's), to rescale together with the reward. Flat: the sums over AUVs,
    ``[*B, 1]``.

    **Stability cost** ``("agents", "stability_cost")`` ``[*B, N, 1]`` (flat: the sum,
    ``"stability_cost"``): :func:`torchrl_auv.iout.stability_cost`, the normalised distance
    to the target, moving away from it, and the collision and violation terms (0 in service,
    at most 5 per AUV), plus :math:`5 / (1 - 0.99) = 500` for the AUV that ends the episode:
    the cost a Lyapunov critic can decrease along an approach (``lyapunov.cost=stability``); a
    separate signal, not part of the reward.

    **Approach legs** ``("agents", "approach" | "service_start")`` ``[*B, N, 1]`` bool
    (observation keys: False at reset, then the last decision's; multi-agent layout only):
    the decision belonged to an approach leg (the AUV headed for one target and kept it or
    reached it) and it ended the leg by starting service (:mod:`torchrl_auv.iout.legs`). The
    Lyapunov critic's legs and absorbing equilibrium.

    **Start state.** Per scene a new seabed, node positions, rates and initial fills
    (U(0, 1000) packets), a new ocean (as deep as the scene's mean seabed), the AUVs 20 m apart
    on a circle around a random point 20 m or more inside the area, 5-10 m deep, random heading,
    cruising at 1.5 m/s and 1200 rpm with the setpoints on the current pose; first targets
    assigned.

    **Episode end.** ``terminated`` when an AUV's state diverges (non-finite or absurd) or it
    is more than ``exit_margin_m`` (default 100 m) outside the area (being outside at all is a
    violation, every decision it lasts); ``truncated`` after ``max_steps`` decisions (default
    1000 = 1000 s). Per scene (``[*B, 1]``): ``done = terminated | truncated``. Per AUV
    (``("agents", ...)`` ``[*B, N, 1]``): the AUV that ends the episode is ``terminated``, the
    others are ``truncated`` (their cost-to-go does not end with a peer's exit: they
    bootstrap); ``done`` is the scene's.

    **Other keys.** The simulator's own state lives under one key, ``"sim"`` (:data:`SIM_KEY`):
    ``("sim", "truth", "eta" | "nu" | "actuators")`` ``[*B, N, .]`` (the true state, for
    metrics and plots; policies must not read it), ``("sim", "kf", "mean" | "cov" |
    "heading")``, ``("sim", "setpoint")`` ``[*B, N, 3]``, ``("sim", "controller")``,
    ``("sim", "ocean")``, ``("sim", "asv")`` ``[*B, 3]``, ``("sim", "asv_gnss_error")``
    ``[*B, 2]``, ``("sim", "sensors", "altitude" | "altitude_valid" | "current")``, ``("sim",
    "task")`` (sensor-network state), ``("sim", "accumulators" | "tracking" |
    "localisation")``: about 30 KB per frame that a learner does not need, so a replay buffer
    stores ``rollout.exclude("sim", ("next", "sim"))`` (well under 1 KB per frame for two AUVs,
    ``examples/plain_torchrl_sac.py``). Beside the observation, reward and done keys:
    ``"overridden"`` ``[*B, N]`` (the station keeper set the AUV's setpoints),
    ``"cost_terms"`` (the weighted cost terms, ``[*B, N]`` each), ``"step_count"`` ``[*B, 1]``
    and ``("metrics", name)`` ``[*B]``: ``sdr`` (Mbit delivered, the paper's "MBit/s"), ``ssn``,
    ``services_inside`` (services that ended within the service radius), ``ec`` (W, 0 until an
    AUV has moved), ``ec_with_hover`` (W), ``shaft_power`` (W), ``collisions``,
    ``violations``, ``overflow`` (packets), ``heading_error_mean``/``_std`` (rad),
    ``depth_error_mean``/``_std`` (m; over the decisions whose setpoints the policy set),
    ``kf_position_error`` and ``usbl_position_error`` (m, mean), running values that are the
    episode's when ``done``.

    **Arguments.** ``batch_size``; ``num_auvs``; ``num_sensors``; ``sea_state`` ("ideal",
    "es", "ves" or a ``SeaState``); ``controller`` ("s_surface", "pid", "smc");
    ``rate_model`` ("shannon", "paper"); ``seed``; ``max_steps`` (default
    ``episode_decisions`` = 1000); ``flatten_agents`` (single-agent layout);
    ``per_agent_done`` (default ``True``; ``False``: the done flags at the scene level only,
    VMAS's layout, which TorchRL's ``sota-implementations/multiagent/`` scripts expect: their
    ``DoneTransform`` expands them over the agents, every AUV terminated when one ends the
    episode);
    ``cost_weights``; ``termination_cost`` (default ``None``: derived as above); ``device``
    (where its outputs and the carried state live; the simulation runs on the CPU,
    :mod:`~torchrl_auv.envs.device`);
    ``exit_margin_m``; ``station_keeping``; ``compile_physics`` (run the decision through
    ``torch.compile``: the 20 physics steps from the first decision on, the code around them
    (setpoints; network, cost, localisation, sensors, flags, observation) from the second;
    one compilation per batch shape, then faster. A decision draws all its random numbers
    first, so what follows the draws is pure tensor code; compiled and eager agree to 1e-5);
    any other :class:`~torchrl_auv.iout.IoUTConfig` field by keyword (e.g.
    ``area_m=(300.0, 300.0)``); any other keyword raises Python's usual ``TypeError: ...
    got an unexpected keyword argument '<name>'`` (which TorchRL's ``GymEnv`` relies on to
    drop ``frameskip``).

    **Version history.** v3 (task v3, gymnasium id ``DataCollection-v2``): the cost pays for
    the mission (the delivery share in service, the age of the AUV's last delivery otherwise)
    instead of the data waiting in the whole network; weights 1 / 0.2 / 2 / 1; the stability
    cost computed from the events; ``delivery_age`` observed (38 features). v2: the simulator
    state under ``"sim"`` (was 12 top-level keys).
    v1 (spec v2): termination only on divergence or 100 m out, derived
    terminal cost, peers truncated; ``reward = -cost`` with the waiting data in the cost;
    station keeping replaces the loiter; re-service above 10 % fill; edges, altimeter and
    current estimate in the observation (37 features); real localisation errors; finite-depth
    waves; fractional SDR; tracking metrics without station keeping. v0: first release.

    Examples:
        >>> env = DataCollectionEnv(batch_size=[2], seed=0)
        >>> td = env.rollout(3)
        >>> td["agents", "observation"].shape, td["next", "agents", "cost"].shape
        (torch.Size([2, 3, 2, 38]), torch.Size([2, 3, 2, 1]))
        >>> flat = DataCollectionEnv(batch_size=[2], seed=0, flatten_agents=True)
        >>> flat.rollout(3)["observation"].shape
        torch.Size([2, 3, 76])
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
        per_agent_done: bool = True,
        cost_weights: iout.CostWeights | None = None,
        termination_cost: float | None = None,
        exit_margin_m: float = 100.0,
        station_keeping: iout.StationKeepingConfig | None = None,
        compile_physics: bool = False,
        device: torch.device | str | None = None,
        **config_fields: object,
    ) -> None:
        known = {f.name for f in dataclasses.fields(iout.IoUTConfig)}
        unknown = [name for name in config_fields if name not in known]
        if unknown:
            # Python's own wording (the first unknown name, in call order): callers such as
            # TorchRL's GymEnv drop an optional keyword (``frameskip``) only on this TypeError.
            raise TypeError(
                f"DataCollectionEnv.__init__() got an unexpected keyword argument "
                f"'{unknown[0]}' (expected DataCollectionEnv's own arguments or IoUTConfig fields)"
            )
        self.config = iout.IoUTConfig(
            num_auvs=num_auvs, num_sensors=num_sensors, rate_model=rate_model, **config_fields
        )
        self.sea = ocean.get_sea_state(sea_state)
        self.controller = controller_from_name(controller)
        self.max_steps = self.config.episode_decisions if max_steps is None else max_steps
        if not (isinstance(self.max_steps, int) and self.max_steps >= 1):
            raise ValueError(f"max_steps must be an int >= 1, got {max_steps!r}")
        if termination_cost is not None and not termination_cost >= 0:
            raise ValueError(f"termination_cost must be None or >= 0, got {termination_cost}")
        super().__init__(batch_size=checked_batch_size(batch_size), device=device)
        self.num_auvs = num_auvs
        self.flatten_agents = bool(flatten_agents)
        self.per_agent_done = bool(per_agent_done)
        self.cost_weights = iout.CostWeights() if cost_weights is None else cost_weights
        if termination_cost is None:
            termination_cost = self.cost_weights.termination_cost(num_auvs)
        self.termination_cost = float(termination_cost)
        self.station_keeping = (
            iout.StationKeepingConfig() if station_keeping is None else station_keeping
        )
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
        self._compiled_parts = None
        self.rng = torch.Generator()
        self.set_seed(seed)  # None: from entropy (scene_generator)
        self._make_specs()

    # -- keys ----------------------------------------------------------------------------
    @property
    def observation_dim(self) -> int:
        """Features per AUV (38: ``AGENT_OBSERVATION_FEATURES``)."""
        return len(AGENT_OBSERVATION_FEATURES)

    @property
    def observation_key(self) -> tuple[str, ...] | str:
        """Where policies read: ``("agents", "observation")``, or ``"observation"`` if flat."""
        return "observation" if self.flatten_agents else AGENT_OBSERVATION

    @property
    def agent_action_key(self) -> tuple[str, ...] | str:
        """Where policies write: ``("agents", "action")``, or ``"action"`` if flat."""
        return "action" if self.flatten_agents else AGENT_ACTION

    @property
    def cost_keys(self) -> list[tuple[str, ...] | str]:
        """The cost and the stability cost, ``[("agents", "cost"), ("agents",
        "stability_cost")]`` (flat: ``["cost", "stability_cost"]``): observation keys (0 at
        reset, then the last decision's), not reward keys, so that ``env.reward_key`` is the one
        reward through every wrapper. To rescale the reward together with the cost the
        Lyapunov loss reads: ``RewardScaling(0.0, s, in_keys=[env.reward_key, *env.cost_keys])``."""
        if self.flatten_agents:
            return ["cost", "stability_cost"]
        return [AGENT_COST, AGENT_STABILITY_COST]

    @property
    def n_agents(self) -> int:
        """The AUVs (TorchRL's multi-agent attribute, as ``VmasEnv.n_agents``)."""
        return self.num_auvs

    @property
    def group_map(self) -> dict[str, list[str]]:
        """One group, ``"agents"``, of the AUVs ``auv_0 ... auv_{N-1}`` (TorchRL's multi-agent
        convention); the flat layout is one agent, ``{"agent": ["agent"]}``."""
        if self.flatten_agents:
            return {"agent": ["agent"]}
        return {AGENTS: [f"auv_{i}" for i in range(self.num_auvs)]}

    # -- specs ---------------------------------------------------------------------------
    def _make_specs(self) -> None:
        rng_state = self.rng.get_state()  # the spec sample must not consume the seed's draws
        sample = self._initial_state(self.batch_size)
        self.rng.set_state(rng_state)
        shape, n, d = self.batch_size, self.num_auvs, self.observation_dim
        agent_shape = (*shape, n)
        state = sample.exclude("agents", "observation", *self.cost_keys)
        state_spec = unbounded_spec_like(state)
        flags = ("done", "terminated", "truncated")

        def bool_flags(flag_shape: tuple[int, ...]) -> dict[str, Categorical]:
            return {k: Categorical(2, shape=(*flag_shape, 1), dtype=torch.bool) for k in flags}

        if self.flatten_agents:
            observation = {
                "observation": Unbounded(shape=(*shape, n * d), dtype=torch.float32),
                "cost": Unbounded(shape=(*shape, 1), dtype=torch.float32),
                "stability_cost": Unbounded(shape=(*shape, 1), dtype=torch.float32),
            }
            action = Bounded(low=-1.0, high=1.0, shape=(*shape, 3 * n), dtype=torch.float32)
            self.full_action_spec = Composite(action=action, shape=shape)
            self.full_reward_spec = Composite(
                reward=Unbounded(shape=(*shape, 1), dtype=torch.float32), shape=shape
            )
            self.full_done_spec = Composite(bool_flags(shape), shape=shape)
        else:
            observation = {
                "agents": Composite(
                    observation=Unbounded(shape=(*agent_shape, d), dtype=torch.float32),
                    cost=Unbounded(shape=(*agent_shape, 1), dtype=torch.float32),
                    stability_cost=Unbounded(shape=(*agent_shape, 1), dtype=torch.float32),
                    approach=Categorical(2, shape=(*agent_shape, 1), dtype=torch.bool),
                    service_start=Categorical(2, shape=(*agent_shape, 1), dtype=torch.bool),
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
                    shape=agent_shape,
                ),
                shape=shape,
            )
            agent_flags = (
                {"agents": Composite(bool_flags(agent_shape), shape=agent_shape)}
                if self.per_agent_done
                else {}
            )
            self.full_done_spec = Composite(**agent_flags, **bool_flags(shape), shape=shape)
        self.observation_spec = Composite(
            **observation, **{k: v for k, v in state_spec.items()}, shape=shape
        )
        self.state_spec = state_spec.clone()
        self._state_keys = tuple(self.state_spec.keys(True, True))

    def _set_seed(self, seed: int | None) -> None:
        self.rng = scene_generator(seed)

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
        sea_td = ocean.reset_ocean(  # finite depth: the scene's mean seabed depth
            self.sea, shape, generator=g, water_depth=task["terrain", "depth"].mean((-2, -1))
        )
        seabed = iout.seabed_depth(task["terrain"], eta[..., 0], eta[..., 1], cfg)
        sensor_draws = self._sensor_draws((*shape, n), eta.dtype, sea_td["current_speed"].dtype)
        sensors = self._sensors(sea_td, seabed - eta[..., 2], (*shape, n), sensor_draws)
        sim = TensorDict(
            {
                "truth": td["truth"],
                "kf": td["kf"],
                "controller": td["controller"],
                "setpoint": torch.stack((eta[..., 2], heading, actuators[..., 2]), -1),
                "ocean": sea_td,
                "asv": asv,
                "asv_gnss_error": gnss_error_init(
                    (*shape, 2), self.sea.gnss_sigma, g, dtype=eta.dtype
                ),
                "sensors": sensors,
                "task": task,
                "accumulators": accumulators,
                "tracking": tracking,
                "localisation": self._localisation_init(shape),
            },
            batch_size=shape,
        )
        state = TensorDict(
            {
                SIM_KEY: sim,
                "overridden": torch.zeros(*shape, n, dtype=torch.bool),
                "cost_terms": TensorDict(
                    {k: torch.zeros(*shape, n) for k in iout.COST_TERMS}, batch_size=(*shape, n)
                ),
                "step_count": torch.zeros(*shape, 1, dtype=torch.int64),
                "metrics": self._metrics(accumulators, tracking, sim["localisation"]),
            },
            batch_size=shape,
        )
        self._write_observation(sim, state)
        for key in self.cost_keys:  # no decision yet: no cost
            state[key] = torch.zeros(*shape, *((n,) if not self.flatten_agents else ()), 1)
        if not self.flatten_agents:  # no decision yet: no leg
            for key in (AGENT_APPROACH, AGENT_SERVICE_START):
                state[key] = torch.zeros(*shape, n, 1, dtype=torch.bool)
        return state

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        return on_env_device(self, self._initial_state(self.batch_size))

    # -- helpers -------------------------------------------------------------------------
    @staticmethod
    def _localisation_init(shape: torch.Size) -> TensorDict:
        """Running sums of the position errors (m) of the filter and of the raw USBL fixes."""
        zeros = {
            k: torch.zeros(shape)
            for k in ("kf_error_sum", "usbl_error_sum", "kf_samples", "usbl_samples")
        }
        return TensorDict(zeros, batch_size=shape)

    def _metrics(
        self, accumulators: TensorDictBase, tracking: TensorDictBase, localisation: TensorDictBase
    ) -> TensorDict:
        metrics = self.task_metrics.finalize(accumulators)
        for name in ("ec", "ec_with_hover", "shaft_power"):  # 0/0 before the first decision
            metrics[name] = torch.nan_to_num(metrics[name], nan=0.0)
        for name, value in tracking_errors(tracking).items():
            metrics[name] = value.mean(-1)  # mean over the AUVs
        for name in ("kf", "usbl"):
            count = localisation[f"{name}_samples"].clamp_min(1.0)
            metrics[f"{name}_position_error"] = localisation[f"{name}_error_sum"] / count
        return metrics

    def _sensor_draws(
        self, shape: tuple[int, ...], dtype: torch.dtype, current_dtype: torch.dtype
    ) -> dict[str, torch.Tensor]:
        """The standard normals of :meth:`_sensors` for AUVs ``[*B, N]``: altimeter, ADCP."""
        g = self.rng
        return {
            "altimeter": torch.randn(shape, generator=g, dtype=dtype),
            "adcp": torch.randn((*shape, 2), generator=g, dtype=current_dtype),
        }

    def _sensors(
        self,
        sea_td: TensorDictBase,
        true_altitude: torch.Tensor,
        shape: tuple[int, ...],
        draws: dict[str, torch.Tensor],
    ) -> TensorDict:
        """What each AUV measures at the end of a decision: its altimeter (m; out of range:
        ``valid`` False and the range as the reading) and its estimate of the current (the
        scene's current, north and east, with ADCP noise, m/s); ``draws`` from
        :meth:`_sensor_draws`."""
        reading, valid = altimeter(
            true_altitude.nan_to_num(1e6),
            _ALTIMETER_SIGMA,
            None,
            max_range=_ALTIMETER_RANGE,
            standard_normal=draws["altimeter"],
        )
        speed, direction = sea_td["current_speed"], sea_td["current_direction"]
        flow = torch.stack((speed * torch.cos(direction), speed * torch.sin(direction)), -1)
        noise = _ADCP_SIGMA * draws["adcp"]
        return TensorDict(
            {"altitude": reading, "altitude_valid": valid, "current": flow[..., None, :] + noise},
            batch_size=shape,
        )

    def _observe(self, state: TensorDictBase) -> torch.Tensor:
        """Per-AUV observation ``[*B, N, 38]`` from the filter's estimate and the sensors."""
        eta_hat, nu_hat = self.vehicles.estimate(state)
        sensors = state["sensors"]
        task_features = iout.task_observation(
            state["task"],
            eta_hat[..., :3],
            self.config,
            altitude=sensors["altitude"],
            current=sensors["current"],
            horizon=self.max_steps,
        )
        sp = state["setpoint"]
        e_sp = sp[..., 1] - eta_hat[..., 5]
        vehicle = torch.stack(
            (
                *nu_hat.unbind(-1),
                eta_hat[..., 3],
                eta_hat[..., 4],
                torch.sin(eta_hat[..., 5]),
                torch.cos(eta_hat[..., 5]),
                (sp[..., 0] - eta_hat[..., 2]) / 10.0,
                torch.sin(e_sp),
                torch.cos(e_sp),
                sp[..., 2] / 1525.0,
            ),
            -1,
        )
        obs = torch.cat([task_features, vehicle], -1).to(torch.float32)
        return torch.nan_to_num(obs, nan=0.0, posinf=0.0, neginf=0.0)

    def _write_observation(self, state: TensorDictBase, out: TensorDictBase) -> None:
        obs = self._observe(state)
        if self.flatten_agents:
            out["observation"] = obs.flatten(-2)
        else:
            out["agents"] = TensorDict({"observation": obs}, batch_size=obs.shape[:-1])

    def _agent_action(self, tensordict: TensorDictBase) -> torch.Tensor:
        """The action ``[*B, N, 3]``, checked (shape, finite) and clipped to [-1, 1]."""
        n, key = self.num_auvs, self.agent_action_key
        shape = (*self.batch_size, 3 * n) if self.flatten_agents else (*self.batch_size, n, 3)
        action = checked_action(tensordict[key], shape, key)
        return action.unflatten(-1, (n, 3)) if self.flatten_agents else action

    # -- step ----------------------------------------------------------------------------
    def _setpoints(
        self, td: TensorDictBase, action: torch.Tensor, hovering: torch.Tensor
    ) -> torch.Tensor:
        """``[*B, N, 3]`` controller setpoints for the decision: the action's (card), or the
        station keeper's for the AUVs in service."""
        eta_hat, _ = self.vehicles.estimate(td)
        sensors = td["sensors"]
        valid = sensors["altitude_valid"]
        sp = td["setpoint"]
        # the depth setpoint stays above the seabed the altimeter sees (when it sees it)
        floor = eta_hat[..., 2] + sensors["altitude"] - self.config.clearance_m
        depth_sp = (sp[..., 0] + DEPTH_STEP * action[..., 0]).clamp_min(0.0)
        depth_sp = torch.where(valid, torch.minimum(depth_sp, floor.clamp_min(0.0)), depth_sp)
        agent = torch.stack(
            (
                depth_sp,
                sp[..., 1] + HEADING_STEP * action[..., 1],
                RPM_SCALE * (action[..., 2] + 3.0),
            ),
            -1,
        )
        task = td["task"]
        node = iout.gather_nodes(task["nodes", "position"], task["auvs", "target"])
        altitude = torch.where(valid, sensors["altitude"], torch.nan)
        keeper = torch.stack(
            iout.station_keeping_setpoints(
                eta_hat[..., :3],
                eta_hat[..., 5],
                node.to(eta_hat.dtype),
                sensors["current"],
                altitude,
                self.station_keeping,
                radius_m=self.config.service_radius_m,
            ),
            -1,
        )
        return torch.where(hovering[..., None], keeper, agent)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        return step_on_cpu(self, tensordict, self._simulate_step)  # envs.device

    def _simulate_step(self, tensordict: TensorDictBase) -> TensorDictBase:
        """One decision: the action checked and every random number of the decision drawn
        (:meth:`_decision_draws`), then pure tensor code: the setpoints, the 20 physics steps
        (:meth:`VehicleStack.decide`), and what follows them (:meth:`_after_physics`); with
        ``compile_physics`` the code before and after the physics runs compiled too."""
        state = tensordict.select(*self._state_keys, strict=True)
        td = state[SIM_KEY]
        action = self._agent_action(tensordict)
        draws = self._decision_draws(td)
        before, after = self._decision_parts()
        setpoint, seabed = before(td, action)
        fleet = TensorDict(
            {k: td[k] for k in ("truth", "kf", "controller")},
            batch_size=(*td.batch_size, self.num_auvs),
        )
        vehicles, sea_td, decision = self.vehicles.decide(
            fleet, setpoint, td["ocean"], seabed, generator=None, noise=draws["vehicles"]
        )
        return after(state, setpoint, vehicles, sea_td, decision, draws)

    def _decision_draws(self, td: TensorDictBase) -> dict:
        """Every random number of one decision from ``self.rng``, in the order the decision
        uses them: the physics steps' (current, onboard sensors), the nodes' Poisson
        arrivals, the ASV's (GNSS, USBL), the end-of-decision sensors' (altimeter, ADCP).
        Drawn ahead, so that what follows is pure tensor code (compilable)."""
        g = self.rng
        eta = td["truth", "eta"]
        shape = eta.shape[:-1]
        vehicles = self.vehicles.draw_noise(
            shape, td["ocean"].batch_size, g, dtype=td["setpoint"].dtype
        )
        nodes = td["task", "nodes"]
        arrivals = torch.poisson(nodes["rate"].expand_as(nodes["buffer"]), generator=g)
        asv = asv_draws(td["asv_gnss_error"], eta[..., :3], g)
        sensors = self._sensor_draws(shape, eta.dtype, td["ocean", "current_speed"].dtype)
        return {"vehicles": vehicles, "arrivals": arrivals, "asv": asv, "sensors": sensors}

    def _decision_parts(self):
        """``(before, after)`` the physics: compiled with ``compile_physics`` from the second
        decision on (the first, eager, fills the constant tensors the code caches on first
        use; filled while tracing, they would recompile every compiled function)."""
        if not self.vehicles.compile:
            return self._before_physics, self._after_physics
        if self._compiled_parts is None:
            options = {"dynamic": False, "options": {"cpp_wrapper": True}}
            self._compiled_parts = (
                torch.compile(self._before_physics, **options),
                torch.compile(self._after_physics, **options),
            )
            return self._before_physics, self._after_physics
        return self._compiled_parts

    def _before_physics(
        self, td: TensorDictBase, action: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """The decision's setpoints ``[*B, N, 3]`` and the seabed depth under each AUV (m)."""
        hovering = td["task", "auvs", "in_service"]
        setpoint = self._setpoints(td, action, hovering)
        eta = td["truth", "eta"]
        seabed = iout.seabed_depth(td["task", "terrain"], eta[..., 0], eta[..., 1], self.config)
        return setpoint, seabed.nan_to_num(self.config.seabed_depth_range_m[1])

    def _after_physics(
        self,
        state: TensorDictBase,
        setpoint: torch.Tensor,
        vehicles: TensorDictBase,
        sea_td: TensorDictBase,
        decision: TensorDictBase,
        draws: dict,
    ) -> TensorDict:
        """Everything of the decision after the physics steps: the network, the cost, the
        localisation, the sensors, the ending flags and the observation."""
        cfg = self.config
        td = state[SIM_KEY]
        shape = td.batch_size
        task = td["task"]
        hovering = task["auvs", "in_service"]
        eta, nu, act = (vehicles["truth", k] for k in ("eta", "nu", "actuators"))
        position = eta[..., :3]
        steps = decision["steps"]
        # mean speed through the water over the decision, inside the EC model's domain
        speed = (decision["speed_sum"] / steps).clamp(max=_EC_SPEED_LIMIT)
        target_before = task["auvs", "target"]
        task, events = iout.step(task, position, cfg, generator=None, arrivals=draws["arrivals"])
        legs = iout.approach_legs(
            hovering, target_before, task["auvs", "in_service"], task["auvs", "target"]
        )
        accumulators = self.task_metrics.update(
            td["accumulators"], events, speed, decision["shaft_power_sum"] / steps
        )
        cost, terms = iout.task_cost(events, speed, cfg, self.cost_weights)

        # the ASV follows the fleet and gives every AUV a USBL fix; the filters take them
        asv, gnss, fix, fix_cov, valid = asv_fixes(
            td["asv"],
            td["asv_gnss_error"],
            position,
            self.sea,
            cfg.decision_dt_s,
            None,
            draws=draws["asv"],
        )
        mean, cov = self.vehicles.localiser.update_usbl(
            vehicles["kf", "mean"], vehicles["kf", "cov"], fix, fix_cov, valid
        )
        vehicles["kf", "mean"], vehicles["kf", "cov"] = mean, cov
        localisation = self._localise(td["localisation"], mean, fix, valid, position)
        seabed_after = iout.seabed_depth(task["terrain"], eta[..., 0], eta[..., 1], cfg)
        sensors = self._sensors(
            sea_td, seabed_after - eta[..., 2], (*shape, self.num_auvs), draws["sensors"]
        )

        # tracking errors count only the decisions whose setpoints the policy set
        own = (~hovering).to(decision["steps"].dtype)
        policy_decision = decision.apply(lambda value: value * own)
        tracking = add_tracking_sums(td["tracking"], policy_decision)

        # the episode ends for an AUV that diverged or left the area; ending costs its terminal
        ending = iout.ending_auvs(eta, nu, act, cfg, self.exit_margin_m)  # [*B, N]
        cost = iout.with_termination(cost, ending, self.termination_cost)
        stability_end = self.cost_weights.stability_termination_cost()
        stability = iout.stability_cost(events, cfg, self.cost_weights)
        stability = iout.with_termination(stability, ending, stability_end)
        step_count = state["step_count"] + 1
        terminated, truncated, done = iout.episode_flags(ending, step_count, self.max_steps)

        sim = TensorDict(
            {
                "truth": vehicles["truth"],
                "kf": vehicles["kf"],
                "controller": vehicles["controller"],
                "setpoint": setpoint,
                "ocean": sea_td,
                "asv": asv,
                "asv_gnss_error": gnss,
                "sensors": sensors,
                "task": task,
                "accumulators": accumulators,
                "tracking": tracking,
                "localisation": localisation,
            },
            batch_size=shape,
        )
        out = TensorDict(
            {
                SIM_KEY: sim,
                "cost_terms": terms.apply(lambda value: value.to(torch.float32)),
                "step_count": step_count,
                "metrics": self._metrics(accumulators, tracking, localisation),
                "overridden": hovering,
                "terminated": terminated,
                "truncated": truncated,
                "done": done,
            },
            batch_size=shape,
        )
        self._write_observation(sim, out)
        self._write_costs(out, cost, stability, ending, done)
        if not self.flatten_agents:
            out[AGENT_APPROACH], out[AGENT_SERVICE_START] = (flag[..., None] for flag in legs)
        return out

    def _write_costs(
        self,
        out: TensorDictBase,
        cost: torch.Tensor,
        stability: torch.Tensor,
        ending: torch.Tensor,
        done: torch.Tensor,
    ) -> None:
        """The reward keys: summed over the AUVs (flat layout), or per AUV with per-AUV flags:
        the AUV that ends the episode is terminated, the others truncated (they bootstrap:
        their cost-to-go does not end with their peer's exit)."""
        cost = cost.to(torch.float32)[..., None]
        stability = stability.to(torch.float32)[..., None]
        if self.flatten_agents:
            out["cost"] = cost.sum(-2)
            out["reward"] = -out["cost"]
            out["stability_cost"] = stability.sum(-2)
            return
        agents = {
            "observation": out["agents", "observation"],
            "cost": cost,
            "reward": -cost,
            "stability_cost": stability,
        }
        if self.per_agent_done:
            agent_terminated = ending[..., None]
            agent_done = done[..., None, :].expand_as(agent_terminated)
            agents["terminated"] = agent_terminated
            agents["truncated"] = agent_done & ~agent_terminated
            agents["done"] = agent_done.clone()
        out["agents"] = TensorDict(agents, batch_size=(*out.batch_size, self.num_auvs))

    def _localise(
        self,
        running: TensorDictBase,
        estimate: torch.Tensor,
        fix: torch.Tensor,
        valid: torch.Tensor,
        position: torch.Tensor,
    ) -> TensorDict:
        """Add this decision's position errors (m) of the filter and of the arrived fixes."""
        kf_error = torch.linalg.vector_norm(estimate[..., :3] - position, dim=-1)
        fix_error = torch.linalg.vector_norm(fix - position, dim=-1)
        finite = kf_error.isfinite()
        dtype = running["kf_error_sum"].dtype
        return TensorDict(
            {
                "kf_error_sum": running["kf_error_sum"]
                + torch.where(finite, kf_error, 0.0).sum(-1).to(dtype),
                "kf_samples": running["kf_samples"] + finite.sum(-1).to(dtype),
                "usbl_error_sum": running["usbl_error_sum"]
                + torch.where(valid & finite, fix_error, 0.0).sum(-1).to(dtype),
                "usbl_samples": running["usbl_samples"] + (valid & finite).sum(-1).to(dtype),
            },
            batch_size=running.batch_size,
        )
