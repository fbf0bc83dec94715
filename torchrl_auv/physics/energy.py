r"""Energy models for the task metrics (``docs/spec/data_collection.md``, "Metrics").

* The data-collection papers' EC model: a moving AUV at speed :math:`V` draws

  .. math::

      P(V) = \frac{F V}{\eta(V)} + 15\ \mathrm{W},\qquad F = \frac{0.7 \cdot 60\, V^2}{2},\qquad
      \eta(V) = -0.081 V^3 + 0.215 V^2 - 0.01 V + 0.541,

  and a hovering AUV draws :data:`HOVER_POWER` = 105 W. The efficiency polynomial has its only
  real root at :data:`EC_MAX_SPEED` :math:`\approx 3.249` m/s: above it :math:`P` turns negative,
  and it grows steeply before (630 W at 2.55 m/s, 2.2 kW at 3 m/s). :math:`F` is a drag, so
  :math:`V` is naturally the speed through the water; an over-ground speed in a strong following
  current can leave the model's range.
* The shaft power of the REMUS-100 propeller model, :math:`P_s = 2\pi n_s Q` with :math:`n_s` in
  rev/s and :math:`Q` the propeller torque of
  :func:`torchrl_auv.physics.remus100.propeller_forces`: a physically grounded companion metric
  (about 173 W at the 1525 rpm cruise).
"""

from __future__ import annotations

import math

import torch

from torchrl_auv.physics.remus100 import DEFAULT_PARAMS, Remus100Params, propeller_forces, saturate

__all__ = [
    "EC_MAX_SPEED",
    "HOTEL_POWER",
    "HOVER_POWER",
    "decision_power",
    "episode_energy_consumption",
    "moving_power",
    "shaft_power",
]

HOVER_POWER = 105.0  # W, while hovering over a sensor node
HOTEL_POWER = 15.0  # W, the constant term of the moving-power model
EC_MAX_SPEED = 3.2490322461803265  # m/s, the real root of eta(V): the EC model's upper limit


def moving_power(speed: torch.Tensor | float) -> torch.Tensor:
    r"""EC model power of a moving AUV (W), :math:`F V / \eta(V) + 15` (module docstring).

    Args:
        speed: speed :math:`V` (m/s), any shape; valid for :math:`0 \le V <` :data:`EC_MAX_SPEED`.

    Returns:
        Power (W), shaped like ``speed``.

    >>> round(moving_power(torch.tensor(2.0)).item(), 2)
    244.2
    """
    speed = torch.as_tensor(speed)
    drag = 0.7 * 60.0 * speed**2 / 2.0
    efficiency = -0.081 * speed**3 + 0.215 * speed**2 - 0.01 * speed + 0.541
    return drag * speed / efficiency + HOTEL_POWER


def decision_power(speed: torch.Tensor, hovering: torch.Tensor) -> torch.Tensor:
    """EC model power (W) per decision: :data:`HOVER_POWER` if hovering, else :func:`moving_power`.

    Args:
        speed: speed (m/s), ``[*B]``.
        hovering: whether the AUV hovers (in service) during the decision, bool, ``[*B]``.

    >>> decision_power(torch.tensor([2.0, 2.0]), torch.tensor([False, True])).tolist()
    [244.19508361816406, 105.0]
    """
    return torch.where(hovering, torch.full_like(speed, HOVER_POWER), moving_power(speed))


def episode_energy_consumption(
    speed: torch.Tensor, hovering: torch.Tensor, *, include_hovering: bool = False
) -> torch.Tensor:
    """The EC metric: mean power (W) over an episode's non-hovering decisions, per AUV.

    The paper's EC is then the mean of this over AUVs.

    Args:
        speed: speed at each decision (m/s), ``[*B, T]`` (decisions last).
        hovering: whether each decision hovers, bool, ``[*B, T]``.
        include_hovering: average :func:`decision_power` over all decisions instead (hovering at
            105 W), a variant for comparison.

    Returns:
        ``[*B]`` (W); NaN for an AUV that never moved (with ``include_hovering=False``).

    >>> speed = torch.tensor([[2.0, 2.0, 1.0]])
    >>> hovering = torch.tensor([[False, True, False]])
    >>> episode_energy_consumption(speed, hovering)  # (244.20 + 46.58) / 2
    tensor([145.3870])
    >>> episode_energy_consumption(speed, hovering, include_hovering=True)  # (... + 105) / 3
    tensor([131.9247])
    """
    if speed.shape != hovering.shape or speed.dim() < 1:
        raise ValueError(
            f"speed and hovering must share a shape [*B, T], got {tuple(speed.shape)} and "
            f"{tuple(hovering.shape)}"
        )
    if include_hovering:
        return decision_power(speed, hovering).mean(-1)
    moving = ~hovering
    total = torch.where(moving, moving_power(speed), torch.zeros_like(speed)).sum(-1)
    return total / moving.sum(-1).to(speed.dtype)


def shaft_power(
    n_rpm: torch.Tensor | float,
    speed: torch.Tensor | float,
    params: Remus100Params | None = None,
) -> torch.Tensor:
    r"""Propeller shaft power :math:`P_s = 2\pi (\bar n/60)\,Q(\bar n, U)` (W).

    :math:`\bar n` is the propeller state saturated as in the dynamics (spec Sec. 5), and
    :math:`Q` the full propeller torque of
    :func:`~torchrl_auv.physics.remus100.propeller_forces` (spec Sec. 4.6). Reverse rpm gives
    :math:`n_s Q = K_{Q0}\rho D^5 |n_s|^3 \ge 0`: the shaft still takes power.

    Args:
        n_rpm: propeller state (rpm), ``[*B]``.
        speed: absolute vehicle speed :math:`U` (m/s), ``[*B]``, for the advance ratio.
        params: vehicle parameters (default REMUS-100).

    Returns:
        Shaft power (W), ``[*B]``.

    >>> round(shaft_power(torch.tensor(1525.0), torch.tensor(2.5536)).item(), 1)
    172.9
    """
    p = DEFAULT_PARAMS if params is None else params
    n = saturate(torch.as_tensor(n_rpm), p.n_max)
    _, torque = propeller_forces(n, torch.as_tensor(speed, dtype=n.dtype), p)
    return 2.0 * math.pi * (n / 60.0) * torque
