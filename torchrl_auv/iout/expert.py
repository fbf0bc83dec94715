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
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from torchrl_auv.iout.approach import approach_direction, unit
from torchrl_auv.iout.dubins import WORDS, dubins_lengths, dubins_points

__all__ = ["ExpertConfig", "expert_setpoints", "other_positions"]

#: The model's steady surge per rpm (m/s): 2.5536 m/s at 1525 rpm.
_MPS_PER_RPM = 2.5536 / 1525.0

#: The edges' inward unit normals (north, east), in the order of ``edges``: x, X - x, y, Y - y.
INWARD_NORMALS = ((1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0))


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


def _edges_of(edges: torch.Tensor, offset: torch.Tensor) -> torch.Tensor:
    """Distances to the edges (``[*B, N, 4]``, as ``edges``) of the point ``offset``
    (``[*B, N, 2]``, m) away from the AUV whose distances are ``edges``."""
    x, y = offset[..., 0], offset[..., 1]
    return edges.to(offset.dtype) + torch.stack((x, -x, y, -y), -1)


def _arrival_direction(
    goal_dir: torch.Tensor, current: torch.Tensor | None, cfg: ExpertConfig
) -> tuple[torch.Tensor, torch.Tensor]:
    """``(direction, use)``: upstream where the current estimate exceeds the threshold."""
    if current is None:
        return goal_dir, torch.zeros_like(goal_dir[..., :1], dtype=torch.bool)
    current = current.to(goal_dir.dtype)
    flowing = torch.linalg.vector_norm(current, dim=-1, keepdim=True) > cfg.current_threshold_mps
    return torch.where(flowing, -unit(current), goal_dir), flowing


def _turn_clear_of_edges(
    heading: torch.Tensor, psi: torch.Tensor, edges: torch.Tensor, radius: torch.Tensor
) -> torch.Tensor:
    """``heading`` (rad), or a setpoint 90 deg the other way round from ``psi``: a turn of
    more than 90 deg goes the way whose bow sweeps the outward normals of the edges nearer
    than ``radius`` (``[*B, N, 1]``, m) least closely (a U-turn carries the vehicle a turning
    diameter sideways: better toward a far edge than a near one)."""
    turn = torch.atan2(torch.sin(heading - psi), torch.cos(heading - psi))
    outward = psi.new_tensor([math.pi, 0.0, -0.5 * math.pi, 0.5 * math.pi])  # x, X-x, y, Y-y
    rel = outward - psi[..., None]
    rel = torch.atan2(torch.sin(rel), torch.cos(rel))
    swept = (rel * turn[..., None] >= 0) & (rel.abs() <= turn.abs()[..., None])
    closeness = (radius - edges.to(psi.dtype)).clamp_min(0.0)  # 0 beyond the radius
    short = torch.where(swept, closeness, 0.0).amax(-1)
    long = torch.where(swept, 0.0, closeness).amax(-1)
    long_way = (turn.abs() > 0.5 * math.pi) & (long < short)
    other_way = psi - torch.sign(turn) * 0.5 * math.pi
    other_way = torch.atan2(torch.sin(other_way), torch.cos(other_way))
    return torch.where(long_way, other_way, heading)


