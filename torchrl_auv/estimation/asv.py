"""The surface vessel (ASV) of the localisation model: it follows the fleet and gives every AUV
a USBL fix, converted to NED from where its own GNSS says it is (``docs/spec/data_collection.md``,
"Localisation").

Examples:
    >>> import torch
    >>> asv = torch.zeros(1, 3)
    >>> auvs = torch.tensor([[[10.0, 0.0, 5.0], [10.0, 0.0, 8.0]]])
    >>> follow_fleet(asv, auvs, reach_m=2.0).tolist()  # 2 m toward the centroid (10, 0)
    [[2.0, 0.0, 0.0]]
"""

from __future__ import annotations

import torch

from torchrl_auv.estimation.sensors import gnss_error_step, usbl_fix_from_asv

__all__ = ["ASV_SPEED", "asv_fixes", "follow_fleet"]

#: The ASV's top speed while it follows the fleet (m/s).
ASV_SPEED = 2.0


def follow_fleet(asv: torch.Tensor, auv_positions: torch.Tensor, reach_m: float) -> torch.Tensor:
    """The ASV's next position ``[*B, 3]``: toward the AUVs' horizontal centroid, at most
    ``reach_m`` (m) in one decision, staying at the surface.

    Args:
        asv: ``[*B, 3]`` NED position of the ASV (m).
        auv_positions: ``[*B, N, 3]`` NED positions of the AUVs (m).
        reach_m: the farthest it moves in one decision (m).
    """
    gap = auv_positions[..., :2].mean(-2) - asv[..., :2]
    scale = reach_m / torch.linalg.vector_norm(gap, dim=-1, keepdim=True).clamp_min(reach_m)
    return asv + torch.cat([gap * scale, torch.zeros(*asv.shape[:-1], 1)], -1)


def asv_fixes(
    asv: torch.Tensor,
    gnss_error: torch.Tensor,
    auv_positions: torch.Tensor,
    sea,
    dt: float,
    generator: torch.Generator,
):
    """One decision of the ASV: it follows the fleet (:func:`follow_fleet` at
    :data:`ASV_SPEED`), its GNSS error evolves (:func:`~torchrl_auv.estimation.gnss_error_step`)
    and it fixes every AUV by USBL (:func:`~torchrl_auv.estimation.usbl_fix_from_asv`).

    Returns:
        ``(asv, gnss_error, fix, fix_cov, valid)``: the ASV's new position ``[*B, 3]``, its
        GNSS error ``[*B, 2]``, and per AUV the fix ``[*B, N, 3]``, its covariance and whether
        it is valid.
    """
    asv = follow_fleet(asv, auv_positions, ASV_SPEED * dt)
    gnss = gnss_error_step(gnss_error, sea.gnss_sigma, sea.gnss_time_constant, dt, generator)
    fix, fix_cov, valid = usbl_fix_from_asv(
        auv_positions, asv[..., None, :].expand_as(auv_positions),
        gnss[..., None, :].expand(*auv_positions.shape[:-1], 2), sea, generator,
    )  # fmt: skip
    return asv, gnss, fix, fix_cov, valid
