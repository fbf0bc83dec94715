r"""Per-AUV cost of one decision; the reward is its negative (spec v2: one learning signal).

The cost is non-negative and bounded (LAC's convention); every term is clipped to ``[0, 1]``
before its weight, so :math:`c_j \in [0, c_{max}]`:

.. math::

    c_j = w_d \min\!\Big(1, \frac{d_j}{D}\Big)
        + w_p \min\!\Big(1, \frac{\max(0, -\Delta_j)}{v_{ref}\,\Delta t}\Big)
        + w_e \min\!\Big(1, \frac{P_j}{P_{ref}}\Big)
        + w_c\, \mathbb{1}[\text{collision}_j]
        + w_v\, \mathbb{1}[\text{violation}_j]
        + \frac{1}{N}\Big(w_b \frac{\sum_i b_i}{M\,C_{max}}
        + w_o \min\!\Big(1, \frac{N_{DO}}{\sum_i \lambda_i}\Big)\Big),

with :math:`d_j` the distance to the target after the decision (0 in service or without a
target), :math:`D` the area diagonal, :math:`\Delta_j` the progress toward the target held
during the decision (m; moving away is penalised, approaching is free), :math:`P_j` the EC
model power (moving power, or 105 W hovering), :math:`b_i` the packets still waiting in node
:math:`i` after the decision (the task's goal: serving a node empties its buffer and lowers
this term for as long as the node refills) and :math:`N_{DO}` the packets overflowed in the
decision, normalised by the packets expected per decision. The last two are properties of the
scene, not of an AUV: each AUV carries :math:`1/N` of them, so the scene's total (and the flat
layout's summed cost) counts them once. The reward is exactly :math:`-c_j`.

**Stability cost** (:func:`stability_cost`, ours; the Lyapunov critic's cost with
``lyapunov.cost=stability``): the AUV's own terms that say where it is against where it should
be,

.. math::

    c^{stab}_j = w_d \min\!\Big(1, \frac{d_j}{D}\Big)
        + w_p \min\!\Big(1, \frac{\max(0, -\Delta_j)}{v_{ref}\,\Delta t}\Big)
        + w_c\, \mathbb{1}[\text{collision}_j] + w_v\, \mathbb{1}[\text{violation}_j],

which is 0 in service (at its node, inside the area, clear of the others) and falls as the
AUV closes on its target: unlike :math:`c_j`, whose waiting-data term never vanishes, it can
satisfy a Lyapunov decrease condition (:class:`~torchrl_auv.objectives.LyapunovActorCriticLoss`).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from tensordict import TensorDict

from torchrl_auv.iout.config import IoUTConfig
from torchrl_auv.physics.energy import decision_power

__all__ = ["COST_TERMS", "STABILITY_TERMS", "CostWeights", "stability_cost", "task_cost"]

#: the names of the cost's terms, in the order of the module docstring
COST_TERMS = ("distance", "regress", "energy", "collision", "violation", "waiting", "overflow")
#: the terms of :func:`stability_cost` (those that vanish in service)
STABILITY_TERMS = ("distance", "regress", "collision", "violation")


@dataclass(frozen=True)
class CostWeights:
    """Weights and scales of :func:`task_cost` (all ours).

    Attributes:
        distance: :math:`w_d`, weight of the normalised distance to the target.
        regress: :math:`w_p`, weight of moving away from the target.
        energy: :math:`w_e`, weight of the normalised EC power.
        collision: :math:`w_c`, per AUV closer than the collision distance to another.
        violation: :math:`w_v`, per AUV outside the area or too close to seabed/surface.
        waiting: :math:`w_b`, weight of the fraction of the network's buffer capacity still
            holding data (shared by the AUVs).
        overflow: :math:`w_o`, weight of the overflowed fraction of a decision's arrivals
            (shared by the AUVs).
        reference_speed_mps: :math:`v_{ref}` (m/s), scale of the regress term.
        reference_power_w: :math:`P_{ref}` (W), scale of the energy term.
        max_discount: the largest discount factor :math:`\\gamma` a learner uses with this
            cost (the recipes' largest is 0.99); it sets the termination cost
            :meth:`termination_cost`.

    Examples:
        >>> CostWeights().collision
        5.0
        >>> CostWeights().max_cost(2)  # 1 + 1 + 0.2 + 5 + 5 + (2 + 0.5) / 2
        13.45
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
    waiting: float = 2.0
    overflow: float = 0.5
    reference_speed_mps: float = 2.0
    reference_power_w: float = 500.0
    max_discount: float = 0.99

    def __post_init__(self) -> None:
        for name in (
            "distance",
            "regress",
            "energy",
            "collision",
            "violation",
            "waiting",
            "overflow",
        ):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        for name in ("reference_speed_mps", "reference_power_w"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if not 0 <= self.max_discount < 1:
            raise ValueError(f"max_discount must be in [0, 1), got {self.max_discount}")

    def max_cost(self, num_auvs: int) -> float:
        """:math:`c_{max}`, the largest cost of one AUV in one decision (every term at 1)."""
        own = self.distance + self.regress + self.energy + self.collision + self.violation
        return own + (self.waiting + self.overflow) / num_auvs

    def termination_cost(self, num_auvs: int) -> float:
        """The terminal cost of the AUV that ends an episode: the largest discounted cost
        the whole scene could still accumulate, :math:`N c_{max} / (1 - \\gamma_{max})`, so
        ending an episode is never cheaper than continuing it, per AUV or for the scene."""
        return num_auvs * self.max_cost(num_auvs) / (1.0 - self.max_discount)

    def max_stability_cost(self) -> float:
        """The largest :func:`stability_cost` of one AUV in one decision (its terms at 1)."""
        return self.distance + self.regress + self.collision + self.violation

    def stability_termination_cost(self) -> float:
        """The terminal stability cost of the AUV that ends an episode,
        :math:`c^{stab}_{max} / (1 - \\gamma_{max})`: leaving is never cheaper than staying."""
        return self.max_stability_cost() / (1.0 - self.max_discount)


def task_cost(
    events: TensorDict,
    speed: torch.Tensor,
    buffer: torch.Tensor,
    node_rate: torch.Tensor,
    config: IoUTConfig,
    weights: CostWeights | None = None,
) -> tuple[torch.Tensor, TensorDict]:
    """Cost per AUV for one decision (module docstring); the reward is ``-cost``.

    Args:
        events: a decision's events from :func:`~torchrl_auv.iout.step`, batch ``[*B]``.
        speed: ``[*B, N]`` AUV speed over the decision (m/s), for the EC power.
        buffer: ``[*B, M]`` packets waiting in the nodes after the decision.
        node_rate: ``[*B, M]`` node arrival rates (packets/decision), to normalise overflow.
        config: task configuration (area, decision time, capacity).
        weights: cost weights (default :class:`CostWeights`).

    Returns:
        ``(cost, terms)``: ``[*B, N]`` cost in ``[0, weights.max_cost(N)]`` and a TensorDict
        (batch ``[*B, N]``) of the weighted terms ``distance``, ``regress``, ``energy``,
        ``collision``, ``violation``, ``waiting`` and ``overflow`` (summing to the cost).

    Examples:
        >>> events = TensorDict({
        ...     "target_distance": torch.tensor([100.0]), "progress": torch.tensor([-1.0]),
        ...     "hovering": torch.tensor([False]), "collision": torch.tensor([False]),
        ...     "violation": torch.tensor([True]), "overflow": torch.tensor(0.0)})
        >>> cost, terms = task_cost(events, torch.tensor([2.0]), torch.tensor([2500.0]),
        ...                         torch.tensor([4.0]), IoUTConfig(num_auvs=1, num_sensors=1))
        >>> round(terms["regress"].item(), 3), terms["violation"].item(), terms["waiting"].item()
        (0.5, 5.0, 1.0)
    """
    w = CostWeights() if weights is None else weights
    hovering = events["hovering"]
    dtype = events["target_distance"].dtype
    n_auv = hovering.shape[-1]
    distance = w.distance * (events["target_distance"] / config.area_diagonal_m).clamp(0.0, 1.0)
    step_m = w.reference_speed_mps * config.decision_dt_s
    regress = w.regress * ((-events["progress"]).clamp_min(0.0) / step_m).clamp(max=1.0)
    power = decision_power(speed, hovering).to(dtype)
    energy = w.energy * (power / w.reference_power_w).clamp(0.0, 1.0)
    collision = w.collision * events["collision"].to(dtype)
    violation = w.violation * events["violation"].to(dtype)
    capacity = buffer.shape[-1] * config.buffer_capacity
    waiting = (w.waiting * buffer.sum(-1) / capacity).to(dtype)
    expected = node_rate.sum(-1).clamp_min(1.0)
    overflow = (w.overflow * (events["overflow"] / expected).clamp(0.0, 1.0)).to(dtype)
    shared = ((waiting + overflow) / n_auv)[..., None].expand_as(energy)
    terms = TensorDict(
        {
            "distance": distance,
            "regress": regress,
            "energy": energy,
            "collision": collision,
            "violation": violation,
            "waiting": (waiting / n_auv)[..., None].expand_as(energy),
            "overflow": (overflow / n_auv)[..., None].expand_as(energy),
        },
        batch_size=hovering.shape,
        device=hovering.device,
    )
    cost = distance + regress + energy + collision + violation + shared
    return cost, terms


def stability_cost(terms: TensorDict) -> torch.Tensor:
    """The stability cost per AUV (module docstring): the sum of the weighted
    :data:`STABILITY_TERMS` of :func:`task_cost`'s ``terms``, ``[*B, N]``, 0 in service.

    Examples:
        >>> events = TensorDict({
        ...     "target_distance": torch.tensor([0.0]), "progress": torch.tensor([0.0]),
        ...     "hovering": torch.tensor([True]), "collision": torch.tensor([False]),
        ...     "violation": torch.tensor([False]), "overflow": torch.tensor(0.0)})
        >>> cost, terms = task_cost(events, torch.tensor([0.0]), torch.tensor([2500.0]),
        ...                         torch.tensor([4.0]), IoUTConfig(num_auvs=1, num_sensors=1))
        >>> stability_cost(terms).item(), cost.item() > 0  # in service: stable, yet data wait
        (0.0, True)
    """
    return sum(terms[name] for name in STABILITY_TERMS)
