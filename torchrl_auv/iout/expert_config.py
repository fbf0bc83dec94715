"""The scripted expert's parameters (:class:`ExpertConfig`), apart from the code that reads
them (:mod:`~torchrl_auv.iout.expert` and its heading rules,
:mod:`~torchrl_auv.iout.expert_rules`), so both import it and neither imports the other.

Examples:
    >>> ExpertConfig().standoff_m > 0
    True
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["ExpertConfig"]


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
