"""Sea-state presets (``ideal``, ``es``, ``ves``) and their validation
(:mod:`~torchrl_auv.physics.ocean`)."""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class SeaState:
    r"""A sea state: current, waves and the USBL noise level that goes with them.

    Attributes:
        name: label used in logs and tables.
        current_mean: mean current speed :math:`\mu_V` (m/s).
        current_sigma: stationary standard deviation of the current speed (m/s).
        current_time_constant: Gauss-Markov time constant :math:`T` of speed and direction (s);
            ``math.inf`` freezes the current within an episode.
        current_direction_mean: mean direction the current flows towards (rad, clockwise from
            north); ``None`` (default) draws it uniformly in :math:`[-\pi, \pi)` per scene.
        current_direction_sigma: stationary standard deviation of the direction (rad, ours).
        wave_hs: significant wave height :math:`H_s` (m); 0 disables waves.
        wave_tp: peak period :math:`T_p` (s).
        wave_gamma: JONSWAP peak-enhancement factor :math:`\gamma \ge 1`.
        usbl_noise_fraction: USBL range noise as a fraction of the slant range.
        usbl_bearing_sigma: USBL bearing noise (rad; default 0.1 deg).
        usbl_dropout: probability that a USBL fix is lost (acoustic loss; 0 to 1).
        usbl_attitude_sigma: residual error of the ASV's wave-driven roll/pitch after motion
            compensation (rad); it tilts the transducer, so it adds in quadrature to
            ``usbl_bearing_sigma`` on both bearing angles (per fix, independent).
        gnss_sigma: stationary standard deviation of the ASV's GNSS position error per
            horizontal axis (m); the USBL fix is computed from the believed ASV position, so
            this error becomes a bias of the fix.
        gnss_time_constant: Gauss-Markov time constant of the GNSS error (s); ``math.inf``
            freezes it within an episode.

    The localisation errors of the presets (``docs/spec/data_collection.md``, "Localisation"
    v2; values ours):

    ===============================  =====  =====  =====  ==========================================
    field                            ideal  es     ves    why
    ===============================  =====  =====  =====  ==========================================
    ``usbl_dropout``                 0      0.05   0.20   the spec's 0 / ~5 / ~20 % of fixes lost
    ``usbl_attitude_sigma`` (deg)    0      0.5    0.75   ASV roll/pitch ~2.5 deg rms per m of
                                                          :math:`H_s`, ~5 % left after compensation
    ``gnss_sigma`` (m)               1.0    1.5    2.0    a standalone/SBAS receiver (1.4 m DRMS)
                                                          on a calm ASV; a small ASV rolling and
                                                          pitching in a 4-6 m sea adds antenna
                                                          motion and multipath (the spec's 1-2 m)
    ``gnss_time_constant`` (s)       60     60     60     the spec's 60 s correlation
    ===============================  =====  =====  =====  ==========================================

    A :class:`SeaState` built by hand has none of these errors unless it sets them.

    Raises:
        ValueError: naming the field, for a negative spread, height or noise level, a
            non-positive time constant or period, :math:`\gamma < 1`, or a non-finite value.

    Examples:
        >>> calm = SeaState(name="calm", current_mean=0.2, current_sigma=0.05)
        >>> calm.wave_hs, calm.current_direction_mean
        (0.0, None)
        >>> SeaState(current_sigma=-0.1)
        Traceback (most recent call last):
        ...
        ValueError: SeaState.current_sigma must be a finite number >= 0, got -0.1
    """

    name: str = "custom"
    current_mean: float = 0.0
    current_sigma: float = 0.0
    current_time_constant: float = 60.0
    current_direction_mean: float | None = None
    current_direction_sigma: float = 0.0
    wave_hs: float = 0.0
    wave_tp: float = 10.0
    wave_gamma: float = 3.3
    usbl_noise_fraction: float = 0.001
    usbl_bearing_sigma: float = math.radians(0.1)
    usbl_dropout: float = 0.0
    usbl_attitude_sigma: float = 0.0
    gnss_sigma: float = 0.0
    gnss_time_constant: float = 60.0

    def __post_init__(self) -> None:
        if not isinstance(self.name, str):
            raise ValueError(f"SeaState.name must be a str, got {type(self.name).__name__}")
        non_negative = (
            "current_mean",
            "current_sigma",
            "current_direction_sigma",
            "wave_hs",
            "usbl_noise_fraction",
            "usbl_bearing_sigma",
            "usbl_attitude_sigma",
            "gnss_sigma",
        )
        for field in non_negative:
            value = getattr(self, field)
            if not (_is_real(value) and math.isfinite(value) and value >= 0):
                raise ValueError(f"SeaState.{field} must be a finite number >= 0, got {value!r}")
        if not (_is_real(self.usbl_dropout) and 0.0 <= self.usbl_dropout <= 1.0):
            raise ValueError(
                f"SeaState.usbl_dropout must be a probability in [0, 1], got {self.usbl_dropout!r}"
            )
        for field in ("current_time_constant", "wave_tp", "gnss_time_constant"):
            value = getattr(self, field)
            if not (_is_real(value) and value > 0):  # inf allowed: a frozen current
                raise ValueError(f"SeaState.{field} must be a number > 0, got {value!r}")
        if not (_is_real(self.wave_gamma) and math.isfinite(self.wave_gamma)) or (
            self.wave_gamma < 1
        ):
            raise ValueError(
                f"SeaState.wave_gamma must be a finite number >= 1, got {self.wave_gamma!r}"
            )
        direction = self.current_direction_mean
        if direction is not None and not (_is_real(direction) and math.isfinite(direction)):
            raise ValueError(
                f"SeaState.current_direction_mean must be None or a finite angle (rad), "
                f"got {direction!r}"
            )


