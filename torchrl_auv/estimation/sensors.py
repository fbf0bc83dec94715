r"""Sensor models (``docs/spec/data_collection.md``, "Localisation"), batched and seeded.

* USBL from the ASV: slant range with noise proportional to the range (the sea state's
  ``usbl_noise_fraction``) and bearing noise (azimuth and elevation, ``usbl_bearing_sigma``),
  converted to a NED position fix with its covariance; an optional dropout probability models
  acoustic loss. :func:`usbl_fix_from_asv` adds the errors a real system has (spec v2), from
  the sea state: the fix is computed from the ASV's *believed* position (true + GNSS error),
  the ASV's wave-driven attitude residual widens the bearing noise, fixes drop out.
* ASV GNSS error: a first-order Gauss-Markov process per horizontal axis
  (:func:`gnss_error_init`, :func:`gnss_error_step`), discretised exactly.
* DVL: body-frame velocity over ground, :math:`\sigma` = 0.03 m/s per axis, only with bottom
  lock: altitude at most ``SensorNoise.dvl_range`` = 30 m (ours: a 1.2 MHz REMUS-class DVL
  bottom-tracks to about 30 m; :func:`dvl_bottom_lock`). Above it the DVL gives nothing
  (the spec's "or none"): its water-track velocity would include the unknown current (up to
  1 m/s in ``ves``), a bias a filter that takes it as over-ground velocity cannot know.
* Depth sensor: :math:`\sigma` = 0.05 m. Compass: heading, :math:`\sigma` = 0.5 deg.
* Altimeter: altitude above the seabed, :math:`\sigma` = 0.1 m within 30 m (ours: the
  altitude from the DVL's beams, so the DVL's range; 0.1 m covers a rough seabed under the beam
  footprint); :func:`altimeter`.

Every draw takes the ``generator`` argument; nothing touches the global RNG.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from torchrl_auv.physics.ocean import SeaState

__all__ = [
    "SensorNoise",
    "altimeter",
    "compass",
    "depth_sensor",
    "dvl",
    "dvl_bottom_lock",
    "gnss_error_init",
    "gnss_error_step",
    "total_bearing_sigma",
    "usbl_fix",
    "usbl_fix_from_asv",
]


@dataclass(frozen=True)
class SensorNoise:
    """Standard deviations (and ranges) of the onboard sensors (SI units)."""

    dvl: float = 0.03  # m/s per axis
    depth: float = 0.05  # m
    compass: float = math.radians(0.5)  # rad
    dvl_range: float = 30.0  # m altitude of bottom lock (1.2 MHz REMUS-class DVL, ours)
    altimeter: float = 0.1  # m
    altimeter_range: float = 30.0  # m (the DVL's beams, ours)

    def __post_init__(self) -> None:
        for name in ("dvl", "depth", "compass", "altimeter"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"SensorNoise.{name} must be >= 0, got {getattr(self, name)}")
        for name in ("dvl_range", "altimeter_range"):
            if not getattr(self, name) > 0:
                raise ValueError(f"SensorNoise.{name} must be > 0, got {getattr(self, name)}")


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


def dvl_bottom_lock(altitude: torch.Tensor, max_range: float = 30.0) -> torch.Tensor:
    """Whether the DVL has bottom lock: ``altitude <= max_range`` (bool, same shape).

    ``altitude`` is the height above the seabed (m); a NaN altitude gives no lock.

    >>> dvl_bottom_lock(torch.tensor([5.0, 30.0, 31.0])).tolist()
    [True, True, False]
    """
    return altitude <= max_range


def altimeter(
    altitude: torch.Tensor,
    sigma: float,
    generator: torch.Generator | None,
    *,
    max_range: float = 30.0,
    standard_normal: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Altimeter: altitude above the seabed (m) with Gaussian noise, within its range.

    Returns ``(reading, valid)``, both shaped like ``altitude``: beyond ``max_range`` (no
    echo) ``valid`` is ``False`` and the reading is ``max_range`` (a finite placeholder, safe in
    an observation). The noise is drawn for every element, in or out of range.

    >>> reading, valid = altimeter(torch.tensor([12.0, 45.0]), 0.0, torch.Generator())
    >>> reading.tolist(), valid.tolist()
    ([12.0, 30.0], [True, False])
    """
    reading = altitude + _noise(altitude, sigma, generator, standard_normal)
    valid = altitude <= max_range
    return torch.where(valid, reading, torch.full_like(reading, max_range)), valid


