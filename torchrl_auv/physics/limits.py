r"""Environment limits the REMUS-100 model lacks: free surface, seabed, divergence.

The model of :mod:`torchrl_auv.physics.remus100` has no free surface and no seabed (``z`` never
enters the dynamics and may become negative). These separate, optional layers let an
environment apply them after each :func:`~torchrl_auv.physics.remus100.step`:

* :func:`depth_limits` clamps the depth into ``[0, seabed]`` and zeroes the part of the NED
  vertical velocity that points out of the water column, and flags which vehicles touched;
* :func:`diverged` flags non-finite or absurd states, which callers turn into termination.
"""

from __future__ import annotations

import math

import torch

from torchrl_auv.physics._ops import small_matmul
from torchrl_auv.physics.remus100 import rotation_matrix

__all__ = ["depth_limits", "diverged"]


def depth_limits(
    eta: torch.Tensor,
    nu: torch.Tensor,
    seabed_depth: torch.Tensor | float,
    *,
    check: bool = True,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    r"""Clamp depth into ``[0, seabed_depth]`` and stop motion through the boundary.

    Where the vehicle left the water column, ``z`` is clamped and the body velocity loses the
    component along NED ``z`` that points outwards:

    .. math::

        v_{ned} = R v,\quad v_{ned,z} \leftarrow 0 \text{ (if outward)},\quad
        v \leftarrow R^\top v_{ned}

    Args:
        eta: ``[*B, 6]`` NED pose (``z`` positive down, m).
        nu: ``[*B, 6]`` body velocities.
        seabed_depth: seabed depth below the vehicle (m, > 0), a float or ``[*B]``.
        check: validate the inputs (``False`` in compiled inner loops: no host sync).

    Returns:
        ``(eta, nu, at_surface, at_seabed)``: clamped copies and two boolean ``[*B]`` flags.

    >>> eta = torch.tensor([0.0, 0.0, -0.3, 0.0, 0.0, 0.0])
    >>> nu = torch.tensor([1.0, 0.0, -0.2, 0.0, 0.0, 0.0])
    >>> eta2, nu2, surf, bed = depth_limits(eta, nu, 40.0)
    >>> eta2[2].item(), nu2[2].item(), surf.item(), bed.item()
    (0.0, 0.0, True, False)
    """
    if eta.shape[-1] != 6 or nu.shape[-1] != 6:
        raise ValueError(
            f"eta and nu must be shaped [*B, 6], got {tuple(eta.shape)}, {tuple(nu.shape)}"
        )
    seabed = torch.as_tensor(seabed_depth, dtype=eta.dtype, device=eta.device)
    if check and bool((seabed <= 0).any()):
        raise ValueError("seabed_depth must be > 0 (m)")
    depth = eta[..., 2]
    at_surface = depth < 0
    at_seabed = depth > seabed
    rot = rotation_matrix(eta[..., 3:])
    v_ned = small_matmul(rot, nu[..., :3].unsqueeze(-1)).squeeze(-1)
    outward = (at_surface & (v_ned[..., 2] < 0)) | (at_seabed & (v_ned[..., 2] > 0))
    v_ned = torch.cat([v_ned[..., :2], torch.where(outward, 0.0, v_ned[..., 2]).unsqueeze(-1)], -1)
    v_body = small_matmul(rot.transpose(-1, -2), v_ned.unsqueeze(-1)).squeeze(-1)
    touched = (at_surface | at_seabed).unsqueeze(-1)
    nu_out = torch.cat([torch.where(touched, v_body, nu[..., :3]), nu[..., 3:]], -1)
    eta_out = torch.cat(
        [eta[..., :2], torch.minimum(depth.clamp_min(0.0), seabed).unsqueeze(-1), eta[..., 3:]],
        -1,
    )
    return eta_out, nu_out, at_surface, at_seabed


def diverged(
    eta: torch.Tensor,
    nu: torch.Tensor,
    actuators: torch.Tensor | None = None,
    *,
    max_speed: float = 5.0,
    max_rate: float = 3.0,
    max_abs_roll: float = math.radians(80),
    max_abs_pitch: float = math.radians(80),
) -> torch.Tensor:
    """Flag vehicles whose state is non-finite or physically absurd, ``[*B]`` bool.

    Absurd means a linear speed above ``max_speed`` (m/s; the REMUS-100 tops out near
    2.6 m/s), an angular rate above ``max_rate`` (rad/s), or ``|roll|``/``|pitch|`` beyond the
    given limits (rad; the Euler kinematics are singular at 90 deg pitch).

    >>> eta, nu = torch.zeros(2, 6), torch.zeros(2, 6)
    >>> nu[1, 0] = float("nan")
    >>> diverged(eta, nu).tolist()
    [False, True]
    """
    for name, value in (
        ("max_speed", max_speed),
        ("max_rate", max_rate),
        ("max_abs_roll", max_abs_roll),
        ("max_abs_pitch", max_abs_pitch),
    ):
        if not value > 0:
            raise ValueError(f"{name} must be > 0, got {value}")
    bad = ~torch.isfinite(eta).all(-1) | ~torch.isfinite(nu).all(-1)
    if actuators is not None:
        bad = bad | ~torch.isfinite(actuators).all(-1)
    bad = bad | (nu[..., :3].norm(dim=-1) > max_speed) | (nu[..., 3:].abs().amax(-1) > max_rate)
    bad = bad | (eta[..., 3].abs() > max_abs_roll) | (eta[..., 4].abs() > max_abs_pitch)
    return bad
