r"""Approach geometry: the heading that brings a vehicle to a node along a given direction.

A torpedo-shaped AUV turns on a circle of about 20 m radius, so *how* it arrives at a node
matters: bow into the current it can hold station, bow downstream it cannot without turning
round. :func:`approach_direction` steers for a point ``offset_m`` *behind* the node (seen along
the wanted arrival direction :math:`\hat a`) until the vehicle is in the cone of half-angle
``cone_deg`` behind the node (``facing_cone_deg`` for a vehicle already facing along
:math:`\hat a`), at least ``offset_m / 2`` back; from there it heads for the node itself,
arriving along :math:`\hat a`. Within ``avoid_radius_m`` of the node, a vehicle whose way to
the approach point crosses the node's neighbourhood goes round it: tangentially, on the side
of ``prefer`` when given, bending outward the more the closer it is within ``keep_out_m``.
Horizontal NED vectors throughout.
"""

from __future__ import annotations

import math

import torch

__all__ = ["approach_direction", "unit"]


def unit(vector: torch.Tensor) -> torch.Tensor:
    """``vector / |vector|`` over the last dim (zero vectors stay finite)."""
    return vector / torch.linalg.vector_norm(vector, dim=-1, keepdim=True).clamp_min(1e-6)


def approach_direction(
    offset: torch.Tensor,
    arrival: torch.Tensor,
    *,
    offset_m: float,
    avoid_radius_m: float = 0.0,
    prefer: torch.Tensor | None = None,
    cone_deg: float = 45.0,
    keep_out_m: float = 30.0,
    bow: torch.Tensor | None = None,
    facing_cone_deg: float = 60.0,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Unit direction to head in, and whether the vehicle is already in the final cone.

    Args:
        offset: ``[*B, 2]`` the vehicle's position relative to the node (m).
        arrival: ``[*B, 2]`` unit vector, the direction the vehicle should arrive heading.
        offset_m: distance of the approach point behind the node (m).
        avoid_radius_m: go round the node within this distance (m); 0: never.
        prefer: ``[*B, 2]`` the side to go round on (e.g. toward the area's centre).
        cone_deg: half-angle of the final cone (deg).
        keep_out_m: going round, the vehicle bends away from the node more strongly inside
            this distance (m).
        bow: ``[*B, 2]`` unit vector of the vehicle's heading; a vehicle already facing
            within 45 deg of the arrival direction uses the wider ``facing_cone_deg`` (turning
            round to reach the narrow cone would bring it closer to the node than it is).

    Returns:
        ``(direction [*B, 2], in_cone [*B, 1] bool)``; in the cone the direction points at
        the node.

    Examples:
        >>> up = torch.tensor([[-1.0, 0.0]])  # arrive heading south
        >>> approach_direction(torch.tensor([[30.0, 0.0]]), up, offset_m=20.0)  # north: in
        (tensor([[-1.,  0.]]), tensor([[True]]))
        >>> d, cone = approach_direction(torch.tensor([[-30.0, 0.0]]), up, offset_m=20.0)
        >>> d.tolist(), cone.item()  # south of the node: go round to the north
        ([[1.0, 0.0]], False)
    """
    behind = -arrival
    along = (offset * behind).sum(-1, keepdim=True)  # metres behind the node
    lateral = torch.linalg.vector_norm(offset - along * behind, dim=-1, keepdim=True)
    slope = torch.full_like(along, math.tan(math.radians(cone_deg)))
    if bow is not None:
        facing = (bow.to(arrival.dtype) * arrival).sum(-1, keepdim=True) > math.cos(math.pi / 4)
        slope = torch.where(facing, math.tan(math.radians(facing_cone_deg)), slope)
    in_cone = (along >= offset_m / 2) & (lateral <= along * slope)
    aim = unit(offset_m * behind - offset)
    radial = unit(offset)
    tangent = torch.stack((-radial[..., 1], radial[..., 0]), -1)
    side = aim if prefer is None else aim + prefer.to(aim.dtype)
    tangent = torch.where((tangent * side).sum(-1, keepdim=True) >= 0, tangent, -tangent)
    distance = torch.linalg.vector_norm(offset, dim=-1, keepdim=True)
    crossing = (aim * radial).sum(-1, keepdim=True) < 0
    around = (distance < avoid_radius_m) & crossing
    # tangential, bending outward the more the closer to the node (inside keep_out_m)
    push = 0.3 + 2.0 * ((keep_out_m - distance) / keep_out_m).clamp_min(0.0)
    aim = torch.where(around, unit(tangent + push * radial), aim)
    return torch.where(in_cone, unit(-offset), aim), in_cone