def gnss_error_init(
    shape: tuple[int, ...] | torch.Size,
    sigma: float,
    generator: torch.Generator,
    *,
    dtype: torch.dtype = torch.float32,
    device: torch.device | str | None = None,
) -> torch.Tensor:
    r"""The ASV's GNSS position error at the start, drawn from the stationary distribution.

    ``shape`` includes the trailing axis, e.g. ``(*B, 2)`` for north and east (m); each entry
    is :math:`\mathcal N(0, \sigma^2)`, so the process is stationary from the first step.
    One draw even for ``sigma = 0`` (the same random numbers for every sea state).

    >>> gnss_error_init((3, 2), 0.0, torch.Generator()).tolist()
    [[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]]
    """
    if not (math.isfinite(sigma) and sigma >= 0):
        raise ValueError(f"sigma must be a finite number >= 0 (m), got {sigma}")
    return sigma * torch.randn(tuple(shape), generator=generator, dtype=dtype, device=device)


def gnss_error_step(
    error: torch.Tensor,
    sigma: float,
    time_constant: float,
    dt: float,
    generator: torch.Generator | None,
    *,
    standard_normal: torch.Tensor | None = None,
) -> torch.Tensor:
    r"""Advance the GNSS error by ``dt`` seconds: a first-order Gauss-Markov process per entry,

    .. math::

        e_{k+1} = a\,e_k + \sigma\sqrt{1 - a^2}\,w_k,\qquad a = e^{-h/T},\
        w_k \sim \mathcal N(0, 1),

    the exact discretisation of :math:`\dot e = -e/T + \sigma\sqrt{2/T}\,\xi`: the
    stationary variance :math:`\sigma^2` is kept and the lag-:math:`h` autocorrelation is
    :math:`e^{-h/T}`. ``time_constant = math.inf`` freezes the error.

    >>> e = torch.ones(2)
    >>> gnss_error_step(e, 1.0, math.inf, 1.0, torch.Generator()).tolist()
    [1.0, 1.0]
    """
    if not (math.isfinite(sigma) and sigma >= 0):
        raise ValueError(f"sigma must be a finite number >= 0 (m), got {sigma}")
    if not time_constant > 0 or not dt > 0:
        raise ValueError(f"time_constant and dt must be > 0 (s), got {time_constant}, {dt}")
    decay = math.exp(-dt / time_constant)
    scale = sigma * math.sqrt(max(1.0 - decay * decay, 0.0))
    return decay * error + _noise(error, scale, generator, standard_normal)


def total_bearing_sigma(sea: SeaState) -> float:
    """The USBL bearing noise in a sea state (rad): the instrument's ``usbl_bearing_sigma``
    and the ASV's residual attitude error ``usbl_attitude_sigma``, independent, in quadrature.

    >>> from torchrl_auv.physics.ocean import get_sea_state
    >>> round(math.degrees(total_bearing_sigma(get_sea_state("ves"))), 4)
    0.7566
    """
    return math.hypot(sea.usbl_bearing_sigma, sea.usbl_attitude_sigma)


