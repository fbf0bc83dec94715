r"""Setpoints of the scripted data-collection expert: go to the target, avoid the other AUVs.

Heading: toward the target in the horizontal plane, bent away from every other AUV closer
than the repulsion radius :math:`r`:

.. math::

    u = \frac{t - p}{\lVert t - p\rVert}
        + k \sum_{q:\ \lVert p - q\rVert < r} \frac{r - \lVert p - q\rVert}{r}
          \frac{p - q}{\lVert p - q\rVert},\qquad \psi_d = \operatorname{atan2}(u_y, u_x)

(positions horizontal, NED: :math:`\psi` from north toward east). A REMUS-100 turns on a
circle of about 20 m radius, wider than the 18 m service radius, so the expert plans *how* it
arrives and where it turns:

* In a current (estimate :math:`\hat c` above ``current_threshold_mps``) it arrives from
  downstream, bow into the flow, the attitude in which it can hold station
  (:mod:`~torchrl_auv.iout.station_keeping`). Until it is in the cone of half-angle
  ``approach_cone_deg`` behind the node it follows the cheapest of the Dubins paths
  (:mod:`~torchrl_auv.iout.dubins`, radius ``plan_radius_m``, planned in the water frame) to
  a pose on the line behind the node, heading upstream (``plan_offsets_m`` back), that keeps
  clear of the node and of the edges; in the cone it heads for the node
  (:func:`~torchrl_auv.iout.approach.approach_direction`). Service starts wherever the AUV
  comes within 18 m of its node, and one that starts bow downstream must turn round on a
  40 m circle: the heuristic this replaced (steer for the point ``downstream_offset_m``
  behind the node, go round it within ``avoid_radius_m``) came through the node bow
  downstream in about one service in six in ``es`` (shannon rate, seed 0), and half of those
  services ended outside the service radius.
* It steers for a point at least ``edge_clearance_m`` from every edge (up to
  ``max_inward_shift_m`` from a node near an edge), and within ``edge_radius_m`` of an edge
  (``edge_radius_current_m`` in a current) it does not head outward unless the point it steers
  for lies farther out: it runs along the edge instead.
* In still water, a point steered for within ``edge_arrival_m`` of an edge is approached
  along the edge, from ``edge_offset_m`` back (a vehicle that arrives heading out coasts on
  toward the edge and needs a turning diameter to come back in); a target inside the turning
  circle (``turn_radius_m``) on its side is left to fall behind while the AUV runs straight
  on (turning toward it, the vehicle would orbit it); and a turn of more than 90 deg near
  edges goes the way whose bow sweeps the outward normal of the nearer edge least.
* A node too close for the vehicle to reach its depth in time (``glide_ratio``, for depth
  changes above ``glide_min_m``) makes it head for the area's centre while it descends.

Depth: ``standoff_m`` above the target node, and never deeper than ``standoff_m`` above the
seabed under the AUV when that is given; at least ``min_depth_m``. Propeller: ``cruise_rpm``,
slowed to ``approach_rpm`` within ``approach_radius_m`` (horizontal) of the target. An AUV
without a target keeps its heading and depth at ``idle_rpm``. The env turns setpoints into
actions (depth change ``0.8 a0`` m, heading change ``0.15 a1`` rad, rpm ``380 (a2 + 3)``).

Each heading rule above is one named function of :mod:`~torchrl_auv.iout.expert_rules`,
applied in the order of :data:`~torchrl_auv.iout.expert_rules.HEADING_RULES`.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from torchrl_auv.iout.expert_rules import HEADING_RULES, ExpertView, turn_clear_of_edges

__all__ = ["ExpertConfig", "expert_setpoints", "other_positions"]


@dataclass(frozen=True)
class ExpertConfig:
    """Parameters of :func:`expert_setpoints` (all ours).

    Attributes:
        cruise_rpm: propeller speed while travelling (rpm); 1200 rpm gives about 2 m/s.
        approach_rpm: propeller speed near the target (rpm).
        approach_radius_m: horizontal distance to the target below which ``approach_rpm`` is
            used (m).
        idle_rpm: propeller speed without a target (rpm, the action's minimum).
        standoff_m: height above the target node / seabed to travel at (m).
        min_depth_m: shallowest depth setpoint (m).
        repulsion_radius_m: other AUVs closer than this push the heading away (m).
        repulsion_gain: :math:`k`, strength of the push relative to the target direction.
        edge_radius_m: within this distance of an edge the AUV does not head outward unless
            the point it steers for lies farther out: the outward part of its direction is
            dropped (m).
        edge_radius_current_m: the same in a current (smaller: there the approach from
            downstream, which holding station needs, must not be bent along an edge) (m).
        edge_gain: ... and replaced by an inward part growing to this (relative to the
            target direction) at the edge.
        edge_clearance_m, max_inward_shift_m: the AUV steers for a point at least
            ``edge_clearance_m`` from every edge, at most ``max_inward_shift_m`` from its node
            (still well inside the service radius), so it does not hug an edge (m).
        glide_ratio: horizontal metres the vehicle needs per metre of depth change; closer
            to its target than this times the depth still to go, the AUV heads for the
            area's centre while it descends (it would otherwise circle the node, wide) ...
        glide_min_m: ... when the depth still to go exceeds this (m; smaller changes are
            made on the way).
        current_threshold_mps: current speed above which the approach comes from downstream.
        downstream_offset_m: distance downstream of the node of the approach point (m).
        approach_cone_deg: half-angle of the cone behind the node from which the AUV heads
            for the node itself (deg).
        keep_out_m: going round its node, the AUV bends away from it the more strongly the
            closer it is within this distance (m).
        avoid_radius_m: horizontal distance to the node within which a vehicle outside the
            approach cone goes round the node (m).
        turn_radius_m: the vehicle's turning circle with a margin (m): in still water a target
            inside the circle on its side is not turned toward (the AUV would orbit it) but
            left to fall behind while the AUV runs straight on.
        edge_arrival_m: in still water, a point steered for nearer an edge than this is
            approached along the edge rather than heading out across it (m) ...
        edge_offset_m: ... from this far back (m).
        plan_radius_m: in a current, the turning radius of the Dubins paths the AUV plans to
            the approach line (m; the model turns on about 20 m); 0 turns planning off: the
            AUV then steers for the point ``downstream_offset_m`` behind the node, going round
            the node within ``avoid_radius_m``.
        plan_offsets_m: the poses planned for lie on the approach line this far downstream
            of the node, heading upstream (m); the cheapest path wins.
        plan_clear_m: a path coming closer to the node than this (m, horizontal) ...
        plan_node_weight: ... costs this many metres per metre of path per metre too close
            (the service would start with the bow the wrong way) ...
        plan_margin_m: ... and one closer to an edge than this (m) ...
        plan_area_weight: ... this many per metre of path per metre too close.
        plan_lookahead_m: the heading steered is the path's this far along it (m).
        plan_samples: points per path for those costs.

    Examples:
        >>> ExpertConfig().cruise_rpm
        1200.0
    """

    cruise_rpm: float = 1200.0
    approach_rpm: float = 760.0
    approach_radius_m: float = 20.0
    idle_rpm: float = 760.0
    standoff_m: float = 8.0
    min_depth_m: float = 2.0
    repulsion_radius_m: float = 20.0
    repulsion_gain: float = 2.0
    edge_radius_m: float = 60.0
    edge_radius_current_m: float = 20.0
    edge_gain: float = 1.0
    glide_ratio: float = 2.5
    glide_min_m: float = 10.0
    edge_clearance_m: float = 12.0
    max_inward_shift_m: float = 10.0
    current_threshold_mps: float = 0.25
    downstream_offset_m: float = 35.0
    avoid_radius_m: float = 45.0
    approach_cone_deg: float = 30.0
    keep_out_m: float = 30.0
    turn_radius_m: float = 22.0
    edge_arrival_m: float = 20.0
    edge_offset_m: float = 25.0
    plan_radius_m: float = 20.0
    plan_offsets_m: tuple[float, ...] = (20.0, 30.0, 45.0, 65.0)
    plan_clear_m: float = 19.0
    plan_margin_m: float = 5.0
    plan_node_weight: float = 20.0
    plan_area_weight: float = 5.0
    plan_lookahead_m: float = 8.0
    plan_samples: int = 32

    def __post_init__(self) -> None:
        for name in (
            "cruise_rpm",
            "approach_rpm",
            "approach_radius_m",
            "idle_rpm",
            "standoff_m",
            "min_depth_m",
            "repulsion_gain",
            "edge_gain",
            "glide_ratio",
            "glide_min_m",
            "edge_clearance_m",
            "max_inward_shift_m",
            "current_threshold_mps",
            "downstream_offset_m",
            "avoid_radius_m",
            "approach_cone_deg",
            "keep_out_m",
            "turn_radius_m",
            "edge_arrival_m",
            "edge_offset_m",
            "plan_radius_m",
            "plan_clear_m",
            "plan_margin_m",
            "plan_node_weight",
            "plan_area_weight",
            "plan_lookahead_m",
        ):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        object.__setattr__(self, "plan_offsets_m", tuple(float(v) for v in self.plan_offsets_m))
        if not self.plan_offsets_m or min(self.plan_offsets_m) < 0:
            raise ValueError(
                f"plan_offsets_m must be one or more distances >= 0 (m), got {self.plan_offsets_m}"
            )
        if self.plan_samples < 2:
            raise ValueError(f"plan_samples must be >= 2, got {self.plan_samples}")
        for name in ("repulsion_radius_m", "edge_radius_m", "edge_radius_current_m"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")


def other_positions(auv_positions: torch.Tensor) -> torch.Tensor:
    """For each AUV, the positions of the other AUVs.

    Args:
        auv_positions: ``[*B, N, D]``.

    Returns:
        ``[*B, N, N - 1, D]``; entry ``[..., j, :, :]`` lists every AUV but ``j`` in order.

    Examples:
        >>> other_positions(torch.tensor([[0.0], [1.0], [2.0]]))[..., 0].tolist()
        [[1.0, 2.0], [0.0, 2.0], [0.0, 1.0]]
    """
    n = auv_positions.shape[-2]
    ids = torch.arange(n, device=auv_positions.device)
    others = ids[None, :].expand(n, n)[ids[:, None] != ids[None, :]].reshape(n, n - 1)
    return auv_positions[..., others, :]


def expert_setpoints(
    auv_pose: torch.Tensor,
    target_position: torch.Tensor,
    other_auv_positions: torch.Tensor,
    config: ExpertConfig | None = None,
    *,
    has_target: torch.Tensor | None = None,
    seabed_below: torch.Tensor | None = None,
    current: torch.Tensor | None = None,
    edges: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Desired depth, heading and propeller speed of each AUV (module docstring).

    Args:
        auv_pose: ``[*B, N, 6]`` NED pose ``(x, y, z, phi, theta, psi)`` (m, rad).
        target_position: ``[*B, N, 3]`` NED position of each AUV's target node (m).
        other_auv_positions: ``[*B, N, K, 3]`` positions of the other AUVs (m), e.g.
            :func:`other_positions`; ``K = 0`` for a lone AUV.
        config: expert parameters (default :class:`ExpertConfig`).
        has_target: ``[*B, N]`` bool, ``False`` where the AUV has no target (default all
            ``True``).
        seabed_below: ``[*B, N]`` seabed depth under each AUV (m), to keep clear of it.
        current: ``[*B, N, 2]`` current estimate, north and east (m/s), for the approach
            from downstream (default: still water).
        edges: ``[*B, N, 4]`` distances to the area's edges (m) ``x``, ``X - x``, ``y``,
            ``Y - y``, for the inward shift of the point steered for, the glide rule and the
            edge band (module docstring; default: no area).

    Returns:
        ``(depth, heading, rpm)``, each ``[*B, N]`` (m, rad in ``(-pi, pi]``, rpm).

    Examples:
        >>> pose = torch.zeros(1, 2, 6)
        >>> pose[0, 1, 1] = 3.0  # second AUV 3 m east of the first
        >>> target = torch.tensor([[[100.0, 0.0, 50.0], [100.0, 3.0, 50.0]]])
        >>> depth, heading, rpm = expert_setpoints(pose, target, other_positions(pose[..., :3]))
        >>> depth.tolist(), rpm.tolist()
        ([[42.0, 42.0]], [[1200.0, 1200.0]])
        >>> bool(heading[0, 0] < 0 < heading[0, 1])  # pushed apart: west and east of north
        True
    """
    cfg = ExpertConfig() if config is None else config
    view = ExpertView.of(
        auv_pose,
        target_position,
        cfg,
        others=other_auv_positions,
        has_target=has_target,
        current=current,
        edges=edges,
    )
    direction = view.goal_dir
    for rule in HEADING_RULES:
        direction = rule(direction, view, cfg)
    heading = turn_clear_of_edges(torch.atan2(direction[..., 1], direction[..., 0]), view, cfg)

    # depth: standoff above the node, and above the seabed under the AUV when given
    depth = view.target_depth - cfg.standoff_m
    if seabed_below is not None:
        depth = torch.minimum(depth, seabed_below - cfg.standoff_m)
    depth = torch.where(view.valid, depth.clamp_min(cfg.min_depth_m), view.position[..., 2])
    # propeller: cruise, slower near the target, idle without one
    near = view.distance.squeeze(-1) < cfg.approach_radius_m
    rpm = torch.where(near, cfg.approach_rpm, cfg.cruise_rpm).to(view.psi.dtype)
    rpm = torch.where(view.valid, rpm, torch.full_like(view.psi, cfg.idle_rpm))
    return depth, heading, rpm
