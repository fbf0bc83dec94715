r"""The scripted data-collection expert's heading rules, one small function each.

:func:`~torchrl_auv.iout.expert_setpoints` builds an :class:`ExpertView` of each AUV (what it
knows: its estimated pose, the point it steers for, the current estimate, the distances to
the area's edges) and passes the direction it wants to head through :data:`HEADING_RULES` in
order; each rule keeps the direction or replaces it where its situation holds (the module
docstring of :mod:`~torchrl_auv.iout.expert` says why each exists):

1. :func:`approach_from_downstream` (in a current: the planned way to arrive bow upstream)
2. :func:`arrive_along_edge` (still water, point steered for near an edge)
3. :func:`run_past_close_target` (still water, target inside the turning circle)
4. :func:`make_room_to_descend` (node too close to reach its depth in time)
5. :func:`hold_course_without_target`
6. :func:`repel_other_auvs`
7. :func:`stay_off_edges` (near an edge, do not head out)

then :func:`turn_clear_of_edges` on the heading itself. The point steered for is already
shifted inside the area (:func:`point_steered_for`). All functions are batched over
``[*B, N]`` (directions ``[*B, N, 2]``, north and east; metres and radians).

Examples:
    >>> import torch
    >>> from torchrl_auv.iout.expert_config import ExpertConfig
    >>> pose = torch.zeros(1, 1, 6)
    >>> view = ExpertView.of(pose, torch.tensor([[[0.0, 50.0, 40.0]]]), ExpertConfig())
    >>> view.goal_dir.tolist()  # the target is due east
    [[[0.0, 1.0]]]
    >>> [rule.__name__ for rule in HEADING_RULES][:2]
    ['approach_from_downstream', 'arrive_along_edge']
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import torch

from torchrl_auv.iout.approach import approach_direction, unit
from torchrl_auv.iout.dubins import WORDS, dubins_lengths, dubins_points
from torchrl_auv.iout.expert_config import ExpertConfig

__all__ = [
    "HEADING_RULES",
    "INWARD_NORMALS",
    "ExpertView",
    "approach_from_downstream",
    "arrive_along_edge",
    "hold_course_without_target",
    "make_room_to_descend",
    "point_steered_for",
    "repel_other_auvs",
    "run_past_close_target",
    "stay_off_edges",
    "turn_clear_of_edges",
]

#: The model's steady surge per rpm (m/s): 2.5536 m/s at 1525 rpm.
_MPS_PER_RPM = 2.5536 / 1525.0

#: The edges' inward unit normals (north, east), in the order of ``edges``: x, X - x, y, Y - y.
INWARD_NORMALS = ((1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0))


def point_steered_for(
    to_target: torch.Tensor, edges: torch.Tensor | None, cfg: ExpertConfig
) -> torch.Tensor:
    """The target relative to the AUV (``[*B, N, 2]``, m), moved to at least
    ``edge_clearance_m`` from every edge, by at most ``max_inward_shift_m``."""
    if edges is None:
        return to_target
    shift = (cfg.edge_clearance_m - _edges_of(edges, to_target)).clamp(0.0, cfg.max_inward_shift_m)
    return to_target + (shift[..., 0::2] - shift[..., 1::2])


@dataclass
class ExpertView:
    """What the expert knows of each AUV (estimated pose, target, current, edges) and the
    quantities its rules share, ``[*B, N, .]``. Build it with :meth:`of`."""

    position: torch.Tensor  # [*B, N, 3] (m)
    psi: torch.Tensor  # [*B, N] heading (rad)
    bow: torch.Tensor  # [*B, N, 2] unit heading direction
    to_target: torch.Tensor  # [*B, N, 2] the point steered for, relative (m)
    distance: torch.Tensor  # [*B, N, 1] its horizontal distance (m)
    goal_dir: torch.Tensor  # [*B, N, 2] unit direction to it (the bow if on it)
    target_depth: torch.Tensor  # [*B, N] the node's depth (m)
    valid: torch.Tensor  # [*B, N] bool: the AUV has a target
    others: torch.Tensor  # [*B, N, K, 3] the other AUVs' positions (m)
    current: torch.Tensor | None  # [*B, N, 2] (m/s)
    edges: torch.Tensor | None  # [*B, N, 4] distances to the edges x, X - x, y, Y - y (m)
    inward: torch.Tensor | None  # [*B, N, 2] unit direction to the area's centre
    arrival: torch.Tensor  # [*B, N, 2] how to arrive: upstream in a current, else goal_dir
    flowing: torch.Tensor  # [*B, N, 1] bool: the current is above the threshold
    along_edge: torch.Tensor = field(init=False)  # [*B, N, 1] set by arrive_along_edge

    def __post_init__(self) -> None:
        self.along_edge = torch.zeros_like(self.flowing)

    @classmethod
    def of(
        cls,
        auv_pose: torch.Tensor,
        target_position: torch.Tensor,
        cfg: ExpertConfig,
        *,
        others: torch.Tensor | None = None,
        has_target: torch.Tensor | None = None,
        current: torch.Tensor | None = None,
        edges: torch.Tensor | None = None,
    ) -> ExpertView:
        """The view of :func:`~torchrl_auv.iout.expert_setpoints`'s arguments."""
        position, psi = auv_pose[..., :3], auv_pose[..., 5]
        valid = torch.ones_like(psi, dtype=torch.bool) if has_target is None else has_target
        others = position[..., None, :0, :] if others is None else others
        to_target = point_steered_for(target_position[..., :2] - position[..., :2], edges, cfg)
        bow = torch.stack((torch.cos(psi), torch.sin(psi)), -1)
        distance = torch.linalg.vector_norm(to_target, dim=-1, keepdim=True)
        goal_dir = torch.where(distance > 1e-6, to_target / distance.clamp_min(1e-6), bow)
        arrival, flowing = _arrival_direction(goal_dir, current, cfg)
        inward = None if edges is None else unit(0.5 * (edges[..., 1::2] - edges[..., 0::2]))
        return cls(
            position,
            psi,
            bow,
            to_target,
            distance,
            goal_dir,
            target_position[..., 2],
            valid,
            others,
            current,
            edges,
            inward,
            arrival,
            flowing,
        )

    def edge_radius(self, cfg: ExpertConfig) -> torch.Tensor:
        """``[*B, N, 1]``: the width of the band along the edges in which the AUV does not
        head out (narrower in a current, where the approach from downstream comes first)."""
        radius = torch.where(self.flowing, cfg.edge_radius_current_m, cfg.edge_radius_m)
        return radius.to(self.goal_dir.dtype)


