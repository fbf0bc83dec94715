r"""Station keeping over a sensor node while the AUV is in service (spec v2, "Hovering").

A REMUS-100 cannot hover, and its smallest turning circle (about 19-21 m radius at full rudder,
at any propeller speed) is wider than the 18 m service radius, so it cannot loiter on a circle
around the node. It can hold station the way a torpedo-shaped vehicle does in a current: bow
into the water flow, propeller speed matched to it. The guidance works on horizontal NED
vectors, from what the vehicle knows (its Kalman position and compass heading, the node's
position, its current estimate :math:`\hat c` and its altimeter):

.. math::

    v_d = \operatorname{sat}_{v_{max}}\big(k\,(n - p)\big),
    \qquad w = v_d - \hat c,

with :math:`v_d` the ground velocity wanted (toward the node :math:`n`, proportional to the
horizontal error, capped; 0 within the dead band, and in still water while the node is more
than 60 deg off the bow: turning round to reach it would take the vehicle out on a 20 m
circle, whereas a vehicle that lets the node lie behind it stays close by), and :math:`w` the
velocity through the water that produces it. In a current (:math:`|\hat c|` at least
``min_water_speed_mps``) :math:`w` keeps an upstream part of at least 0 and a cross-flow part
of at most :math:`\tan` ``max_crab_deg`` times the larger of that and
``min_water_speed_mps``: the bow stays within ``max_crab_deg`` of upstream, and the vehicle
moves downstream by going slower than the current, down to stopping the propeller and letting
the current carry it, instead of turning round on a 20 m circle (which it would overshoot
and repeat). The heading setpoint is the direction of :math:`w`. The propeller speed gives
the surge through the water :math:`w\cos e` (its component along the present heading, with
:math:`e` the heading error) at the speed over ground wanted, :math:`|w + \hat c|`: the
thrust that holds :math:`w\cos e` in still water (at :math:`597\,\mathrm{rpm}` per m/s, the
model's steady rpm) inverted at that speed
(:func:`~torchrl_auv.physics.remus100.rpm_for_thrust`). The model's propeller sees the speed
over ground, so a vehicle held still against a current needs fewer rpm than the still-water
rule gives; with the still-water rule it crept upstream out of the service radius. The
still-water rule itself is linear and under-drives at low speed, which the position feedback
makes up for (both measured: ``docs/design_notes.md``, station keeping). The propeller
turns at ``turn_rpm`` while the heading error exceeds 45 deg (the fins need flow to turn),
and stops when :math:`|w|` is below ``min_water_speed_mps`` (no current and on station: the
vehicle coasts, the neutrally buoyant hull keeps its depth). Depth: ``altitude_m`` above the
seabed from the altimeter, or above the node where the altimeter has no reading.

In a current the vehicle thus ends up bow into it, making way through the water at the
current's speed (the propeller must beat 1 m/s in ``ves``). An AUV that starts its service
heading downstream has to turn round first, which carries it a turning diameter (40 m)
sideways: it often cannot come back within a long service. Approaching a node from
downstream avoids that (the scripted expert plans its way there,
:mod:`~torchrl_auv.iout.expert`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from torchrl_auv.physics.remus100 import propeller_forces, rpm_for_thrust

__all__ = ["StationKeepingConfig", "station_keeping_setpoints"]


@dataclass(frozen=True)
class StationKeepingConfig:
    """Parameters of :func:`station_keeping_setpoints` (all ours, tuned in closed loop).

    Attributes:
        altitude_m: altitude above the seabed to hold (m); the node is on the seabed, so the
            3-D distance to it is at least this.
        gain: :math:`k` (1/s), ground speed wanted per metre of horizontal error.
        max_ground_speed_mps: :math:`v_{max}` (m/s).
        deadband_m: no ground velocity is wanted within this horizontal distance (m).
        min_water_speed_mps: below this :math:`|w|` the propeller stops (m/s).
        turn_rpm: propeller speed while turning toward :math:`w` (rpm; fast: the turning
            circle is about the same at any speed, so the turn is over sooner and the vehicle
            drifts less meanwhile).
        rpm_per_mps: steady propeller speed per m/s of surge (the REMUS-100 model reaches
            2.554 m/s at 1525 rpm).
        max_rpm: the highest propeller speed used (rpm).
        max_crab_deg: in a current, the largest angle between the bow and upstream (deg).
        radius_margin_m: with ``radius_m`` given, the dead band ends this far inside the
            horizontal radius left at the vehicle's height (m) ...
        min_deadband_m: ... but is never smaller than this (m).

    Examples:
        >>> StationKeepingConfig().altitude_m
        8.0
    """

    altitude_m: float = 8.0
    gain: float = 0.1
    max_ground_speed_mps: float = 1.0
    deadband_m: float = 12.0
    min_water_speed_mps: float = 0.25
    turn_rpm: float = 1520.0
    rpm_per_mps: float = 1525.0 / 2.5536
    max_rpm: float = 1520.0
    max_crab_deg: float = 40.0
    radius_margin_m: float = 3.0
    min_deadband_m: float = 2.0

    def __post_init__(self) -> None:
        for name in (
            "altitude_m",
            "gain",
            "max_ground_speed_mps",
            "deadband_m",
            "min_water_speed_mps",
            "turn_rpm",
            "rpm_per_mps",
            "max_rpm",
            "max_crab_deg",
            "radius_margin_m",
            "min_deadband_m",
        ):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")


def _bow_upstream(
    water: torch.Tensor, current: torch.Tensor, cfg: StationKeepingConfig
) -> torch.Tensor:
    """``water`` (``[*B, 2]``, m/s) with its upstream part at least 0 and its cross-flow part
    at most ``tan(max_crab_deg)`` times the larger of that and ``min_water_speed_mps``: the
    bow stays within ``max_crab_deg`` of upstream (or across the flow, when the vehicle only
    moves across it), and ground speed downstream comes from going slower than the current,
    down to letting it carry the vehicle, rather than from turning round on a 20 m circle."""
    up = -current / torch.linalg.vector_norm(current, dim=-1, keepdim=True).clamp_min(1e-6)
    along = (water * up).sum(-1, keepdim=True)
    upstream = along.clamp_min(0.0)
    cross = water - along * up
    cap = upstream.clamp_min(cfg.min_water_speed_mps) * math.tan(math.radians(cfg.max_crab_deg))
    cross_speed = torch.linalg.vector_norm(cross, dim=-1, keepdim=True).clamp_min(1e-6)
    return upstream * up + cross * (cap / cross_speed).clamp_max(1.0)


def station_keeping_setpoints(
    position: torch.Tensor,
    heading: torch.Tensor,
    node: torch.Tensor,
    current: torch.Tensor,
    altitude: torch.Tensor,
    config: StationKeepingConfig | None = None,
    *,
    radius_m: float | None = None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    r"""Depth, heading and propeller setpoints that hold an AUV over its node (module doc).

    Args:
        position: ``[*B, 3]`` the vehicle's NED position estimate (m).
        heading: ``[*B]`` its heading estimate (rad).
        node: ``[*B, 3]`` NED position of the node served (m).
        current: ``[*B, 2]`` current estimate, north and east (m/s).
        altitude: ``[*B]`` altimeter reading (m), NaN where it has none.
        config: guidance parameters (default :class:`StationKeepingConfig`).
        radius_m: the 3-D radius to stay within (m; the task's service radius), or ``None``.
            Given, in a current the dead band shrinks to ``radius_margin_m`` inside the
            horizontal radius left at the vehicle's height above the node,
            :math:`\sqrt{r^2 - h^2}`: a vehicle that could not yet descend (the fins need
            flow) is held closer. Not in still water, where the vehicle coasts rather than
            turn round and a smaller band measured worse (``docs/design_notes.md``).

    Returns:
        ``(depth, heading, rpm)`` setpoints, each ``[*B]`` (m, rad, rpm).

    Examples:
        >>> p, n = torch.tensor([[0.0, 0.0, 37.0]]), torch.tensor([[0.0, 0.0, 45.0]])
        >>> still, up = torch.zeros(1, 2), torch.tensor([[0.0, -1.0]])  # 1 m/s toward west
        >>> station_keeping_setpoints(p, torch.zeros(1), n, still, torch.tensor([7.5]))
        (tensor([36.5000]), tensor([0.]), tensor([0.]))
        >>> depth, psi, rpm = station_keeping_setpoints(p, torch.tensor([math.pi / 2]), n, up,
        ...                                             torch.tensor([float("nan")]))
        >>> depth.item(), round(psi.item(), 4), round(rpm.item())  # bow east, into the flow
        (37.0, 1.5708, 369)
    """
    cfg = StationKeepingConfig() if config is None else config
    gap = node[..., :2] - position[..., :2]
    distance = torch.linalg.vector_norm(gap, dim=-1, keepdim=True)
    wanted = cfg.gain * gap
    speed = cfg.gain * distance
    wanted = wanted * (cfg.max_ground_speed_mps / speed.clamp_min(cfg.max_ground_speed_mps))
    bow = torch.stack((torch.cos(heading), torch.sin(heading)), -1).to(gap.dtype)
    ahead = (gap * bow).sum(-1, keepdim=True) >= 0.5 * distance  # within 60 deg of the bow
    still = torch.linalg.vector_norm(current, dim=-1, keepdim=True) < cfg.min_water_speed_mps
    band = torch.full_like(distance, cfg.deadband_m)
    if radius_m is not None:  # in a current: the dead band inside the 3-D radius
        height = (node[..., 2:3] - position[..., 2:3]).to(distance.dtype)
        flat = (radius_m**2 - height.square()).clamp_min(0.0).sqrt() - cfg.radius_margin_m
        band = torch.where(still, band, torch.minimum(band, flat.clamp_min(cfg.min_deadband_m)))
    idle = (distance < band) | (still & ~ahead)
    wanted = torch.where(idle, torch.zeros_like(wanted), wanted)
    water = wanted - current.to(wanted.dtype)
    water = torch.where(still, water, _bow_upstream(water, current.to(water.dtype), cfg))
    water_speed = torch.linalg.vector_norm(water, dim=-1)
    moving = water_speed > cfg.min_water_speed_mps
    heading_sp = torch.where(moving, torch.atan2(water[..., 1], water[..., 0]), heading)
    error = torch.atan2(torch.sin(heading_sp - heading), torch.cos(heading_sp - heading)).abs()
    along = water_speed * torch.cos(error).clamp_min(0.0)
    # the thrust that holds `along` through still water, at the speed over ground wanted
    thrust, _ = propeller_forces(cfg.rpm_per_mps * along, along)
    ground = torch.linalg.vector_norm(water + current.to(water.dtype), dim=-1)
    rpm = rpm_for_thrust(thrust, ground).clamp(0.0, cfg.max_rpm)
    rpm = torch.where(error > math.pi / 4, torch.full_like(rpm, cfg.turn_rpm), rpm)
    rpm = torch.where(moving, rpm, torch.zeros_like(rpm))
    ground_level = torch.where(altitude.isnan(), node[..., 2], position[..., 2] + altitude)
    depth = (ground_level - cfg.altitude_m).clamp_min(0.0)
    return depth, heading_sp, rpm
