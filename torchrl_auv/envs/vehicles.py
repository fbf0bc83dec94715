"""One agent decision of a fleet of REMUS-100s: 20 physics steps with controller, sea and sensors.

Both environments (:class:`~torchrl_auv.envs.AUVTrackingEnv`,
:class:`~torchrl_auv.envs.DataCollectionEnv`) run the same inner loop; it lives here so that the
env classes stay thin. Per physics step (``dt`` = 0.05 s):

1. the controller reads the vehicle's *estimated* state (Kalman position/velocity, AHRS roll,
   pitch and rates, compass heading) and the setpoints, and commands fins and propeller;
2. the ocean advances (Gauss-Markov current, clock) and the vehicle steps in the water velocity
   at its position; depth is kept in ``[0, seabed]``;
3. the filter predicts and fuses DVL, depth and compass readings.

The USBL fix, once per decision, is left to the env (it knows where the ASV is).

A decision's random numbers (ocean and sensors) are drawn in two calls up front from the
env's generator, which is also faster than four small draws per physics step.
"""

from __future__ import annotations

import torch
from tensordict import TensorDict, TensorDictBase

from torchrl_auv.control import Controller, wrap_angle
from torchrl_auv.estimation import Localiser, SensorNoise, compass, depth_sensor, dvl
from torchrl_auv.physics import ocean
from torchrl_auv.physics.energy import shaft_power
from torchrl_auv.physics.limits import depth_limits
from torchrl_auv.physics.remus100 import rotation_matrix
from torchrl_auv.physics.simulation import step_in_ocean

__all__ = ["DECISION_STATS", "VehicleStack", "estimated_state"]

#: running sums of one decision, per vehicle, returned by :meth:`VehicleStack.decide`
DECISION_STATS = (
    "steps",
    "heading_error_sum",
    "heading_error_sq",
    "depth_error_sum",
    "depth_error_sq",
    "speed_sum",
    "shaft_power_sum",
)