def approach_from_downstream(
    direction: torch.Tensor, v: ExpertView, cfg: ExpertConfig
) -> torch.Tensor:
    """In a current: inside the cone behind the node head for the node, outside it follow the
    cheapest Dubins path to the approach line (``plan_radius_m`` > 0), arriving bow upstream."""
    approach, in_cone = approach_direction(
        -v.to_target,
        v.arrival,
        offset_m=cfg.downstream_offset_m,
        avoid_radius_m=cfg.avoid_radius_m,
        prefer=v.inward,
        cone_deg=cfg.approach_cone_deg,
        keep_out_m=cfg.keep_out_m,
        bow=v.bow,
    )
    if v.current is not None and cfg.plan_radius_m > 0 and bool(v.flowing.any()):
        planned = _planned_direction(v.to_target, v.psi, v.arrival, v.current, v.edges, cfg)
        approach = torch.where(in_cone, approach, planned)
    return torch.where(v.flowing, approach, direction)


def arrive_along_edge(direction: torch.Tensor, v: ExpertView, cfg: ExpertConfig) -> torch.Tensor:
    """Still water, a point steered for near an edge that the way to it heads out across:
    arrive along the edge instead (sets ``v.along_edge``)."""
    if v.edges is None:
        return direction
    edge_approach, along_edge = _edge_arrival(direction, v.to_target, v.edges, v.inward, v.bow, cfg)
    v.along_edge = along_edge & ~v.flowing
    return torch.where(v.along_edge, edge_approach, direction)


def run_past_close_target(
    direction: torch.Tensor, v: ExpertView, cfg: ExpertConfig
) -> torch.Tensor:
    """Still water: a target inside the turning circle on the AUV's side would be orbited, not
    reached; run straight on until it is outside (:math:`|d|^2 < 2 R |lateral|` is inside)."""
    lateral = (v.to_target * torch.stack((-v.bow[..., 1], v.bow[..., 0]), -1)).sum(-1)
    orbit = v.distance[..., 0].square() < 2.0 * cfg.turn_radius_m * lateral.abs()
    return torch.where(orbit[..., None] & ~v.flowing & ~v.along_edge, v.bow, direction)


