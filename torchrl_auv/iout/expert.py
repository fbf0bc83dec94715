r"""Setpoints of the scripted data-collection expert: go to the target, avoid the other AUVs.

Heading: toward the target in the horizontal plane, bent away from every other AUV closer
than the repulsion radius :math:`r`:

.. math::

    u = \frac{t - p}{\lVert t - p\rVert}
        + k \sum_{q:\ \lVert p - q\rVert < r} \frac{r - \lVert p - q\rVert}{r}
          \frac{p - q}{\lVert p - q\rVert},\qquad \psi_d = \operatorname{atan2}(u_y, u_x)

(positions horizontal, NED: :math:`\psi` from north toward east). Depth: ``standoff_m`` above
the target node, and never deeper than ``standoff_m`` above the seabed under the AUV when that
is given; at least ``min_depth_m``. Propeller: ``cruise_rpm``, slowed to ``approach_rpm``
within ``approach_radius_m`` (horizontal) of the target so that the vehicle circles the node
tightly while it descends into the service radius. An AUV without a target keeps its heading
and depth at ``idle_rpm``. The env turns setpoints into actions
(depth change ``0.8 a0`` m, heading change ``0.15 a1`` rad, rpm ``380 (a2 + 3)``).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

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

    Examples:
        >>> ExpertConfig().cruise_rpm
        1200.0
    """

    cruise_rpm: float = 1200.0
    approach_rpm: float = 760.0
    approach_radius_m: float = 20.0
    idle_rpm: float = 760.0
    standoff_m: float = 5.0
    min_depth_m: float = 2.0
    repulsion_radius_m: float = 20.0
    repulsion_gain: float = 2.0

    def __post_init__(self) -> None:
        for name in (
            "cruise_rpm",
            "approach_rpm",
            "approach_radius_m",
            "idle_rpm",
            "standoff_m",
            "min_depth_m",
            "repulsion_gain",
        ):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        if not self.repulsion_radius_m > 0:
            raise ValueError(f"repulsion_radius_m must be > 0, got {self.repulsion_radius_m}")


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

    Returns:
        ``(depth, heading, rpm)``, each ``[*B, N]`` (m, rad in ``(-pi, pi]``, rpm).

    Examples:
        >>> pose = torch.zeros(1, 2, 6)
        >>> pose[0, 1, 1] = 3.0  # second AUV 3 m east of the first
        >>> target = torch.tensor([[[100.0, 0.0, 50.0], [100.0, 3.0, 50.0]]])
        >>> depth, heading, rpm = expert_setpoints(pose, target, other_positions(pose[..., :3]))
        >>> depth.tolist(), rpm.tolist()
        ([[45.0, 45.0]], [[1200.0, 1200.0]])
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
    heading_dir = torch.stack((torch.cos(psi), torch.sin(psi)), -1)
    norm = torch.linalg.vector_norm(to_target, dim=-1, keepdim=True)
    goal_dir = torch.where(norm > 1e-6, to_target / norm.clamp_min(1e-6), heading_dir)
    goal_dir = torch.where(valid[..., None], goal_dir, heading_dir)

    away = position[..., None, :2] - other_auv_positions[..., :2]  # [*B, N, K, 2]
    gap = torch.linalg.vector_norm(away, dim=-1, keepdim=True)
    strength = ((cfg.repulsion_radius_m - gap) / cfg.repulsion_radius_m).clamp_min(0.0)
    push = (cfg.repulsion_gain * strength * away / gap.clamp_min(1e-6)).sum(-2)
    direction = goal_dir + push
    heading = torch.atan2(direction[..., 1], direction[..., 0])

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