def _planned_direction(
    to_node: torch.Tensor,
    psi: torch.Tensor,
    arrival: torch.Tensor,
    current: torch.Tensor,
    edges: torch.Tensor | None,
    cfg: ExpertConfig,
) -> torch.Tensor:
    r"""Unit heading along the cheapest Dubins path (:mod:`~torchrl_auv.iout.dubins`) to a pose
    on the approach line: ``plan_offsets_m`` behind the node, heading along ``arrival``.

    Planned in the water frame, in which a node fixed on the ground drifts against the
    current: a path of length :math:`L` (m) takes :math:`L / V` s at the cruise speed
    :math:`V`, so its goal is moved by :math:`-\hat c L / V` and its points are brought back
    to the ground by :math:`+\hat c\,\ell / V`. Cost: the path's length and the final
    straight to the node, plus penalties for coming within ``plan_clear_m`` of the node and
    within ``plan_margin_m`` of an edge. All ``[*B, N]``-batched; ``to_node`` is the node
    relative to the vehicle (m), ``psi`` its heading (rad), ``arrival`` a unit vector.
    """
    r = cfg.plan_radius_m
    speed = cfg.cruise_rpm * _MPS_PER_RPM
    drift = current.to(to_node.dtype) / speed  # ground metres per metre through the water
    start = torch.zeros_like(to_node)
    goal_heading = torch.atan2(arrival[..., 1], arrival[..., 0])
    frac = torch.linspace(0.0, 1.0, cfg.plan_samples, dtype=to_node.dtype, device=to_node.device)
    ahead = torch.full((*psi.shape, len(WORDS), 1), cfg.plan_lookahead_m, dtype=to_node.dtype,
                       device=to_node.device)  # fmt: skip
    costs, headings = [], []
    for offset in cfg.plan_offsets_m:
        goal = to_node - offset * arrival
        lengths, _ = dubins_lengths(start, psi, goal, goal_heading, r)
        shortest = lengths.sum(-1).amin(-1, keepdim=True)
        goal = goal - drift * torch.where(shortest.isfinite(), shortest, 0.0)
        lengths, straight = dubins_lengths(start, psi, goal, goal_heading, r)
        total = lengths.sum(-1)  # [*B, N, 4]
        ok = total.isfinite()
        lengths = torch.where(ok[..., None], lengths, 0.0)
        span = torch.where(ok, total, 0.0)
        along = span[..., None] * frac
        points, _ = dubins_points(start, psi, lengths, straight, r, along)
        points = points + along[..., None] * drift[..., None, None, :]  # back on the ground
        step = span / cfg.plan_samples
        gap = torch.linalg.vector_norm(points - to_node[..., None, None, :], dim=-1)
        cost = (
            total
            + offset
            + cfg.plan_node_weight * step * (cfg.plan_clear_m - gap).clamp_min(0.0).sum(-1)
        )
        if edges is not None:
            room = _edges_of(edges[..., None, None, :], points)  # [*B, N, 4, K, 4]
            short = (cfg.plan_margin_m - room).clamp_min(0.0).amax(-1).sum(-1)
            cost = cost + cfg.plan_area_weight * step * short
        costs.append(torch.where(ok, cost, math.inf))
        headings.append(dubins_points(start, psi, lengths, straight, r, ahead)[1][..., 0])
    best = torch.cat(costs, -1).argmin(-1, keepdim=True)
    heading = torch.cat(headings, -1).gather(-1, best)[..., 0]
    return torch.stack((torch.cos(heading), torch.sin(heading)), -1)


