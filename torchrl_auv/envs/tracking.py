"""``AUVTrackingEnv``: one REMUS-100 following a random heading/depth/speed reference.

The small, fast environment for unit tests, examples and the Lyapunov experiments. It wires the
layers below together and holds no task logic of its own beyond the reward: physics
(:mod:`torchrl_auv.physics`), a low-level controller (:mod:`torchrl_auv.control`), sensors and
the Kalman filter (:mod:`torchrl_auv.estimation`).
"""

from __future__ import annotations

import math

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from torchrl_auv.control import wrap_angle
from torchrl_auv.envs.device import on_env_device, step_on_cpu
from torchrl_auv.envs.specs import (
    checked_action,
    checked_batch_size,
    controller_from_name,
    scene_generator,
    unbounded_spec_like,
)
from torchrl_auv.envs.vehicles import (
    TRACKING_SUMS,
    VehicleStack,
    add_tracking_sums,
    tracking_errors,
)
from torchrl_auv.estimation import gnss_error_init, gnss_error_step, usbl_fix_from_asv
from torchrl_auv.physics import ocean
from torchrl_auv.physics.limits import diverged

__all__ = ["AUVTrackingEnv"]

OBS_DIM = 16
RPM_SCALE = 380.0  # rpm per unit action: n = 380 (a2 + 3), 760-1520 rpm
DEPTH_STEP = 0.8  # m per unit action (setpoint change)
HEADING_STEP = 0.15  # rad per unit action (setpoint change)
DIVERGENCE_COST = 10.0  # cost of the decision that ends in a diverged state


