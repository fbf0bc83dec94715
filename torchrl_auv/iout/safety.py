r"""Collision and violation flags of the AUVs at a decision.

* Collision: an AUV is within ``collision_distance_m`` (5 m, 3-D) of another AUV.
* Violation: an AUV is outside the area (:math:`x \notin [0, X]` or :math:`y \notin [0, Y]`),
  or within ``clearance_m`` (1 m) of the surface (:math:`z < 1`) or of the seabed
  (:math:`h(x, y) - z < 1`).
"""

from __future__ import annotations

import torch
from tensordict import TensorDict

from torchrl_auv.iout.config import IoUTConfig
from torchrl_auv.iout.terrain import seabed_depth

__all__ = ["collision_mask", "nearest_auv_distance", "violation_mask"]


def nearest_auv_distance(auv_positions: torch.Tensor) -> torch.Tensor:
    """3-D distance from each AUV to its nearest other AUV (m), ``inf`` for a lone AUV.

    Args:
        auv_positions: ``[*B, N, 3]`` NED positions (m).

    Returns:
        ``[*B, N]``.

    Examples:
        >>> pos = torch.tensor([[0.0, 0, 0], [3.0, 4.0, 0.0], [0.0, 0, 10.0]])
        >>> nearest_auv_distance(pos).tolist()
        [5.0, 5.0, 10.0]
    """
    n = auv_positions.shape[-2]
    gap = torch.linalg.vector_norm(
        auv_positions[..., :, None, :] - auv_positions[..., None, :, :], dim=-1
    )
    eye = torch.eye(n, dtype=torch.bool, device=auv_positions.device)
    return torch.where(eye, torch.inf, gap).amin(-1)


def collision_mask(auv_positions: torch.Tensor, config: IoUTConfig) -> torch.Tensor:
    """Whether each AUV is closer than ``collision_distance_m`` to another AUV, ``[*B, N]``.

    Examples:
        >>> collision_mask(torch.tensor([[0.0, 0, 0], [3.0, 0, 0]]), IoUTConfig()).tolist()
        [True, True]
    """
    return nearest_auv_distance(auv_positions) < config.collision_distance_m


def violation_mask(
    auv_positions: torch.Tensor, terrain: TensorDict, config: IoUTConfig
) -> torch.Tensor:
    """Whether each AUV violates the area or the clearance (module docstring), ``[*B, N]``.

    Args:
        auv_positions: ``[*B, N, 3]`` NED positions (m).
        terrain: seabed of the scenes, batch ``[*B]``.
        config: area and clearance.

    Examples:
        >>> from torchrl_auv.iout import make_terrain
        >>> cfg = IoUTConfig()
        >>> terrain = make_terrain(cfg, (), generator=torch.Generator().manual_seed(0))
        >>> pos = torch.tensor([[100.0, 100, 20], [100.0, 100, 0.5], [-1.0, 100, 20]])
        >>> violation_mask(pos, terrain, cfg).tolist()
        [False, True, True]
    """
    x, y, z = auv_positions.unbind(-1)
    outside = (x < 0) | (x > config.area_m[0]) | (y < 0) | (y > config.area_m[1])
    bed = seabed_depth(terrain, x, y, config)
    return outside | (z < config.clearance_m) | (bed - z < config.clearance_m)
