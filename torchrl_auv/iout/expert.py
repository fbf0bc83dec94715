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
  downstream, and such services often ended outside the service radius (measured:
  ``docs/design_notes.md``, the expert).
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

import torch

from torchrl_auv.iout.expert_config import ExpertConfig
from torchrl_auv.iout.expert_rules import HEADING_RULES, ExpertView, turn_clear_of_edges

__all__ = ["ExpertConfig", "expert_setpoints", "other_positions"]


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