def _edge_arrival(
    goal_dir: torch.Tensor,
    to_target: torch.Tensor,
    edges: torch.Tensor,
    inward: torch.Tensor,
    bow: torch.Tensor,
    cfg: ExpertConfig,
) -> tuple[torch.Tensor, torch.Tensor]:
    """``(direction, use)``: where the point steered for lies within ``edge_arrival_m`` of an
    edge and the way to it heads out across that edge, the approach that arrives along the
    edge instead (the outward part of the arrival dropped; toward the centre in a corner)."""
    out = -goal_dir.new_tensor(INWARD_NORMALS)
    outward = (goal_dir[..., None, :] * out).sum(-1).clamp_min(0.0)  # [*B, N, 4]
    outward = torch.where(_edges_of(edges, to_target) < cfg.edge_arrival_m, outward, 0.0)
    tangential = goal_dir - (outward[..., None] * out).sum(-2)
    length = torch.linalg.vector_norm(tangential, dim=-1, keepdim=True)
    arrival = torch.where(length > 0.1, unit(tangential), inward.to(goal_dir.dtype))
    direction, _ = approach_direction(-to_target, arrival, offset_m=cfg.edge_offset_m,
                                      avoid_radius_m=cfg.avoid_radius_m, prefer=inward,
                                      cone_deg=cfg.approach_cone_deg, keep_out_m=cfg.keep_out_m,
                                      bow=bow)  # fmt: skip
    return direction, outward.amax(-1, keepdim=True) > 0.2


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
    position, psi = auv_pose[..., :3], auv_pose[..., 5]
    valid = (
        torch.ones(psi.shape, dtype=torch.bool, device=psi.device)
        if has_target is None
        else has_target
    )
    to_target = target_position[..., :2] - position[..., :2]
    if edges is not None:  # steer for a point up to 10 m inside a node near an edge
        shift = cfg.edge_clearance_m - _edges_of(edges, to_target)
        shift = shift.clamp(0.0, cfg.max_inward_shift_m)
        to_target = to_target + (shift[..., 0::2] - shift[..., 1::2])
    heading_dir = torch.stack((torch.cos(psi), torch.sin(psi)), -1)
    norm = torch.linalg.vector_norm(to_target, dim=-1, keepdim=True)
    goal_dir = torch.where(norm > 1e-6, to_target / norm.clamp_min(1e-6), heading_dir)
    arrival_dir, flowing = _arrival_direction(goal_dir, current, cfg)
    # the direction to the area's centre, from the distances to its edges
    inward = None if edges is None else unit(0.5 * (edges[..., 1::2] - edges[..., 0::2]))
    approach, in_cone = approach_direction(-to_target, arrival_dir,
                                           offset_m=cfg.downstream_offset_m,
                                           avoid_radius_m=cfg.avoid_radius_m, prefer=inward,
                                           cone_deg=cfg.approach_cone_deg,
                                           keep_out_m=cfg.keep_out_m, bow=heading_dir)  # fmt: skip
    planning = current is not None and cfg.plan_radius_m > 0 and bool(flowing.any())
    if planning:  # outside the final cone: plan the way
        planned = _planned_direction(to_target, psi, arrival_dir, current, edges, cfg)
        approach = torch.where(in_cone, approach, planned)
    goal_dir = torch.where(flowing, approach, goal_dir)
    along_edge = torch.zeros_like(flowing)
    if edges is not None:  # still water, steered point near an edge: arrive along the edge
        edge_approach, along_edge = _edge_arrival(goal_dir, to_target, edges, inward,
                                                  heading_dir, cfg)  # fmt: skip
        along_edge = along_edge & ~flowing
        goal_dir = torch.where(along_edge, edge_approach, goal_dir)
    # still water: a target inside the turning circle on its side is orbited, not reached;
    # run straight on until it is outside (|d|^2 < 2 R |lateral| is inside)
    lateral = (to_target * torch.stack((-heading_dir[..., 1], heading_dir[..., 0]), -1)).sum(-1)
    orbit = norm[..., 0].square() < 2.0 * cfg.turn_radius_m * lateral.abs()
    goal_dir = torch.where(orbit[..., None] & ~flowing & ~along_edge, heading_dir, goal_dir)
    if edges is not None:  # too steep to reach the node's depth in time: make room inward
        wanted_depth = target_position[..., 2] - cfg.standoff_m
        climb = (wanted_depth - position[..., 2]).abs()
        steep = (norm[..., 0] < cfg.glide_ratio * climb) & (climb > cfg.glide_min_m)
        goal_dir = torch.where(steep[..., None], inward.to(goal_dir.dtype), goal_dir)
    goal_dir = torch.where(valid[..., None], goal_dir, heading_dir)

    away = position[..., None, :2] - other_auv_positions[..., :2]  # [*B, N, K, 2]
    gap = torch.linalg.vector_norm(away, dim=-1, keepdim=True)
    strength = ((cfg.repulsion_radius_m - gap) / cfg.repulsion_radius_m).clamp_min(0.0)
    push = (cfg.repulsion_gain * strength * away / gap.clamp_min(1e-6)).sum(-2)
    direction = goal_dir + push
    if edges is not None:  # near an edge, never head out: keep only the along-edge part
        # in a current the approach from downstream comes first: a narrower band
        radius = torch.where(flowing, cfg.edge_radius_current_m, cfg.edge_radius_m)
        radius = radius.to(direction.dtype)
        normals = direction.new_tensor(INWARD_NORMALS)
        goal_edges = _edges_of(edges, to_target)
        for k in range(4):
            normal = normals[k]
            distance = edges[..., k : k + 1].to(direction.dtype)
            outward = (direction * normal).sum(-1, keepdim=True) < 0
            # heading out is fine while the point steered for lies farther out still
            needed = goal_edges[..., k : k + 1] < distance
            along = direction - (direction * normal).sum(-1, keepdim=True) * normal
            along = along + cfg.edge_gain * normal * ((radius - distance) / radius).clamp_min(0)
            direction = torch.where((distance < radius) & outward & ~needed, along, direction)
    heading = torch.atan2(direction[..., 1], direction[..., 0])
    if edges is not None:
        heading = _turn_clear_of_edges(heading, psi, edges, radius)

    depth = target_position[..., 2] - cfg.standoff_m
    if seabed_below is not None:
        depth = torch.minimum(depth, seabed_below - cfg.standoff_m)
    depth = torch.where(valid, depth.clamp_min(cfg.min_depth_m), position[..., 2])
    near = norm.squeeze(-1) < cfg.approach_radius_m
    rpm = torch.where(
        near, torch.full_like(psi, cfg.approach_rpm), torch.full_like(psi, cfg.cruise_rpm)
    )
    rpm = torch.where(valid, rpm, torch.full_like(psi, cfg.idle_rpm))
    return depth, heading, rpm