def usbl_fix(
    position: torch.Tensor,
    asv_position: torch.Tensor,
    range_fraction: float,
    bearing_sigma: float,
    generator: torch.Generator | None,
    *,
    dropout: float = 0.0,
    min_range_sigma: float = 0.01,
    asv_error: torch.Tensor | None = None,
    asv_error_sigma: float = 0.0,
    standard_normal: torch.Tensor | None = None,
    uniform: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    r"""A USBL position fix of the vehicle from the ASV's transducer.

    With the line of sight :math:`\ell = p - p_{asv}`, range :math:`\rho = |\ell|`, azimuth and
    elevation angles of :math:`\ell`, the fix is
    :math:`\hat p = p_{asv} + (\rho + n_\rho)\,\mathrm{dir}(az + n_a, el + n_e)` with
    :math:`n_\rho \sim \mathcal N(0, (f\rho)^2)` and bearing noises
    :math:`\mathcal N(0, \sigma_b^2)`. Its covariance is approximated by
    :math:`\sigma_\rho^2 \hat\ell\hat\ell^\top + (\rho\sigma_b)^2 (I - \hat\ell\hat\ell^\top)`.
    The ASV measures range and bearings from its true transducer position but converts them to
    NED from where it *believes* it is, :math:`p_{asv} + e_{asv}`, so the fix is shifted by
    the ASV's navigation error :math:`e_{asv}` (``asv_error``); ``asv_error_sigma`` adds its
    variance to the covariance's north and east entries.

    Args:
        position: true vehicle position ``[*B, 3]`` (NED, m).
        asv_position: transducer position ``[*B, 3]`` (NED, m; z = 0 at the surface).
        range_fraction: range noise as a fraction of the slant range.
        bearing_sigma: bearing noise (rad).
        generator: the random source.
        dropout: probability that a fix is lost (acoustic loss). The uniform draw behind it
            is made for every value, so the random stream does not depend on ``dropout``.
        min_range_sigma: floor of the range noise (m), keeps the covariance positive definite.
        asv_error: the ASV's position error (believed minus true), ``[*B, 2]`` (north, east)
            or ``[*B, 3]`` (m); ``None`` for none.
        asv_error_sigma: standard deviation of that error per horizontal axis (m), added to
            the covariance so that a filter fusing the fix knows its noise.
        standard_normal, uniform: the draws themselves instead of ``generator``'s (both or
            neither): ``[3, *B]`` standard normals (range, azimuth, elevation) and ``[*B]``
            uniforms on [0, 1) for the dropout, e.g. drawn ahead of a compiled step; drawn
            with ``torch.randn((3, *B))`` then ``torch.rand(B)`` they give the same fix.

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
    if (standard_normal is None) != (uniform is None):
        raise ValueError("standard_normal and uniform must be given together (or neither)")
    if standard_normal is None:
        if generator is None:
            raise ValueError("generator must be a torch.Generator when the draws are not given")
        kw = {"generator": generator, "dtype": position.dtype, "device": position.device}
        standard_normal = torch.randn((3, *rng.shape), **kw)
        uniform = torch.rand(rng.shape, **kw)
    elif standard_normal.shape != (3, *rng.shape) or uniform.shape != rng.shape:
        raise ValueError(
            f"standard_normal must be shaped {(3, *rng.shape)} and uniform {tuple(rng.shape)}, "
            f"got {tuple(standard_normal.shape)} and {tuple(uniform.shape)}"
        )
    noise = standard_normal
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
    if asv_error is not None:
        if asv_error.shape[-1] == 2:
            asv_error = torch.cat([asv_error, torch.zeros_like(asv_error[..., :1])], -1)
        fix = fix + asv_error
    if asv_error_sigma > 0:
        horizontal = torch.tensor([1.0, 1.0, 0.0], dtype=position.dtype, device=position.device)
        cov = cov + asv_error_sigma**2 * torch.diag(horizontal)
    valid = uniform >= dropout  # rand < 1: dropout 0 keeps every fix
    return fix, cov, valid


def usbl_fix_from_asv(
    position: torch.Tensor,
    asv_position: torch.Tensor,
    gnss_error: torch.Tensor,
    sea: SeaState,
    generator: torch.Generator | None,
    *,
    standard_normal: torch.Tensor | None = None,
    uniform: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """A USBL fix with the errors a real system has in ``sea`` (spec v2, "Localisation").

    :func:`usbl_fix` with the sea state's range noise, the bearing noise
    :func:`total_bearing_sigma` (instrument and the ASV's wave-driven attitude residual), its
    dropout probability, and the ASV's GNSS error ``gnss_error`` (``[*B, 2]``, north and east,
    m; from :func:`gnss_error_init` / :func:`gnss_error_step`) as the fix's bias, with
    ``sea.gnss_sigma`` in its covariance; ``standard_normal`` and ``uniform``: the draws, as
    in :func:`usbl_fix`. ``asv_position`` is the ASV's *true* transducer
    position ``[*B, 3]`` (z = 0: its heave is taken as measured by its motion sensor).

    Returns:
        ``(fix [*B, 3], covariance [*B, 3, 3], valid [*B] bool)``.

    >>> from torchrl_auv.physics.ocean import get_sea_state
    >>> g = torch.Generator().manual_seed(0)
    >>> p, asv = torch.tensor([[30.0, 0.0, 20.0]]), torch.zeros(1, 3)
    >>> fix, cov, valid = usbl_fix_from_asv(p, asv, torch.tensor([[1.5, -2.0]]),
    ...                                     get_sea_state("ideal"), g)
    >>> bias = torch.tensor([1.5, -2.0])  # the GNSS error, plus cm of acoustic noise
    >>> bool(((fix - p)[0, :2] - bias).norm() < 0.3), bool(valid)
    (True, True)
    """
    return usbl_fix(
        position,
        asv_position,
        sea.usbl_noise_fraction,
        total_bearing_sigma(sea),
        generator,
        dropout=sea.usbl_dropout,
        asv_error=gnss_error,
        asv_error_sigma=sea.gnss_sigma,
        standard_normal=standard_normal,
        uniform=uniform,
    )
