r"""Energy models for the task metrics.

* The data-collection papers' EC model (``shared/spec/data_collection.md``, "Metrics"): a
  moving AUV draws

  .. math::

      P(V) = \frac{F V}{\eta(V)} + 15\ \mathrm{W},\quad F = \frac{0.7 \cdot 60\, V^2}{2},\quad
      \eta(V) = -0.081 V^3 + 0.215 V^2 - 0.01 V + 0.541,

  and a hovering AUV draws :data:`HOVER_POWER` = 105 W.
* The shaft power of the REMUS-100 propeller model, :math:`P_s = 2\pi n_s Q` with
  :math:`n_s` in rev/s and :math:`Q` the propeller torque of
  :func:`torchrl_auv.physics.remus100.propeller_forces`: a physically grounded companion metric.
"""

from __future__ import annotations

import math

import torch

from torchrl_auv.physics.remus100 import DEFAULT_PARAMS, Remus100Params, propeller_forces, saturate

__all__ = ["HOTEL_POWER", "HOVER_POWER", "moving_power", "shaft_power"]

HOVER_POWER = 105.0  # W, while hovering over a sensor node
HOTEL_POWER = 15.0  # W, the constant term of the moving-power model


def moving_power(speed: torch.Tensor) -> torch.Tensor:
    """EC model power of a moving AUV (W) at speed ``speed`` (m/s); see the module docstring.

    >>> round(moving_power(torch.tensor(2.0)).item(), 2)
    244.2
    """
    speed = torch.as_tensor(speed)
    drag = 0.7 * 60.0 * speed**2 / 2.0
    efficiency = -0.081 * speed**3 + 0.215 * speed**2 - 0.01 * speed + 0.541
    return drag * speed / efficiency + HOTEL_POWER


def shaft_power(
    n_rpm: torch.Tensor, speed: torch.Tensor, params: Remus100Params | None = None
) -> torch.Tensor:
    r"""Propeller shaft power :math:`2\pi (n/60) Q` (W) at the saturated propeller speed.

    Args:
        n_rpm: propeller state (rpm); saturated at the model's limit as in the dynamics.
        speed: absolute vehicle speed (m/s), for the propeller's advance ratio.
        params: vehicle parameters (default REMUS-100).

    >>> round(shaft_power(torch.tensor(1525.0), torch.tensor(2.5536)).item(), 1)
    172.9
    """
    p = DEFAULT_PARAMS if params is None else params
    n = saturate(torch.as_tensor(n_rpm), p.n_max)
    _, torque = propeller_forces(n, torch.as_tensor(speed, dtype=n.dtype), p)
    return 2.0 * math.pi * (n / 60.0) * torque
