r"""Per-AUV cost of one decision; the reward is its negative (task v3).

The design, its weights' reasons and the candidates measured on the way:
``docs/spec/data_collection.md``.

The cost is non-negative and bounded (LAC's convention): every term is clipped to ``[0, 1]``
before its weight, so :math:`0 \le c_j \le c_{max} = w_m + w_e + w_c + w_v`, and it is AUV
:math:`j`'s own: nothing another AUV does moves it but a collision they share.

.. math::

    c_j = w_m \begin{cases}
              1 - \min\!\big(1, \frac{R_j \tau_j}{R_{ref}\,\Delta t}\big)
                  & \text{in service (delivering)} \\
              \min\!\big(1, \frac{a_j}{A}\big) & \text{otherwise}
          \end{cases}
        + w_e \min\!\Big(1, \frac{P_j}{P_{ref}}\Big)
        + w_c\, \mathbb{1}[\text{collision}_j]
        + w_v\, \mathbb{1}[\text{violation}_j],

with :math:`R_j \tau_j` the bits AUV :math:`j` delivered in the decision (link rate times
time in service), :math:`R_{ref}` the link's rate at ``reference_distance_m`` (8 m, where
station keeping holds an AUV over its node: the most a decision can deliver), :math:`a_j`
the decisions since AUV :math:`j` last delivered data (the *age* of its last delivery, after
the decision; :math:`A` at reset: nothing delivered yet) and :math:`A` =
``config.age_scale`` (645 decisions by default: the time an average node takes to fill an
empty buffer, after which data overflows); :math:`P_j` the EC model's power (moving power
at the AUV's speed through the water, or 105 W in service). The reward is exactly
:math:`-c_j`.

**The mission term** (terms ``undelivered`` and ``delivery_age``). Delivering data is the
only thing that lowers it: a decision spent delivering at the reference rate costs 0, one in
which the AUV delivers nothing costs :math:`a_j / A`, growing with every decision since its
last delivery until it costs the whole weight. Summed over an episode the second part is the
area under the AUV's delivery-age sawtooth, the time-average *age of information* of its
deliveries (Kaul, Yates and Gruteser, INFOCOM 2012) divided by :math:`A`: a leg of
:math:`\ell` decisions between two services costs about :math:`\ell^2 / 2A`, so an AUV that
serves often on short legs pays little, and an idle AUV pays :math:`w_m` every decision. The
candidates measured and dropped on the way (the share of decisions without delivery; a
potential-based credit for closing on the target) are in ``docs/spec/data_collection.md``.

**Weights** (ours; the reasons in ``docs/spec/data_collection.md``): :math:`w_m = 1` (the
unit: a decision lost to the mission), :math:`w_e = 0.2` at :math:`P_{ref}` = 500 W (the
paper's EC objective, never worth more than a fifth of a lost decision: cruising at 2 m/s
costs about 0.1), :math:`w_c = 2` (a collision risks both vehicles), :math:`w_v = 1` (a
decision outside the area or within 1 m of the seabed or the surface is a decision lost to
the mission; leaving the area for good is paid by the termination cost, below).
:meth:`CostWeights.termination_cost` is :math:`N c_{max} / (1 - \gamma_{max})`, so ending an
episode is never cheaper than continuing it (spec v2's rule, kept).

**Stability cost** (:func:`stability_cost`, the Lyapunov critic's cost with
``lyapunov.cost=stability``): the AUV's own terms that say where it is against where it
should be, a separate signal and not part of the reward,

.. math::

    c^{stab}_j = w_d \min\!\Big(1, \frac{d_j}{D}\Big)
        + w_p \min\!\Big(1, \frac{\max(0, -\Delta_j)}{v_{ref}\,\Delta t}\Big)
        + w_c\, \mathbb{1}[\text{collision}_j] + w_v\, \mathbb{1}[\text{violation}_j],

with :math:`d_j` the distance to the target after the decision (0 in service or without a
target), :math:`D` the area's diagonal and :math:`\Delta_j` the progress toward the target
held during the decision (m). It is 0 in service (at the node, inside the area, clear of the
others) and falls as the AUV closes on its target, so it can satisfy a Lyapunov decrease
condition along an approach (:class:`~torchrl_auv.objectives.LyapunovActorCriticLoss`). It
shares the safety terms with :math:`c_j`; where :math:`c_j` pays for time without delivery,
:math:`c^{stab}_j` pays for distance from the next delivery, which is what shortens the age.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from tensordict import TensorDict

from torchrl_auv.iout.config import IoUTConfig
from torchrl_auv.iout.link import link_rate
from torchrl_auv.physics.energy import decision_power

__all__ = ["COST_TERMS", "STABILITY_TERMS", "CostWeights", "stability_cost", "task_cost"]

#: the names of the cost's terms (the env's ``"cost_terms"``), summing to the cost
COST_TERMS = ("undelivered", "delivery_age", "energy", "collision", "violation")
#: the terms of :func:`stability_cost`
STABILITY_TERMS = ("distance", "regress", "collision", "violation")


@dataclass(frozen=True)
class CostWeights:
    """Weights and scales of :func:`task_cost` and :func:`stability_cost` (all ours).

    Attributes:
        mission: :math:`w_m`, weight of the mission term (a decision lost to the mission).
        energy: :math:`w_e`, weight of the normalised EC power.
        collision: :math:`w_c`, per AUV closer than the collision distance to another.
        violation: :math:`w_v`, per AUV outside the area or too close to seabed/surface.
        distance: :math:`w_d`, the stability cost's weight of the normalised distance to the
            target (not in the task cost).
        regress: :math:`w_p`, the stability cost's weight of moving away from the target
            (not in the task cost).
        reference_distance_m: the node-AUV distance (m) whose link rate :math:`R_{ref}` counts
            as a fully delivering decision.
        reference_speed_mps: :math:`v_{ref}` (m/s), scale of the stability cost's regress term.
        reference_power_w: :math:`P_{ref}` (W), scale of the energy term.
        max_discount: the largest discount factor :math:`\\gamma` a learner uses with this
            cost (the recipes' largest is 0.99); it sets the termination costs.

    Examples:
        >>> CostWeights().max_cost()  # 1 + 0.2 + 2 + 1
        4.2
        >>> round(CostWeights().termination_cost(2), 6)  # 2 * 4.2 / (1 - 0.99)
        840.0
        >>> CostWeights(energy=-1.0)
        Traceback (most recent call last):
            ...
        ValueError: energy must be >= 0, got -1.0
    """

    mission: float = 1.0
    energy: float = 0.2
    collision: float = 2.0
    violation: float = 1.0
    distance: float = 1.0
    regress: float = 1.0
    reference_distance_m: float = 8.0
    reference_speed_mps: float = 2.0
    reference_power_w: float = 500.0
    max_discount: float = 0.99

    def __post_init__(self) -> None:
        for name in ("mission", "energy", "collision", "violation", "distance", "regress"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        for name in ("reference_distance_m", "reference_speed_mps", "reference_power_w"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if not 0 <= self.max_discount < 1:
            raise ValueError(f"max_discount must be in [0, 1), got {self.max_discount}")

    def max_cost(self) -> float:
        """:math:`c_{max}`, the largest cost of one AUV in one decision (every term at 1)."""
        return self.mission + self.energy + self.collision + self.violation

    def termination_cost(self, num_auvs: int) -> float:
        """The terminal cost of the AUV that ends an episode: the largest discounted cost
        the whole scene could still accumulate, :math:`N c_{max} / (1 - \\gamma_{max})`, so
        ending an episode is never cheaper than continuing it, per AUV or for the scene."""
        return num_auvs * self.max_cost() / (1.0 - self.max_discount)

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
    config: IoUTConfig,
    weights: CostWeights | None = None,
) -> tuple[torch.Tensor, TensorDict]:
    """Cost per AUV for one decision (module docstring); the reward is ``-cost``.

    Args:
        events: a decision's events from :func:`~torchrl_auv.iout.step`, batch ``[*B]``
            (``hovering``, ``rate``, ``service_time``, ``delivery_age``, ``collision``,
            ``violation``).
        speed: ``[*B, N]`` AUV speed through the water over the decision (m/s), for the power.
        config: task configuration (decision time, link, ``age_scale``).
        weights: cost weights (default :class:`CostWeights`).

    Returns:
        ``(cost, terms)``: ``[*B, N]`` cost in ``[0, weights.max_cost()]`` and a TensorDict
        (batch ``[*B, N]``) of the weighted :data:`COST_TERMS` (summing to the cost).

    Examples:
        >>> cfg = IoUTConfig(num_auvs=2, num_sensors=1)
        >>> events = TensorDict({  # AUV 0 delivers a whole decision at 29 kbit/s, AUV 1 idles
        ...     "hovering": torch.tensor([True, False]), "rate": torch.tensor([29.1e3, 0.0]),
        ...     "service_time": torch.tensor([1.0, 0.0]),
        ...     "delivery_age": torch.tensor([0.0, 1e4]),
        ...     "collision": torch.tensor([False, False]),
        ...     "violation": torch.tensor([False, True])})
        >>> cost, terms = task_cost(events, torch.tensor([0.0, 2.0]), cfg)
        >>> [round(v, 3) for v in terms["undelivered"].tolist()]  # 29.1 of 30.9 kbit/s
        [0.058, 0.0]
        >>> terms["delivery_age"].tolist(), terms["violation"].tolist()
        ([0.0, 1.0], [0.0, 1.0])
    """
    w = CostWeights() if weights is None else weights
    hovering = events["hovering"]
    dtype = events["service_time"].dtype
    reference = link_rate(torch.tensor(w.reference_distance_m, dtype=torch.float64), config)
    delivered = events["rate"].to(torch.float64) * events["service_time"].to(torch.float64)
    share = (delivered / (reference * config.decision_dt_s)).clamp(0.0, 1.0).to(dtype)
    undelivered = torch.where(hovering, w.mission * (1.0 - share), torch.zeros_like(share))
    age = (events["delivery_age"].to(dtype) / config.age_scale).clamp(0.0, 1.0)
    delivery_age = torch.where(hovering, torch.zeros_like(age), w.mission * age)
    power = decision_power(speed, hovering).to(dtype)
    energy = w.energy * (power / w.reference_power_w).clamp(0.0, 1.0)
    terms = TensorDict(
        {
            "undelivered": undelivered,
            "delivery_age": delivery_age,
            "energy": energy,
            "collision": w.collision * events["collision"].to(dtype),
            "violation": w.violation * events["violation"].to(dtype),
        },
        batch_size=hovering.shape,
        device=hovering.device,
    )
    cost = sum(terms[name] for name in COST_TERMS)
    return cost, terms


def stability_cost(
    events: TensorDict, config: IoUTConfig, weights: CostWeights | None = None
) -> torch.Tensor:
    """The stability cost per AUV (module docstring), ``[*B, N]``, 0 in service.

    Args:
        events: a decision's events from :func:`~torchrl_auv.iout.step` (``target_distance``,
            ``progress``, ``collision``, ``violation``).
        config: task configuration (area diagonal, decision time).
        weights: cost weights (default :class:`CostWeights`).

    Examples:
        >>> events = TensorDict({
        ...     "target_distance": torch.tensor([0.0, 141.4213562]),
        ...     "progress": torch.tensor([0.0, -1.0]),
        ...     "collision": torch.tensor([False, False]),
        ...     "violation": torch.tensor([False, False])})
        >>> [round(v, 3) for v in stability_cost(events, IoUTConfig()).tolist()]
        [0.0, 1.0]
    """
    w = CostWeights() if weights is None else weights
    dtype = events["target_distance"].dtype
    distance = (events["target_distance"] / config.area_diagonal_m).clamp(0.0, 1.0)
    step_m = w.reference_speed_mps * config.decision_dt_s
    regress = ((-events["progress"]).clamp_min(0.0) / step_m).clamp(max=1.0)
    return (
        w.distance * distance
        + w.regress * regress
        + w.collision * events["collision"].to(dtype)
        + w.violation * events["violation"].to(dtype)
    )
