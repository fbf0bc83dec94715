r"""Sensor models (``shared/spec/data_collection.md``, "Localisation"), batched and seeded.

* USBL from the ASV: slant range with noise proportional to the range (the sea state's
  ``usbl_noise_fraction``) and bearing noise (azimuth and elevation, ``usbl_bearing_sigma``),
  converted to a NED position fix with its covariance; an optional dropout probability models
  acoustic loss.
* DVL: body-frame velocity over ground, :math:`\sigma` = 0.03 m/s per axis.
* Depth sensor: :math:`\sigma` = 0.05 m. Compass: heading, :math:`\sigma` = 0.5 deg.

Every draw takes the ``generator`` argument; nothing touches the global RNG.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

__all__ = ["SensorNoise", "compass", "depth_sensor", "dvl", "usbl_fix"]


@dataclass(frozen=True)
class SensorNoise:
    """Standard deviations of the onboard sensors (SI units)."""

    dvl: float = 0.03  # m/s per axis
    depth: float = 0.05  # m
    compass: float = math.radians(0.5)  # rad

    def __post_init__(self) -> None:
        for name in ("dvl", "depth", "compass"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"SensorNoise.{name} must be >= 0, got {getattr(self, name)}")


def _noise(
    like: torch.Tensor,
    sigma: float,
    generator: torch.Generator | None,
    standard_normal: torch.Tensor | None = None,
) -> torch.Tensor:
    if standard_normal is not None:
        if standard_normal.shape != like.shape:
            raise ValueError(
                f"standard_normal must be shaped {tuple(like.shape)}, "
                f"got {tuple(standard_normal.shape)}"
            )
        return sigma * standard_normal
    if generator is None:
        raise ValueError("generator must be a torch.Generator when standard_normal is not given")
    return sigma * torch.randn(
        like.shape, generator=generator, dtype=like.dtype, device=like.device
    )


def dvl(
    nu: torch.Tensor,
    sigma: float,
    generator: torch.Generator | None,
    *,
    standard_normal: torch.Tensor | None = None,
) -> torch.Tensor:
    """DVL body velocity ``[*B, 3]`` (m/s) from ``nu [*B, 6]``.

    ``standard_normal`` (``[*B, 3]``), when given, replaces the draw from ``generator`` (so a
    caller can draw a whole decision's noise at once); the same holds for the other sensors.

    >>> g = torch.Generator().manual_seed(0)
    >>> dvl(torch.zeros(6), 0.0, g).tolist()
    [0.0, 0.0, 0.0]
    """
    return nu[..., :3] + _noise(nu[..., :3], sigma, generator, standard_normal)


def depth_sensor(
    depth: torch.Tensor,
    sigma: float,
    generator: torch.Generator | None,
    *,
    standard_normal: torch.Tensor | None = None,
) -> torch.Tensor:
    """Depth reading (m), same shape as ``depth``."""
    return depth + _noise(depth, sigma, generator, standard_normal)


def compass(
    heading: torch.Tensor,
    sigma: float,
    generator: torch.Generator | None,
    *,
    standard_normal: torch.Tensor | None = None,
) -> torch.Tensor:
    """Compass heading (rad), same shape as ``heading`` (not wrapped)."""
    return heading + _noise(heading, sigma, generator, standard_normal)


def usbl_fix(
    position: torch.Tensor,
    asv_position: torch.Tensor,
    range_fraction: float,
    bearing_sigma: float,
    generator: torch.Generator,
    *,
    dropout: float = 0.0,
    min_range_sigma: float = 0.01,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    r"""A USBL position fix of the vehicle from the ASV's transducer.

    With the line of sight :math:`\ell = p - p_{asv}`, range :math:`\rho = |\ell|`, azimuth and
    elevation angles of :math:`\ell`, the fix is
    :math:`\hat p = p_{asv} + (\rho + n_\rho)\,\mathrm{dir}(az + n_a, el + n_e)` with
    :math:`n_\rho \sim \mathcal N(0, (f\rho)^2)` and bearing noises
    :math:`\mathcal N(0, \sigma_b^2)`. Its covariance is approximated by
    :math:`\sigma_\rho^2 \hat\ell\hat\ell^\top + (\rho\sigma_b)^2 (I - \hat\ell\hat\ell^\top)`.

    Args:
        position: true vehicle position ``[*B, 3]`` (NED, m).
        asv_position: transducer position ``[*B, 3]`` (NED, m; z = 0 at the surface).
        range_fraction: range noise as a fraction of the slant range.
        bearing_sigma: bearing noise (rad).
        generator: the random source.
        dropout: probability that a fix is lost (acoustic loss).
        min_range_sigma: floor of the range noise (m), keeps the covariance positive definite.

    Returns:
        ``(fix [*B, 3], covariance [*B, 3, 3], valid [*B] bool)``.

    >>> g = torch.Generator().manual_seed(0)
    >>> fix, cov, ok = usbl_fix(torch.tensor([30.0, 40.0, 20.0]), torch.zeros(3), 0.0, 0.0, g)
    >>> fix.tolist(), bool(ok)
    ([30.0, 40.0, 20.0], True)
    """
    if position.shape[-1] != 3 or asv_position.shape != position.shape:
        raise ValueError(
            f"position and asv_position must both be [*B, 3], got {tuple(position.shape)}, "
            f"{tuple(asv_position.shape)}"
        )
    if not 0.0 <= dropout <= 1.0:
        raise ValueError(f"dropout must be in [0, 1], got {dropout}")
    line = position - asv_position
    rng = line.norm(dim=-1).clamp_min(1e-6)
    azimuth = torch.atan2(line[..., 1], line[..., 0])
    elevation = torch.asin((line[..., 2] / rng).clamp(-1.0, 1.0))
    kw = {"generator": generator, "dtype": position.dtype, "device": position.device}
    noise = torch.randn((3, *rng.shape), **kw)
    range_sigma = (range_fraction * rng).clamp_min(min_range_sigma)
    rng_m = rng + range_sigma * noise[0]
    az_m = azimuth + bearing_sigma * noise[1]
    el_m = elevation + bearing_sigma * noise[2]
    direction = torch.stack(
        (torch.cos(el_m) * torch.cos(az_m), torch.cos(el_m) * torch.sin(az_m), torch.sin(el_m)),
        -1,
    )
    fix = asv_position + rng_m.unsqueeze(-1) * direction
    unit = line / rng.unsqueeze(-1)
    outer = unit.unsqueeze(-1) * unit.unsqueeze(-2)
    eye = torch.eye(3, dtype=position.dtype, device=position.device)
    lateral = (rng * max(bearing_sigma, 1e-4)).square()
    cov = range_sigma.square()[..., None, None] * outer + lateral[..., None, None] * (eye - outer)
    if dropout > 0:
        valid = torch.rand(rng.shape, **kw) >= dropout
    else:
        valid = torch.ones(rng.shape, dtype=torch.bool, device=position.device)
    return fix, cov, valid
