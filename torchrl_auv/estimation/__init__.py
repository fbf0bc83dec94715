"""Sensors and state estimation: what the policy sees of the vehicle.

Owns the sensor models of ``shared/spec/data_collection.md`` ("Localisation": USBL fixes from
the ASV, DVL, depth sensor, compass; :mod:`~torchrl_auv.estimation.sensors`), a batched linear
Kalman filter checked against filterpy (:mod:`~torchrl_auv.estimation.kalman`) and the AUV
localisation model that combines them (:mod:`~torchrl_auv.estimation.localisation`). Plain
batched torch; randomness only from passed generators.
"""

from __future__ import annotations

from torchrl_auv.estimation.kalman import kf_predict, kf_update
from torchrl_auv.estimation.localisation import Localiser
from torchrl_auv.estimation.sensors import SensorNoise, compass, depth_sensor, dvl, usbl_fix

__all__ = [
    "Localiser",
    "SensorNoise",
    "compass",
    "depth_sensor",
    "dvl",
    "kf_predict",
    "kf_update",
    "usbl_fix",
]
