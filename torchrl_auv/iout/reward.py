r"""Per-AUV cost and reward of one decision.

The cost is non-negative (LAC's convention) and sums five terms, each scaled to order one:

.. math::

    c_j = w_d \min\!\Big(1, \frac{d_j}{D}\Big)
        + w_p \frac{\max(0, -\Delta_j)}{v_{ref}\,\Delta t}
        + w_e \frac{P_j}{P_{ref}}
        + w_c\, \mathbb{1}[\text{collision}_j]
        + w_v\, \mathbb{1}[\text{violation}_j]
        + w_o \frac{N_{DO}}{\sum_i \lambda_i},

with :math:`d_j` the distance to the target after the decision (0 in service or without a
target), :math:`D` the area diagonal, :math:`\Delta_j` the progress toward the target held
during the decision (m; moving away is penalised, approaching is free), :math:`P_j` the EC
model power (moving power, or 105 W hovering), :math:`N_{DO}` the packets overflowed in the
decision in the scene (shared by all AUVs) normalised by the packets expected per decision.
The reward adds a bonus per completed service:

.. math::

    r_j = -c_j + w_s\, \mathbb{1}[\text{service completed}_j].
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from tensordict import TensorDict

from torchrl_auv.iout.config import IoUTConfig
from torchrl_auv.physics.energy import decision_power

__all__ = ["CostWeights", "task_cost"]


@dataclass(frozen=True)
class CostWeights:
    """Weights and scales of :func:`task_cost` (all ours).

    Attributes:
        distance: :math:`w_d`, weight of the normalised distance to the target.
        regress: :math:`w_p`, weight of moving away from the target.
        energy: :math:`w_e`, weight of the normalised EC power.
        collision: :math:`w_c`, per AUV closer than the collision distance to another.
        violation: :math:`w_v`, per AUV outside the area or too close to seabed/surface.
        overflow: :math:`w_o`, weight of the overflowed fraction of a decision's arrivals.
        service_bonus: :math:`w_s`, reward per completed service.
        reference_speed_mps: :math:`v_{ref}` (m/s), scale of the regress term.
        reference_power_w: :math:`P_{ref}` (W), scale of the energy term.

    Examples:
        >>> CostWeights().collision
        5.0
        >>> CostWeights(energy=-1.0)
        Traceback (most recent call last):
            ...
        ValueError: energy must be >= 0, got -1.0
    """

    distance: float = 1.0
    regress: float = 1.0
    energy: float = 0.2
    collision: float = 5.0
    violation: float = 5.0
    overflow: float = 0.5
    service_bonus: float = 5.0
    reference_speed_mps: float = 2.0
    reference_power_w: float = 500.0

    def __post_init__(self) -> None:
        for name in (
            "distance",
            "regress",
            "energy",
            "collision",
            "violation",
            "overflow",
            "service_bonus",
        ):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        for name in ("reference_speed_mps", "reference_power_w"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")


def task_cost(
    events: TensorDict,
    speed: torch.Tensor,
    node_rate: torch.Tensor,
    config: IoUTConfig,
    weights: CostWeights | None = None,
) -> tuple[torch.Tensor, torch.Tensor, TensorDict]:
    """Cost and reward per AUV for one decision (module docstring).

    Args:
        events: a decision's events from :func:`~torchrl_auv.iout.step`, batch ``[*B]``.
        speed: ``[*B, N]`` AUV speed over the decision (m/s), for the EC power.
        node_rate: ``[*B, M]`` node arrival rates (packets/decision), to normalise overflow.
        config: task configuration (area, decision time).
        weights: cost weights (default :class:`CostWeights`).

    Returns:
        ``(cost, reward, terms)``: ``[*B, N]`` cost (>= 0) and reward, and a TensorDict
        (batch ``[*B, N]``) of the weighted terms ``distance``, ``regress``, ``energy``,
        ``collision``, ``violation``, ``overflow`` and the ``service_bonus``.

    Examples:
        >>> events = TensorDict({
        ...     "target_distance": torch.tensor([100.0]), "progress": torch.tensor([-1.0]),
        ...     "hovering": torch.tensor([False]), "completed": torch.tensor([False]),
        ...     "collision": torch.tensor([False]), "violation": torch.tensor([True]),
        ...     "overflow": torch.tensor(0.0)})
        >>> cost, reward, terms = task_cost(events, torch.tensor([2.0]), torch.tensor([4.0]),
        ...                                 IoUTConfig(num_auvs=1))
        >>> round(terms["regress"].item(), 3), terms["violation"].item()
        (0.5, 5.0)
        >>> bool(cost >= 0) and bool(reward == -cost)
        True
    """
    w = CostWeights() if weights is None else weights
    hovering = events["hovering"]
    dtype = events["target_distance"].dtype
    distance = w.distance * (events["target_distance"] / config.area_diagonal_m).clamp(0.0, 1.0)
    regress = (
        w.regress
        * (-events["progress"]).clamp_min(0.0)
        / (w.reference_speed_mps * config.decision_dt_s)
    )
    energy = w.energy * decision_power(speed, hovering).to(dtype) / w.reference_power_w
    collision = w.collision * events["collision"].to(dtype)
    violation = w.violation * events["violation"].to(dtype)
    expected = node_rate.sum(-1).clamp_min(1.0)
    overflow = (w.overflow * events["overflow"] / expected).to(dtype)[..., None].expand_as(energy)
    terms = TensorDict(
        {
            "distance": distance,
            "regress": regress,
            "energy": energy,
            "collision": collision,
            "violation": violation,
            "overflow": overflow,
        },
        batch_size=hovering.shape,
        device=hovering.device,
    )
    cost = distance + regress + energy + collision + violation + overflow
    bonus = w.service_bonus * events["completed"].to(dtype)
    terms.set("service_bonus", bonus)
    return cost, bonus - cost, terms
