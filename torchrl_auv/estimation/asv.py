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

__all__ = ["ASV_SPEED", "asv_draws", "asv_fixes", "follow_fleet"]

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
    generator: torch.Generator | None,
    *,
    draws: dict[str, torch.Tensor] | None = None,
):
    """One decision of the ASV: it follows the fleet (:func:`follow_fleet` at
    :data:`ASV_SPEED`), its GNSS error evolves (:func:`~torchrl_auv.estimation.gnss_error_step`)
    and it fixes every AUV by USBL (:func:`~torchrl_auv.estimation.usbl_fix_from_asv`).

    ``draws``: the decision's random numbers instead of ``generator``'s (e.g. drawn ahead of
    a compiled step): ``"gnss"`` ``[*B, 2]`` and ``"usbl"`` ``[3, *B, N]`` standard normals,
    ``"dropout"`` ``[*B, N]`` uniforms; :func:`asv_draws` draws them as ``generator`` would.

    Returns:
        ``(asv, gnss_error, fix, fix_cov, valid)``: the ASV's new position ``[*B, 3]``, its
        GNSS error ``[*B, 2]``, and per AUV the fix ``[*B, N, 3]``, its covariance and whether
        it is valid.
    """
    if draws is None:
        if generator is None:  # torch's global generator is never a silent fallback
            raise ValueError("generator must be a torch.Generator when draws is not given")
        draws = asv_draws(gnss_error, auv_positions, generator)
    asv = follow_fleet(asv, auv_positions, ASV_SPEED * dt)
    gnss = gnss_error_step(
        gnss_error, sea.gnss_sigma, sea.gnss_time_constant, dt, None, standard_normal=draws["gnss"]
    )
    fix, fix_cov, valid = usbl_fix_from_asv(
        auv_positions,
        asv[..., None, :].expand_as(auv_positions),
        gnss[..., None, :].expand(*auv_positions.shape[:-1], 2),
        sea,
        None,
        standard_normal=draws["usbl"],
        uniform=draws["dropout"],
    )
    return asv, gnss, fix, fix_cov, valid


def asv_draws(
    gnss_error: torch.Tensor, auv_positions: torch.Tensor, generator: torch.Generator
) -> dict[str, torch.Tensor]:
    """The random numbers of one :func:`asv_fixes` decision, in the order it uses them:
    the GNSS error's step ``[*B, 2]``, then per AUV the USBL fix's range and bearing noises
    ``[3, *B, N]`` and its dropout uniforms ``[*B, N]``."""
    like = {"dtype": auv_positions.dtype, "device": auv_positions.device}
    gnss = torch.randn(
        gnss_error.shape, generator=generator, dtype=gnss_error.dtype, device=gnss_error.device
    )
    shape = auv_positions.shape[:-1]
    usbl = torch.randn((3, *shape), generator=generator, **like)
    return {"gnss": gnss, "usbl": usbl, "dropout": torch.rand(shape, generator=generator, **like)}
