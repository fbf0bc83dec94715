r"""Configuration of the data-collection task (``docs/spec/data_collection.md``).

Every number of the task spec is a default of :class:`IoUTConfig`; values the spec does not
give are marked "ours" in the field list.

Coordinates are NED with the origin at a corner of the area: ``x`` (north) in
``[0, area_m[0]]``, ``y`` (east) in ``[0, area_m[1]]``, ``z`` the depth (m, positive down).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from torchrl_auv.physics.acoustics import RATE_MODELS

__all__ = ["IoUTConfig"]


@dataclass(frozen=True)
class IoUTConfig:
    """All parameters of the Internet-of-Underwater-Things data-collection task.

    Attributes:
        area_m: horizontal extent ``(x, y)`` of the area (m).
        seabed_depth_range_m: minimum and maximum seabed depth (m).
        terrain_grid_points: grid points per side of the seabed depth grid (ours; 41 gives a
            5 m spacing over 200 m). The seabed between grid points is bilinear.
        terrain_modes: number of random cosine modes summed into the seabed (ours).
        terrain_wavelength_range_m: wavelengths of those modes (m, ours): smooth hills.
        num_sensors: number of sensor nodes ``M``.
        num_auvs: number of AUVs ``N``.
        arrival_rates: Poisson arrival rates ``lambda_i`` a node draws from (packets/decision).
        buffer_capacity: node buffer capacity ``C_max`` (packets).
        initial_fill_range: initial buffer fill, uniform integers in this closed range (packets).
        priority_rate_weight: weight of ``lambda_i b_i / C_max`` in the target priority.
        priority_distance_weight: weight of the distance ``d_i`` in the priority (1/m).
        retarget_every_decision: re-run the target rule every decision for every AUV that is
            not in service (the group's heuristic); ``False`` (default, ours) keeps a target
            until it is served. A torpedo-shaped AUV cannot turn on the spot, so how it
            arrives at a node decides whether it can hold station there in a current (bow
            into it, :mod:`~torchrl_auv.iout.station_keeping`); re-targeting every decision
            starts services at whatever node the AUV happens to pass, from any direction,
            and fewer of them end within the service radius (measured:
            ``docs/design_notes.md``, the expert).
        refill_fraction: a node is eligible as a target again once its buffer holds at
            least this fraction of ``C_max`` (ours, spec v2: 10 %); a node is never a target
            while it is emptier, so an AUV cannot farm services on a just-emptied node.
        service_radius_m: 3-D AUV-node distance below which service starts (m).
        data_volume_bits: ``Q``, the data of a full buffer (bit); the hover time is
            ``Q (b_i / C_max) / R``.
        decision_dt_s: duration of one decision (s).
        carrier_khz: acoustic carrier frequency ``f`` (kHz).
        bandwidth_hz: acoustic bandwidth ``B`` (Hz).
        shipping: shipping activity ``s`` in [0, 1] of the noise model.
        wind_mps: wind speed ``w`` of the noise model (m/s).
        source_power_w: acoustic transmit power ``P`` (W).
        source_level_offset_db: the constant of ``SL = 10 log10 P + offset`` (dB re uPa).
        rate_model: ``"shannon"`` (correct, default) or ``"paper"`` (the group's formula without
            the /10 in the power of ten, about tenfold rates), see :mod:`torchrl_auv.iout.link`.
        collision_distance_m: inter-AUV distance below which a decision counts a collision (m).
        clearance_m: minimum distance to the seabed and the surface (m); closer is a violation.
        auv_start_depth_range_m: AUVs start at a uniform depth in this range (m, ours).
        auv_start_spread_m: AUVs start evenly on a circle of this radius (m, ours) ...
        auv_start_margin_m: ... around a uniform centre this far inside the area's edges (ours).
        episode_decisions: decisions per episode (1000 s at 1 Hz).
        delivery_age_scale: the age of an AUV's last delivery (decisions) at which the
            cost's mission term reaches its weight and the observation's ``delivery_age`` 1
            (ours, task v3; :mod:`~torchrl_auv.iout.reward`). ``None`` (default): the
            decisions an average node takes to fill its empty buffer,
            :attr:`buffer_fill_decisions` (645 with the defaults): an AUV that has delivered
            nothing for that long lets the network's data overflow.

    Raises:
        ValueError: naming the field, for a non-positive count, size, rate or range.

    Examples:
        >>> cfg = IoUTConfig()
        >>> cfg.num_sensors, cfg.num_auvs, cfg.packet_bits
        (60, 2, 400.0)
        >>> IoUTConfig(num_auvs=0)
        Traceback (most recent call last):
            ...
        ValueError: num_auvs must be >= 1, got 0
    """

    area_m: tuple[float, float] = (200.0, 200.0)
    seabed_depth_range_m: tuple[float, float] = (39.0, 58.0)
    terrain_grid_points: int = 41
    terrain_modes: int = 6
    terrain_wavelength_range_m: tuple[float, float] = (80.0, 400.0)
    num_sensors: int = 60
    num_auvs: int = 2
    arrival_rates: tuple[float, ...] = (4.0, 6.0, 9.0, 12.0)
    buffer_capacity: int = 5000
    initial_fill_range: tuple[int, int] = (0, 1000)
    priority_rate_weight: float = 1.0
    priority_distance_weight: float = 0.05
    retarget_every_decision: bool = False
    refill_fraction: float = 0.1
    service_radius_m: float = 18.0
    data_volume_bits: float = 2.0e6
    decision_dt_s: float = 1.0
    carrier_khz: float = 20.0
    bandwidth_hz: float = 1000.0
    shipping: float = 0.5
    wind_mps: float = 0.0
    source_power_w: float = 0.09
    source_level_offset_db: float = 170.77
    rate_model: str = "shannon"
    collision_distance_m: float = 5.0
    clearance_m: float = 1.0
    auv_start_depth_range_m: tuple[float, float] = (5.0, 10.0)
    auv_start_spread_m: float = 10.0
    auv_start_margin_m: float = 20.0
    episode_decisions: int = 1000
    delivery_age_scale: float | None = None

    def __post_init__(self) -> None:
        for name in ("num_sensors", "num_auvs", "terrain_modes", "episode_decisions"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        if self.terrain_grid_points < 2:
            raise ValueError(f"terrain_grid_points must be >= 2, got {self.terrain_grid_points}")
        if len(self.area_m) != 2 or not all(math.isfinite(a) and a > 0 for a in self.area_m):
            raise ValueError(f"area_m must be two finite sizes > 0 (m), got {self.area_m}")
        for name in ("seabed_depth_range_m", "terrain_wavelength_range_m"):
            low, high = getattr(self, name)
            if not 0 < low <= high:
                raise ValueError(f"{name} must satisfy 0 < low <= high, got {(low, high)}")
        low, high = self.auv_start_depth_range_m
        if not 0 <= low <= high < self.seabed_depth_range_m[0] - self.clearance_m:
            raise ValueError(
                "auv_start_depth_range_m must satisfy 0 <= low <= high < shallowest seabed - "
                f"clearance, got {low, high}"
            )
        if len(self.arrival_rates) < 1 or not all(r >= 0 for r in self.arrival_rates):
            raise ValueError(
                f"arrival_rates must be a non-empty tuple of rates >= 0, got {self.arrival_rates}"
            )
        if self.buffer_capacity < 1:
            raise ValueError(f"buffer_capacity must be >= 1, got {self.buffer_capacity}")
        low, high = self.initial_fill_range
        if not 0 <= low <= high <= self.buffer_capacity:
            raise ValueError(
                f"initial_fill_range must satisfy 0 <= low <= high <= buffer_capacity, got "
                f"{(low, high)}"
            )
        for name in (
            "service_radius_m",
            "data_volume_bits",
            "decision_dt_s",
            "carrier_khz",
            "bandwidth_hz",
            "source_power_w",
            "collision_distance_m",
        ):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        for name in (
            "priority_rate_weight",
            "priority_distance_weight",
            "clearance_m",
            "wind_mps",
            "auv_start_spread_m",
            "auv_start_margin_m",
        ):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        if not 0 <= self.refill_fraction <= 1:
            raise ValueError(f"refill_fraction must be in [0, 1], got {self.refill_fraction}")
        if not 0 <= self.shipping <= 1:
            raise ValueError(f"shipping must be in [0, 1], got {self.shipping}")
        if not self.carrier_khz * 1000.0 > self.bandwidth_hz / 2:
            raise ValueError("bandwidth_hz must be < 2 * carrier (the band f -+ B/2 must be > 0)")
        if self.rate_model not in RATE_MODELS:
            raise ValueError(f"rate_model must be one of {RATE_MODELS}, got {self.rate_model!r}")
        if self.delivery_age_scale is not None and not self.delivery_age_scale >= 1:
            raise ValueError(
                f"delivery_age_scale must be None or >= 1 (decisions), got "
                f"{self.delivery_age_scale}"
            )
        if 2 * self.auv_start_margin_m >= min(self.area_m):
            raise ValueError(
                f"auv_start_margin_m must be < half the area's side, got {self.auv_start_margin_m}"
            )

    @property
    def packet_bits(self) -> float:
        """Bits per packet, ``Q / C_max``: a full buffer holds exactly ``Q`` bits (ours)."""
        return self.data_volume_bits / self.buffer_capacity

    @property
    def area_diagonal_m(self) -> float:
        """Horizontal diagonal of the area (m), a natural distance scale."""
        return math.hypot(*self.area_m)

    @property
    def buffer_fill_decisions(self) -> float:
        """Decisions an average node takes to fill an empty buffer, ``C_max / mean(lambda)``.

        Examples:
            >>> round(IoUTConfig().buffer_fill_decisions, 1)  # 5000 / 7.75
            645.2
        """
        mean_rate = sum(self.arrival_rates) / len(self.arrival_rates)
        return self.buffer_capacity / max(mean_rate, 1e-12)

    @property
    def age_scale(self) -> float:
        """:attr:`delivery_age_scale`, or :attr:`buffer_fill_decisions` when it is ``None``."""
        if self.delivery_age_scale is not None:
            return float(self.delivery_age_scale)
        return self.buffer_fill_decisions
