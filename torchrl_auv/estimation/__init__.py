"""Sensors and state estimation: what the policy sees of the vehicle.

Owns the sensor models of ``docs/spec/data_collection.md`` ("Localisation": USBL fixes from
the ASV with its GNSS error, DVL with bottom lock, depth sensor, compass, altimeter;
:mod:`~torchrl_auv.estimation.sensors`), a batched linear
Kalman filter checked against filterpy (:mod:`~torchrl_auv.estimation.kalman`) and the AUV
localisation model that combines them (:mod:`~torchrl_auv.estimation.localisation`). Plain
batched torch; randomness only from passed generators.
"""

from __future__ import annotations

from torchrl_auv.estimation.asv import ASV_SPEED, asv_draws, asv_fixes, follow_fleet
from torchrl_auv.estimation.kalman import kf_predict, kf_update
from torchrl_auv.estimation.localisation import Localiser
from torchrl_auv.estimation.sensors import (
    SensorNoise,
    altimeter,
    compass,
    depth_sensor,
    dvl,
    dvl_bottom_lock,
    gnss_error_init,
    gnss_error_step,
    total_bearing_sigma,
    usbl_fix,
    usbl_fix_from_asv,
)

__all__ = [
    "ASV_SPEED",
    "Localiser",
    "SensorNoise",
    "altimeter",
    "asv_draws",
    "asv_fixes",
    "compass",
    "depth_sensor",
    "dvl",
    "dvl_bottom_lock",
    "follow_fleet",
    "gnss_error_init",
    "gnss_error_step",
    "kf_predict",
    "kf_update",
    "total_bearing_sigma",
    "usbl_fix",
    "usbl_fix_from_asv",
]
