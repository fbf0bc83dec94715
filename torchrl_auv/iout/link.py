r"""Sensor-node-to-AUV acoustic link rate with the task's parameters.

The formulas live in :mod:`torchrl_auv.physics.acoustics` (noise PSDs, Thorp absorption,
:math:`TL = 15\log_{10} d + \alpha d/1000`, :math:`SL = 10\log_{10} P + 170.77`, the better of
:math:`f \pm B/2`); this module only feeds them an :class:`~torchrl_auv.iout.IoUTConfig`:

.. math::

    R = B \log_2\!\big(1 + 10^{SNR/10}\big)\ \text{(shannon)},\qquad
    R = B \log_2\!\big(1 + 10^{SNR}\big)\ \text{(paper)}.

A configured source-level constant other than 170.77 dB enters as the equivalent transmit
power :math:`P' = P\,10^{(\text{offset} - 170.77)/10}`, which gives the same :math:`SL`.
"""

from __future__ import annotations

import torch

from torchrl_auv.iout.config import IoUTConfig
from torchrl_auv.physics import acoustics

__all__ = ["link_rate"]

_PHYSICS_SL_OFFSET_DB = 170.77  # the constant of physics.acoustics.source_level_db


def link_rate(distance_m: torch.Tensor, config: IoUTConfig) -> torch.Tensor:
    """Link rate (bit/s) from a node to an AUV ``distance_m`` away.

    Args:
        distance_m: 3-D node-AUV distance (m), any shape; distances below 1 m count as 1 m.
        config: link parameters (``carrier_khz``, ``bandwidth_hz``, ``shipping``, ``wind_mps``,
            ``source_power_w``, ``source_level_offset_db``, ``rate_model``).

    Returns:
        Rate (bit/s), shaped and typed like ``distance_m``; decreasing in distance.

    Examples:
        >>> d = torch.tensor([18.0, 100.0])
        >>> shannon = link_rate(d, IoUTConfig())
        >>> paper = link_rate(d, IoUTConfig(rate_model="paper"))
        >>> [round(r / 1e3, 1) for r in shannon.tolist()]  # kbit/s
        [29.1, 25.3]
        >>> [round(r / 1e3, 1) for r in paper.tolist()]
        [291.4, 253.1]
    """
    power = config.source_power_w * 10.0 ** (
        (config.source_level_offset_db - _PHYSICS_SL_OFFSET_DB) / 10.0
    )
    return acoustics.link_rate(
        distance_m,
        rate_model=config.rate_model,
        f_khz=config.carrier_khz,
        bandwidth_hz=config.bandwidth_hz,
        power_w=power,
        shipping=config.shipping,
        wind=config.wind_mps,
    )