def _is_real(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


SEA_STATES: dict[str, SeaState] = {
    "ideal": SeaState(
        name="ideal",
        usbl_noise_fraction=0.001,
        usbl_dropout=0.0,
        usbl_attitude_sigma=0.0,
        gnss_sigma=1.0,
        gnss_time_constant=60.0,
    ),
    "es": SeaState(
        name="es",
        current_mean=0.5,
        current_sigma=0.1,
        current_time_constant=60.0,
        current_direction_sigma=0.2,
        wave_hs=4.0,
        wave_tp=10.0,
        wave_gamma=3.3,
        usbl_noise_fraction=0.005,
        usbl_dropout=0.05,
        usbl_attitude_sigma=math.radians(0.5),
        gnss_sigma=1.5,
        gnss_time_constant=60.0,
    ),
    "ves": SeaState(
        name="ves",
        current_mean=1.0,
        current_sigma=0.2,
        current_time_constant=60.0,
        current_direction_sigma=0.3,
        wave_hs=6.0,
        wave_tp=12.0,
        wave_gamma=3.3,
        usbl_noise_fraction=0.01,
        usbl_dropout=0.20,
        usbl_attitude_sigma=math.radians(0.75),
        gnss_sigma=2.0,
        gnss_time_constant=60.0,
    ),
}


def get_sea_state(sea_state: str | SeaState) -> SeaState:
    """Return a preset by name (``ideal``, ``es``, ``ves``) or pass a :class:`SeaState` through.

    Args:
        sea_state: a preset name or a :class:`SeaState`.

    Raises:
        ValueError: for an unknown name, listing the valid ones.

    >>> get_sea_state("es").current_mean
    0.5
    >>> get_sea_state("stormy")
    Traceback (most recent call last):
    ...
    ValueError: sea_state must be one of ['es', 'ideal', 'ves'] or a SeaState, got 'stormy'
    """
    if isinstance(sea_state, SeaState):
        return sea_state
    if isinstance(sea_state, str) and sea_state in SEA_STATES:
        return SEA_STATES[sea_state]
    raise ValueError(
        f"sea_state must be one of {sorted(SEA_STATES)} or a SeaState, got {sea_state!r}"
    )
