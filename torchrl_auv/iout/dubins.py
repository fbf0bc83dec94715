r"""Dubins paths: the shortest way for a vehicle with a minimum turning radius to reach a pose.

A vehicle moving at constant speed with a bounded turn rate, from a pose
:math:`(p_0, \psi_0)` to a pose :math:`(p_g, \psi_g)`, has a shortest path made of arcs of the
minimum radius :math:`R` and straight segments (Dubins 1957). We use the four words with a
straight middle segment (LSL, RSR, LSR, RSL), which always contain a feasible path; the two
three-arc words, shorter only when start and goal are within about :math:`4R`, are left out.

Coordinates are any right-handed or left-handed plane frame with the heading measured from
the first axis toward the second (NED north-east with :math:`\psi` from north toward east
works as is): a turn sign :math:`s = +1` increases :math:`\psi`, :math:`s = -1` decreases it.
With :math:`n(\theta) = (-\sin\theta, \cos\theta)`, a vehicle at heading :math:`\theta` on a
circle of centre :math:`c` and turn sign :math:`s` is at :math:`c - sR\,n(\theta)`.

* Same turn signs: the straight runs along :math:`c_2 - c_1` (angle :math:`\gamma`), length
  :math:`D = \lVert c_2 - c_1\rVert`.
* Opposite signs (:math:`D \ge 2R`): the straight's heading is
  :math:`\varphi = \gamma + s_1 \arcsin(2R/D)`, its length :math:`\sqrt{D^2 - 4R^2}`.

Each arc turns by :math:`(s(\theta_{end} - \theta_{start})) \bmod 2\pi`.
"""

from __future__ import annotations

import math

import torch

__all__ = ["WORDS", "dubins_lengths", "dubins_points"]

#: The four words as (first turn sign, last turn sign): LSL, RSR, LSR, RSL (L = +1).
WORDS = ((1.0, 1.0), (-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0))


def _normal(theta: torch.Tensor) -> torch.Tensor:
    return torch.stack((-torch.sin(theta), torch.cos(theta)), -1)


def _mod2pi(angle: torch.Tensor) -> torch.Tensor:
    return torch.remainder(angle, 2.0 * math.pi)


def dubins_lengths(
    start: torch.Tensor,
    start_heading: torch.Tensor,
    goal: torch.Tensor,
    goal_heading: torch.Tensor,
    radius: float,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Segment lengths of the four CSC words, and the straight's heading.

    Args:
        start, goal: ``[*B, 2]`` positions (m).
        start_heading, goal_heading: ``[*B]`` headings (rad).
        radius: turning radius :math:`R` (m, > 0).

    Returns:
        ``(lengths [*B, 4, 3], straight_heading [*B, 4])``: first arc, straight, last arc
        (m) per word of :data:`WORDS`; ``inf`` where a word is infeasible.

    Examples:
        >>> z = torch.zeros(1)
        >>> lengths, _ = dubins_lengths(torch.zeros(1, 2), z, torch.tensor([[50.0, 0.0]]), z, 10.0)
        >>> lengths[0, 0].tolist()  # straight ahead: no turn, 50 m
        [0.0, 50.0, 0.0]
    """
    lengths, headings = [], []
    for s1, s2 in WORDS:
        c1 = start + s1 * radius * _normal(start_heading)
        c2 = goal + s2 * radius * _normal(goal_heading)
        v = c2 - c1
        d = torch.linalg.vector_norm(v, dim=-1)
        gamma = torch.atan2(v[..., 1], v[..., 0])
        if s1 == s2:
            phi, straight = gamma, d
            feasible = torch.ones_like(d, dtype=torch.bool)
        else:
            ratio = (2.0 * radius / d.clamp_min(1e-9)).clamp(max=1.0)
            phi = gamma + s1 * torch.asin(ratio)
            straight = (d.square() - 4.0 * radius**2).clamp_min(0.0).sqrt()
            feasible = d >= 2.0 * radius
        first = radius * _mod2pi(s1 * (phi - start_heading))
        last = radius * _mod2pi(s2 * (goal_heading - phi))
        word = torch.stack((first, straight, last), -1)
        lengths.append(torch.where(feasible[..., None], word, torch.full_like(word, math.inf)))
        headings.append(phi)
    return torch.stack(lengths, -2), torch.stack(headings, -1)


def dubins_points(
    start: torch.Tensor,
    start_heading: torch.Tensor,
    lengths: torch.Tensor,
    straight_heading: torch.Tensor,
    radius: float,
    arc_length: torch.Tensor,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Positions and headings at given distances along each word's path.

    Args:
        start: ``[*B, 2]``; start_heading: ``[*B]``.
        lengths, straight_heading: from :func:`dubins_lengths` (finite lengths).
        radius: turning radius (m).
        arc_length: ``[*B, 4, K]`` distances along the path (m), clamped to its length.

    Returns:
        ``(points [*B, 4, K, 2], headings [*B, 4, K])``.

    Examples:
        >>> start, psi = torch.zeros(1, 2), torch.zeros(1)
        >>> goal, turned = torch.tensor([[10.0, 10.0]]), torch.tensor([math.pi / 2])
        >>> lengths, straight = dubins_lengths(start, psi, goal, turned, 10.0)
        >>> round(lengths[0, 0].sum().item(), 4)  # LSL: a quarter circle of radius 10 m
        15.708
        >>> points, _ = dubins_points(start, psi, lengths.clamp_max(1e3), straight, 10.0,
        ...                           torch.full((1, 4, 1), 2.5 * math.pi))
        >>> [round(v, 3) for v in points[0, 0, 0].tolist()]  # half way: 45 deg round
        [7.071, 2.929]
    """
    s1 = lengths.new_tensor([w[0] for w in WORDS])[:, None]  # [4, 1]
    s2 = lengths.new_tensor([w[1] for w in WORDS])[:, None]
    first, straight, last = (lengths[..., i : i + 1] for i in range(3))  # [*B, 4, 1]
    ell = torch.minimum(arc_length, first + straight + last)
    psi0 = start_heading[..., None, None]
    p0 = start[..., None, None, :]
    phi = straight_heading[..., None]
    c1 = p0 + (s1 * radius)[..., None] * _normal(psi0)
    # on the first arc
    theta_a = psi0 + s1 * ell / radius
    point_a = c1 - (s1 * radius)[..., None] * _normal(theta_a)
    # on the straight
    p1 = c1 - (s1 * radius)[..., None] * _normal(phi)
    along = (ell - first).clamp_min(0.0)
    point_b = p1 + along[..., None] * torch.stack((torch.cos(phi), torch.sin(phi)), -1)
    # on the last arc
    p2 = p1 + straight[..., None] * torch.stack((torch.cos(phi), torch.sin(phi)), -1)
    c2 = p2 + (s2 * radius)[..., None] * _normal(phi)
    theta_c = phi + s2 * (ell - first - straight).clamp_min(0.0) / radius
    point_c = c2 - (s2 * radius)[..., None] * _normal(theta_c)
    on_first = ell < first
    on_straight = ~on_first & (ell < first + straight)
    points = torch.where(
        on_first[..., None], point_a, torch.where(on_straight[..., None], point_b, point_c)
    )
    headings = torch.where(on_first, theta_a, torch.where(on_straight, phi.expand_as(ell), theta_c))
    return points, headings