def make_room_to_descend(direction: torch.Tensor, v: ExpertView, cfg: ExpertConfig) -> torch.Tensor:
    """A node too close to reach its depth in time (``glide_ratio``, depth changes above
    ``glide_min_m``): head for the area's centre while descending."""
    if v.edges is None:
        return direction
    climb = (v.target_depth - cfg.standoff_m - v.position[..., 2]).abs()
    steep = (v.distance[..., 0] < cfg.glide_ratio * climb) & (climb > cfg.glide_min_m)
    return torch.where(steep[..., None], v.inward.to(direction.dtype), direction)


def hold_course_without_target(
    direction: torch.Tensor, v: ExpertView, cfg: ExpertConfig
) -> torch.Tensor:
    """An AUV without a target keeps its heading."""
    return torch.where(v.valid[..., None], direction, v.bow)


def repel_other_auvs(direction: torch.Tensor, v: ExpertView, cfg: ExpertConfig) -> torch.Tensor:
    r"""Add :math:`k \sum_q (r - |p - q|) / r \, (p - q) / |p - q|` over the other AUVs closer
    than the repulsion radius :math:`r` (module docstring of :mod:`~torchrl_auv.iout.expert`)."""
    away = v.position[..., None, :2] - v.others[..., :2]  # [*B, N, K, 2]
    gap = torch.linalg.vector_norm(away, dim=-1, keepdim=True)
    strength = ((cfg.repulsion_radius_m - gap) / cfg.repulsion_radius_m).clamp_min(0.0)
    return direction + (cfg.repulsion_gain * strength * away / gap.clamp_min(1e-6)).sum(-2)


def stay_off_edges(direction: torch.Tensor, v: ExpertView, cfg: ExpertConfig) -> torch.Tensor:
    """Within the edge band (:meth:`ExpertView.edge_radius`) never head out, unless the point
    steered for lies farther out still: keep the along-edge part and add an inward part
    growing to ``edge_gain`` at the edge."""
    if v.edges is None:
        return direction
    radius = v.edge_radius(cfg).to(direction.dtype)
    normals = direction.new_tensor(INWARD_NORMALS)
    goal_edges = _edges_of(v.edges, v.to_target)
    for k in range(4):
        normal = normals[k]
        distance = v.edges[..., k : k + 1].to(direction.dtype)
        outward = (direction * normal).sum(-1, keepdim=True) < 0
        needed = goal_edges[..., k : k + 1] < distance
        along = direction - (direction * normal).sum(-1, keepdim=True) * normal
        along = along + cfg.edge_gain * normal * ((radius - distance) / radius).clamp_min(0)
        direction = torch.where((distance < radius) & outward & ~needed, along, direction)
    return direction


#: The heading rules, in the order :func:`~torchrl_auv.iout.expert_setpoints` applies them.
HEADING_RULES: tuple[Callable[[torch.Tensor, ExpertView, ExpertConfig], torch.Tensor], ...] = (
    approach_from_downstream,
    arrive_along_edge,
    run_past_close_target,
    make_room_to_descend,
    hold_course_without_target,
    repel_other_auvs,
    stay_off_edges,
)


def turn_clear_of_edges(heading: torch.Tensor, v: ExpertView, cfg: ExpertConfig) -> torch.Tensor:
    """The last rule, on the heading (rad): near edges, a turn of more than 90 deg goes the way
    whose bow sweeps the outward normal of the nearer edge least (:func:`_turn_clear_of_edges`)."""
    if v.edges is None:
        return heading
    return _turn_clear_of_edges(heading, v.psi, v.edges, v.edge_radius(cfg))


# -- geometry the rules share ------------------------------------------------------------
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
    ahead = torch.full(
        (*psi.shape, len(WORDS), 1),
        cfg.plan_lookahead_m,
        dtype=to_node.dtype,
        device=to_node.device,
    )
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
    direction, _ = approach_direction(
        -to_target,
        arrival,
        offset_m=cfg.edge_offset_m,
        avoid_radius_m=cfg.avoid_radius_m,
        prefer=inward,
        cone_deg=cfg.approach_cone_deg,
        keep_out_m=cfg.keep_out_m,
        bow=bow,
    )
    return direction, outward.amax(-1, keepdim=True) > 0.2