class AUVTrackingEnv(EnvBase):
    """Heading, depth and speed tracking with one REMUS-100 (env card).

    **Description.** A REMUS-100 (``docs/spec/remus100.md``) must follow a reference of
    depth, heading and surge speed that changes every ``segment_seconds`` (drawn per episode:
    depth U(5, 30) m, heading U(-pi, pi) rad, speed U(1.2, 2.2) m/s). The agent acts once per
    second by moving the setpoints of a low-level controller (S-Surface, PID or SMC) that runs
    at 20 Hz, in the chosen sea state, and sees the vehicle only through its sensors and a
    Kalman filter.

    **Action** ``[*B, 3]`` in [-1, 1]:

    ====  ==============================  ===================================
    idx   meaning                         effect
    ====  ==============================  ===================================
    0     depth setpoint change           ``z_sp += 0.8 a0`` m (kept in [0, 100])
    1     heading setpoint change         ``psi_sp += 0.15 a1`` rad
    2     propeller speed                 ``n_sp = 380 (a2 + 3)`` rpm (760-1520)
    ====  ==============================  ===================================

    Values outside [-1, 1] are clipped to it; a NaN or infinite entry, or an action of another
    shape, is a ``ValueError`` naming ``action`` and the expected shape.

    **Observation** ``"observation"`` ``[*B, 16]`` (float32), from the Kalman-filter estimate
    (hats) and the AHRS, never the true pose: ``(z_ref - z^)/10``, ``sin``/``cos`` of
    ``psi_ref - psi^``, ``u_ref - u^`` (m/s), ``u^, v^, w^`` (body, m/s), ``p, q, r`` (rad/s),
    roll, pitch (rad), ``(z_sp - z^)/10``, ``sin``/``cos`` of ``psi_sp - psi^``, ``n_sp/1525``.

    **Cost and reward.** ``cost = |wrap(psi_ref - psi)|/pi + |z_ref - z|/10 +
    |u_ref - u|/2`` on the true state at the end of the decision (>= 0, LAC's convention);
    ``reward = -cost``. Both ``[*B, 1]``. ``reward`` is the one reward key (``env.reward_key``
    through any wrapper); ``cost`` is an observation key (``env.cost_keys``; 0 at reset).

    **Start state.** Cruising: depth U(5, 15) m, heading U(-pi, pi), surge 1.5 m/s,
    the setpoints on the current pose, 1200 rpm; a fresh ocean per episode.

    **Episode end.** ``terminated`` when the divergence guard fires (non-finite or absurd
    state; that decision costs ``DIVERGENCE_COST`` = 10, an observation with non-finite
    entries is zeroed); ``truncated`` after ``max_steps`` decisions.
    ``done = terminated | truncated``.

    **Localisation.** Every physics step the filter fuses compass, depth and, with bottom lock
    (altitude at most 30 m; the seabed here is 200 m deep, so in this env never), the DVL; once
    per decision a USBL fix from an ASV keeping station 30 m north of the AUV, with the sea
    state's errors (:func:`~torchrl_auv.estimation.usbl_fix_from_asv`): range and bearing
    noise, the ASV's wave-driven attitude residual, dropouts, and the ASV's GNSS error
    (Gauss-Markov, ``"asv_gnss_error"``) as the fix's bias.

    **Other keys.** ``("truth", "eta"|"nu"|"actuators")`` and ``"asv_gnss_error"``
    ``[*B, 2]`` (north, east, m) (true state, for metrics and plots; policies must not read
    them), ``("kf", "mean"|"cov")``, ``"setpoint"``, ``"reference"``,
    ``("controller", ...)``, ``"ocean"``, and ``("metrics", name)`` with the running episode
    values of ``heading_error_mean``, ``heading_error_std`` (rad), ``depth_error_mean``,
    ``depth_error_std`` (m), between the controller setpoints and the true state over all
    physics steps (final when ``done``).

    **Arguments.** ``batch_size``; ``sea_state`` ("ideal", "es", "ves" or a ``SeaState``);
    ``controller`` ("s_surface", "pid", "smc"); ``seed``; ``max_steps`` (decisions, default
    300); ``segment_seconds`` (default 60); ``compile_physics`` (the 20 Hz inner loop through
    ``torch.compile``, see :class:`~torchrl_auv.envs.vehicles.VehicleStack`); ``device``
    (where its outputs and the carried state live; the simulation runs on the CPU,
    :mod:`~torchrl_auv.envs.device`).

    **Version history.** v0: first release.

    Examples:
        >>> env = AUVTrackingEnv(batch_size=[2], sea_state="es", seed=0)
        >>> td = env.rollout(3)
        >>> td["observation"].shape, td["next", "cost"].shape
        (torch.Size([2, 3, 16]), torch.Size([2, 3, 1]))
    """

    batch_locked = True

    def __init__(
        self,
        batch_size: torch.Size | list[int] | tuple[int, ...] = (),
        *,
        sea_state: str | ocean.SeaState = "ideal",
        controller: str = "s_surface",
        seed: int | None = None,
        max_steps: int = 300,
        segment_seconds: float = 60.0,
        compile_physics: bool = False,
        device: torch.device | str | None = None,
    ) -> None:
        self.sea = ocean.get_sea_state(sea_state)
        self.controller = controller_from_name(controller)
        if not (isinstance(max_steps, int) and max_steps >= 1):
            raise ValueError(f"max_steps must be an int >= 1, got {max_steps!r}")
        if not (math.isfinite(segment_seconds) and segment_seconds > 0):
            raise ValueError(f"segment_seconds must be finite and > 0, got {segment_seconds}")
        super().__init__(batch_size=checked_batch_size(batch_size), device=device)
        self.dt = 0.05
        self.decision_steps = 20
        self.max_steps = max_steps
        self.segment_steps = max(1, round(segment_seconds))
        self.num_segments = math.ceil(max_steps / self.segment_steps) + 1
        self.vehicles = VehicleStack(self.sea, self.controller, dt=self.dt, compile=compile_physics)
        self.noise, self.localiser = self.vehicles.noise, self.vehicles.localiser
        self.rng = torch.Generator()
        self.set_seed(seed)  # None: from entropy (scene_generator)
        self._make_specs()

    # -- specs ---------------------------------------------------------------------------
    def _make_specs(self) -> None:
        rng_state = self.rng.get_state()  # the spec sample must not consume the seed's draws
        sample = self._initial_state(self.batch_size)
        self.rng.set_state(rng_state)
        state = sample.exclude("observation")
        shape = self.batch_size
        self.observation_spec = Composite(
            observation=Unbounded(shape=(*shape, OBS_DIM), dtype=torch.float32),
            **{
                k: unbounded_spec_like(v)
                if isinstance(v, TensorDictBase)
                else Unbounded(shape=v.shape, dtype=v.dtype)
                for k, v in state.items()
            },
            shape=shape,
        )
        self.state_spec = Composite(
            {
                k: v.clone()
                for k, v in self.observation_spec.items()
                if k not in ("observation", "cost")
            },
            shape=shape,
        )
        self.action_spec = Bounded(low=-1.0, high=1.0, shape=(*shape, 3), dtype=torch.float32)
        self.done_spec = Composite(
            {
                k: Categorical(2, shape=(*shape, 1), dtype=torch.bool)
                for k in ("done", "terminated", "truncated")
            },
            shape=shape,
        )
        self.reward_spec = Composite(
            reward=Unbounded(shape=(*shape, 1), dtype=torch.float32), shape=shape
        )

    @property
    def cost_keys(self) -> list[str]:
        """``["cost"]``: an observation key (0 at reset, then the last decision's), not a
        reward key, so that ``env.reward_key`` is the one reward through every wrapper."""
        return ["cost"]

    def _set_seed(self, seed: int | None) -> None:
        self.rng = scene_generator(seed)

    # -- reset ---------------------------------------------------------------------------
    def _initial_state(self, shape: torch.Size) -> TensorDict:
        g, f32 = self.rng, torch.float32

        def uniform(low: float, high: float, *size: int) -> torch.Tensor:
            return low + (high - low) * torch.rand((*shape, *size), generator=g, dtype=f32)

        eta = torch.zeros(*shape, 6)
        eta[..., 2] = uniform(5.0, 15.0)
        eta[..., 5] = uniform(-math.pi, math.pi)
        nu = torch.zeros(*shape, 6)
        nu[..., 0] = 1.5
        actuators = torch.zeros(*shape, 3)
        actuators[..., 2] = 1200.0
        reference = torch.stack(
            (
                uniform(5.0, 30.0, self.num_segments),
                uniform(-math.pi, math.pi, self.num_segments),
                uniform(1.2, 2.2, self.num_segments),
            ),
            -1,
        )
        setpoint = torch.stack((eta[..., 2], eta[..., 5], actuators[..., 2]), -1)
        stats = TensorDict({k: torch.zeros(shape) for k in TRACKING_SUMS}, batch_size=shape)
        td = self.vehicles.init(eta, nu, actuators)
        td.update(
            {
                "setpoint": setpoint,
                "reference": reference,
                "ocean": ocean.reset_ocean(self.sea, shape, generator=g),
                "step_count": torch.zeros(*shape, 1, dtype=torch.int64),
                "stats": stats,
                "metrics": self._metrics(stats),
            }
        )
        td["asv_gnss_error"] = gnss_error_init((*shape, 2), self.sea.gnss_sigma, g)
        td["observation"] = self._observe(td)
        td["cost"] = torch.zeros(*shape, 1)  # no decision yet: no cost
        return td

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        return on_env_device(self, self._initial_state(self.batch_size))

    # -- step ----------------------------------------------------------------------------
    def _reference_now(self, td: TensorDictBase) -> torch.Tensor:
        segment = (td["step_count"] // self.segment_steps).clamp_max(self.num_segments - 1)
        index = segment.unsqueeze(-1).expand(*segment.shape[:-1], 1, 3)
        return td["reference"].gather(-2, index).squeeze(-2)

    def _observe(self, td: TensorDictBase) -> torch.Tensor:
        eta_hat, nu_hat = self.vehicles.estimate(td)
        ref = self._reference_now(td)
        sp = td["setpoint"]
        e_psi = ref[..., 1] - eta_hat[..., 5]
        e_sp = sp[..., 1] - eta_hat[..., 5]
        return torch.stack(
            (
                (ref[..., 0] - eta_hat[..., 2]) / 10.0,
                torch.sin(e_psi),
                torch.cos(e_psi),
                ref[..., 2] - nu_hat[..., 0],
                *nu_hat.unbind(-1),
                eta_hat[..., 3],
                eta_hat[..., 4],
                (sp[..., 0] - eta_hat[..., 2]) / 10.0,
                torch.sin(e_sp),
                torch.cos(e_sp),
                sp[..., 2] / 1525.0,
            ),
            -1,
        ).to(torch.float32)

    @staticmethod
    def _metrics(stats: TensorDictBase) -> TensorDict:
        return TensorDict(tracking_errors(stats), batch_size=stats.batch_size)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        return step_on_cpu(self, tensordict, self._simulate_step)  # envs.device

    def _simulate_step(self, tensordict: TensorDictBase) -> TensorDictBase:
        g = self.rng
        td = tensordict.select(*self.state_spec.keys(True, True), strict=True).clone(False)
        action = checked_action(tensordict["action"], (*self.batch_size, 3), "action")
        sp = td["setpoint"]
        setpoint = torch.stack(
            (
                (sp[..., 0] + DEPTH_STEP * action[..., 0]).clamp(0.0, 100.0),
                sp[..., 1] + HEADING_STEP * action[..., 1],
                RPM_SCALE * (action[..., 2] + 3.0),
            ),
            -1,
        )
        vehicles, sea_td, decision = self.vehicles.decide(
            td.select("truth", "kf", "controller"), setpoint, td["ocean"], 200.0, generator=g
        )
        stats = add_tracking_sums(td["stats"], decision)
        eta, nu, act = (vehicles["truth", k] for k in ("eta", "nu", "actuators"))
        mean, cov, heading = (vehicles["kf", k] for k in ("mean", "cov", "heading"))
        memory = vehicles["controller"]
        asv = torch.cat([eta[..., :2], torch.zeros_like(eta[..., :1])], -1)
        asv[..., 0] += 30.0  # the ASV keeps station 30 m north of the AUV
        sea = self.sea
        gnss = gnss_error_step(
            td["asv_gnss_error"],
            sea.gnss_sigma,
            sea.gnss_time_constant,
            self.decision_steps * self.dt,
            g,
        )
        fix, fix_cov, valid = usbl_fix_from_asv(eta[..., :3], asv, gnss, sea, g)
        mean, cov = self.localiser.update_usbl(mean, cov, fix, fix_cov, valid)

        step_count = td["step_count"] + 1
        out = TensorDict(
            {
                "truth": {"eta": eta, "nu": nu, "actuators": act},
                "kf": {"mean": mean, "cov": cov, "heading": heading},
                "setpoint": setpoint,
                "reference": td["reference"],
                "controller": memory,
                "ocean": sea_td,
                "step_count": step_count,
                "stats": stats,
                "metrics": self._metrics(stats),
                "asv_gnss_error": gnss,
            },
            batch_size=td.batch_size,
        )
        ref = self._reference_now(out)
        cost = (
            wrap_angle(ref[..., 1] - eta[..., 5]).abs() / math.pi
            + (ref[..., 0] - eta[..., 2]).abs() / 10.0
            + (ref[..., 2] - nu[..., 0]).abs() / 2.0
        ).unsqueeze(-1)
        bad = diverged(eta, nu, act).unsqueeze(-1)
        cost = torch.where(bad, torch.full_like(cost, DIVERGENCE_COST), cost).to(torch.float32)
        out["observation"] = torch.nan_to_num(self._observe(out), nan=0.0, posinf=0.0, neginf=0.0)
        out["cost"] = cost
        out["reward"] = -cost
        truncated = step_count >= self.max_steps
        out["terminated"] = bad
        out["truncated"] = truncated & ~bad
        out["done"] = bad | truncated
        return out