def estimated_state(
    eta: torch.Tensor, nu: torch.Tensor, kf_mean: torch.Tensor, kf_heading: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """The controller's and policy's view of a vehicle: ``(eta_hat, nu_hat)``, ``[*V, 6]`` each.

    Position and NED velocity come from the Kalman filter (``kf_mean`` ``[*V, 6]``), heading
    from the compass (``kf_heading`` ``[*V]``, rad), roll, pitch and the body rates from the
    AHRS (taken as exact from the true ``eta``/``nu``); the body velocity is the filter's NED
    velocity rotated into the body frame.
    """
    attitude = torch.stack((eta[..., 3], eta[..., 4], kf_heading), -1)
    rot = rotation_matrix(attitude)
    v_body = (rot.transpose(-1, -2) @ kf_mean[..., 3:].unsqueeze(-1)).squeeze(-1)
    return torch.cat([kf_mean[..., :3], attitude], -1), torch.cat([v_body, nu[..., 3:]], -1)


class VehicleStack:
    """Runs one decision (``decision_steps`` physics steps) for a batch of vehicles.

    Vehicles have batch ``[*V]``; the ocean has batch ``[*S]`` with ``V = (*S, n)`` for fleets
    (every vehicle of a scene sees the same ocean at its own position) or ``V = S``.

    Args:
        sea: the sea state (a :class:`~torchrl_auv.physics.ocean.SeaState`).
        controller: the low-level controller.
        noise: onboard sensor noise.
        dt: physics step (s).
        decision_steps: physics steps per decision.

    Examples:
        >>> from torchrl_auv.control import make_controller
        >>> stack = VehicleStack(ocean.get_sea_state("es"), make_controller("pid"))
        >>> g = torch.Generator().manual_seed(0)
        >>> eta = torch.zeros(3, 6)
        >>> eta[:, 2] = 10.0
        >>> nu = torch.zeros(3, 6)
        >>> nu[:, 0] = 1.5
        >>> vehicles = stack.init(eta, nu, torch.zeros(3, 3))
        >>> sea = ocean.reset_ocean("es", (3,), generator=g)
        >>> setpoint = torch.tensor([[10.0, 0.0, 1200.0]] * 3)
        >>> vehicles, sea, stats = stack.decide(vehicles, setpoint, sea, 50.0, generator=g)
        >>> vehicles["truth", "eta"].shape, stats["steps"].tolist()
        (torch.Size([3, 6]), [20.0, 20.0, 20.0])
    """

    def __init__(
        self,
        sea: ocean.SeaState,
        controller: Controller,
        noise: SensorNoise | None = None,
        *,
        dt: float = 0.05,
        decision_steps: int = 20,
    ) -> None:
        self.sea = sea
        self.controller = controller
        self.noise = SensorNoise() if noise is None else noise
        self.localiser = Localiser(self.noise)
        self.dt = dt
        self.decision_steps = decision_steps

    def init(
        self,
        eta: torch.Tensor,
        nu: torch.Tensor,
        actuators: torch.Tensor,
        *,
        position_sigma: float = 1.0,
    ) -> TensorDict:
        """Vehicle state ``[*V]``: ``truth`` (eta, nu, actuators), ``kf`` (mean, cov, heading)
        started on the true position (sigma ``position_sigma`` m) and NED velocity, and zeroed
        controller memory."""
        shape = eta.shape[:-1]
        mean, cov = self.localiser.init(eta[..., :3], position_sigma=position_sigma)
        rot = rotation_matrix(eta[..., 3:])
        mean[..., 3:] = (rot @ nu[..., :3].unsqueeze(-1)).squeeze(-1)
        return TensorDict(
            {
                "truth": {"eta": eta, "nu": nu, "actuators": actuators},
                "kf": {"mean": mean, "cov": cov, "heading": eta[..., 5].clone()},
                "controller": self.controller.init_memory(shape, dtype=eta.dtype),
            },
            batch_size=shape,
        )

    def estimate(self, vehicles: TensorDictBase) -> tuple[torch.Tensor, torch.Tensor]:
        """:func:`estimated_state` of a vehicle-state TensorDict."""
        return estimated_state(
            vehicles["truth", "eta"],
            vehicles["truth", "nu"],
            vehicles["kf", "mean"],
            vehicles["kf", "heading"],
        )

    def decide(
        self,
        vehicles: TensorDictBase,
        setpoint: torch.Tensor,
        sea_state: TensorDict,
        seabed_depth: torch.Tensor | float,
        *,
        generator: torch.Generator,
    ) -> tuple[TensorDict, TensorDict, TensorDict]:
        """Run one decision with fixed ``setpoint`` ``[*V, 3]`` (depth m, heading rad, rpm).

        Args:
            vehicles: from :meth:`init` or a previous call, batch ``[*V]`` (left unchanged).
            setpoint: controller setpoints for the whole decision.
            sea_state: ocean state, batch ``[*S]`` (a prefix of ``[*V]``).
            seabed_depth: seabed under each vehicle (m), float or ``[*V]``, for the depth clamp.
            generator: the only source of randomness.

        Returns:
            ``(vehicles, sea_state, stats)``; ``stats`` (batch ``[*V]``) holds the sums over
            the physics steps of :data:`DECISION_STATS`: step count, ``|heading error|`` and
            its square (rad, setpoint vs true), ``|depth error|`` and its square (m), speed
            ``|v|`` (m/s) and propeller shaft power (W).
        """
        dt, noise, loc = self.dt, self.noise, self.localiser
        shape = vehicles.batch_size
        extra = len(shape) - len(sea_state.batch_size)
        dtype, device = setpoint.dtype, setpoint.device
        steps = self.decision_steps
        sea_noise = torch.randn(
            (steps, 2, *sea_state.batch_size), generator=generator, dtype=dtype, device=device
        )
        sensor_noise = torch.randn(
            (steps, *shape, 5), generator=generator, dtype=dtype, device=device
        )
        eta, nu, act = (vehicles["truth", k] for k in ("eta", "nu", "actuators"))
        mean, cov, heading = (vehicles["kf", k] for k in ("mean", "cov", "heading"))
        memory = vehicles["controller"]
        zero = torch.zeros(shape, dtype=dtype, device=device)
        e_h_sum, e_h_sq, e_d_sum, e_d_sq, speed_sum, power_sum = (zero,) * 6
        for k in range(steps):
            eta_hat, nu_hat = estimated_state(eta, nu, mean, heading)
            command, memory = self.controller(setpoint, eta_hat, nu_hat, memory, dt)
            sea_state = ocean.step_ocean(
                sea_state, self.sea, dt, generator=None, standard_normal=sea_noise[k]
            )
            sea_here = sea_state
            for _ in range(extra):
                sea_here = sea_here.unsqueeze(len(sea_here.batch_size))
            if extra:
                sea_here = sea_here.expand(shape)
            eta, nu, act = step_in_ocean(eta, nu, act, command, sea_here, dt)
            eta, nu, _, _ = depth_limits(eta, nu, seabed_depth)
            mean, cov = loc.predict(mean, cov, dt)
            draw = sensor_noise[k]
            heading = compass(eta[..., 5], noise.compass, None, standard_normal=draw[..., 4])
            attitude = torch.stack((eta[..., 3], eta[..., 4], heading), -1)
            mean, cov = loc.update_onboard(
                mean,
                cov,
                dvl(nu, noise.dvl, None, standard_normal=draw[..., :3]),
                attitude,
                depth_sensor(eta[..., 2], noise.depth, None, standard_normal=draw[..., 3]),
            )
            e_h = wrap_angle(setpoint[..., 1] - eta[..., 5]).abs()
            e_d = (setpoint[..., 0] - eta[..., 2]).abs()
            speed = torch.linalg.vector_norm(nu[..., :3], dim=-1)
            e_h_sum, e_h_sq = e_h_sum + e_h, e_h_sq + e_h * e_h
            e_d_sum, e_d_sq = e_d_sum + e_d, e_d_sq + e_d * e_d
            speed_sum = speed_sum + speed
            power_sum = power_sum + shaft_power(act[..., 2], speed)
        out = TensorDict(
            {
                "truth": {"eta": eta, "nu": nu, "actuators": act},
                "kf": {"mean": mean, "cov": cov, "heading": heading},
                "controller": memory,
            },
            batch_size=shape,
        )
        stats = TensorDict(
            dict(
                zip(
                    DECISION_STATS,
                    (zero + steps, e_h_sum, e_h_sq, e_d_sum, e_d_sq, speed_sum, power_sum),
                    strict=True,
                )
            ),
            batch_size=shape,
        )
        return out, sea_state, stats
