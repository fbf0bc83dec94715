r"""Per-episode task metrics of the paper, accumulated decision by decision.

With :math:`h_{jk}` whether AUV :math:`j` hovers (is in service) in decision :math:`k`,
:math:`\tau_{jk}` its time in service during the decision (s: the decision's 1 s, or the
fraction left in a service's last decision), :math:`R_{jk}` its link rate (bit/s),
:math:`V_{jk}` its speed (m/s), :math:`P^s_{jk}` its shaft power (W) and :math:`N` AUVs:

.. math::

    \mathrm{SDR} = \sum_k \sum_j R_{jk}\,\tau_{jk} / 10^6 \quad (\text{Mbit}),\qquad
    \mathrm{SSN} = \#\text{completed services},

    \mathrm{EC} = \frac{1}{N}\sum_j
        \frac{\sum_k (1 - h_{jk})\, P(V_{jk})}{\sum_k (1 - h_{jk})}\ \mathrm{W},\qquad
    \mathrm{EC}_{hover} = \frac{1}{N}\sum_j \frac{1}{K}\sum_k
        \big[(1 - h_{jk}) P(V_{jk}) + 105\, h_{jk}\big],

    \text{shaft power} = \frac{1}{N K}\sum_{j,k} P^s_{jk},

SDR is the data delivered in the episode in Mbit; with 1 s decisions it equals the sum of
the per-decision rates in Mbit/s, which the paper labels "MBit/s" (tables say "Mbit, the
paper's MBit/s"). With :math:`P(V)` the moving power of
:func:`torchrl_auv.physics.energy.moving_power`; EC
averages over the non-hovering decisions as the spec says, ``ec_with_hover`` (an extra, for
comparison) over all decisions with 105 W while hovering. ``collisions`` counts decisions in
which some pair of AUVs is closer than 5 m, ``violations`` counts (AUV, decision) pairs in
violation, ``overflow`` the packets lost (``N_DO``), ``services_inside`` the completed
services that ended with the AUV within the service radius of its node (station keeping held
it there; ``services_inside / ssn`` is the fraction).
"""

from __future__ import annotations

import torch
from tensordict import TensorDict

from torchrl_auv.iout.config import IoUTConfig
from torchrl_auv.physics.energy import HOVER_POWER, moving_power

__all__ = ["METRIC_KEYS", "TaskMetrics"]

METRIC_KEYS = ("sdr", "ssn", "ec", "shaft_power", "collisions", "violations", "overflow")


class TaskMetrics:
    """Accumulator of the task metrics, carried as a TensorDict (``[*B]``) in env state.

    The accumulator keys are ``sdr`` (Mbit), ``ssn``, ``collisions``,
    ``violations``, ``overflow`` (``[*B]``), ``decisions`` (``[*B]``), and per AUV
    (``[*B, N]``) ``moving_power_sum`` (W), ``moving_decisions``, ``hover_decisions`` and
    ``shaft_power_sum`` (W). Counts are int64, sums follow the dtype.

    Args:
        config: task configuration (number of AUVs).

    Examples:
        >>> metrics = TaskMetrics(IoUTConfig(num_auvs=1))
        >>> acc = metrics.init((), dtype=torch.float64)
        >>> events = TensorDict({
        ...     "hovering": torch.tensor([False]), "rate": torch.tensor([0.0]),
        ...     "service_time": torch.tensor([0.0]), "held_distance": torch.tensor([0.0]),
        ...     "completed": torch.tensor([False]), "collision": torch.tensor([False]),
        ...     "violation": torch.tensor([False]), "overflow": torch.tensor(0.0)})
        >>> acc = metrics.update(acc, events, torch.tensor([2.0]), torch.tensor([100.0]))
        >>> out = metrics.finalize(acc)
        >>> round(out["ec"].item(), 2), out["shaft_power"].item()
        (244.2, 100.0)
    """

    def __init__(self, config: IoUTConfig) -> None:
        self.config = config

    def init(
        self,
        batch_shape: tuple[int, ...] | torch.Size,
        *,
        dtype: torch.dtype = torch.float32,
        device: torch.device | str | None = None,
    ) -> TensorDict:
        """A zero accumulator with batch ``batch_shape``."""
        shape = torch.Size(batch_shape)
        auv = (*shape, self.config.num_auvs)

        def count(size: tuple[int, ...] | torch.Size) -> torch.Tensor:
            return torch.zeros(size, dtype=torch.long, device=device)

        def total(size: tuple[int, ...] | torch.Size) -> torch.Tensor:
            return torch.zeros(size, dtype=dtype, device=device)

        return TensorDict(
            {
                "sdr": total(shape),
                "ssn": count(shape),
                "ends_inside": count(shape),
                "collisions": count(shape),
                "violations": count(shape),
                "overflow": count(shape),
                "decisions": count(shape),
                "moving_power_sum": total(auv),
                "moving_decisions": count(auv),
                "hover_decisions": count(auv),
                "shaft_power_sum": total(auv),
            },
            batch_size=shape,
            device=device,
        )

    def update(
        self,
        acc: TensorDict,
        events: TensorDict,
        speed: torch.Tensor,
        shaft_power: torch.Tensor,
    ) -> TensorDict:
        """Add one decision.

        Args:
            acc: accumulator from :meth:`init` or a previous :meth:`update` (left unchanged).
            events: a decision's events from :func:`~torchrl_auv.iout.step` (``hovering``,
                ``rate``, ``service_time``, ``completed``, ``held_distance``, ``collision``,
                ``violation``, ``overflow``).
            speed: ``[*B, N]`` AUV speed over the decision (m/s) for the EC model.
            shaft_power: ``[*B, N]`` propeller shaft power :math:`2\\pi n Q` (W).

        Returns:
            The new accumulator.
        """
        hovering = events["hovering"]
        moving = ~hovering
        near = events["held_distance"] <= self.config.service_radius_m
        inside = events["completed"] & near
        sums = acc["moving_power_sum"]
        power = torch.where(moving, moving_power(speed).to(sums.dtype), torch.zeros_like(sums))
        delivered = events["rate"] * events["service_time"]  # bit (0 when not in service)
        mbit = torch.where(hovering, delivered, torch.zeros_like(delivered)) / 1e6
        return TensorDict(
            {
                "sdr": acc["sdr"] + mbit.sum(-1).to(acc["sdr"].dtype),
                "ssn": acc["ssn"] + events["completed"].sum(-1),
                "ends_inside": acc["ends_inside"] + inside.sum(-1),
                "collisions": acc["collisions"] + events["collision"].any(-1).long(),
                "violations": acc["violations"] + events["violation"].sum(-1),
                "overflow": acc["overflow"] + events["overflow"].round().long(),
                "decisions": acc["decisions"] + 1,
                "moving_power_sum": sums + power,
                "moving_decisions": acc["moving_decisions"] + moving.long(),
                "hover_decisions": acc["hover_decisions"] + hovering.long(),
                "shaft_power_sum": acc["shaft_power_sum"] + shaft_power.to(sums.dtype),
            },
            batch_size=acc.batch_size,
            device=acc.device,
        )

    def finalize(self, acc: TensorDict) -> TensorDict:
        """The episode metrics, batch ``[*B]``: :data:`METRIC_KEYS` plus ``ec_with_hover``.

        ``ec`` is NaN only if every AUV hovered through the whole episode (an AUV that never
        moved is left out of the mean over AUVs).
        """
        sums = acc["moving_power_sum"]
        moving = acc["moving_decisions"].to(sums.dtype)
        decisions = acc["decisions"].to(sums.dtype)[..., None]
        per_auv = sums / moving
        hover_energy = HOVER_POWER * acc["hover_decisions"].to(sums.dtype)
        return TensorDict(
            {
                "sdr": acc["sdr"],
                "ssn": acc["ssn"],
                "services_inside": acc["ends_inside"],
                "ec": per_auv.nanmean(-1),
                "ec_with_hover": ((sums + hover_energy) / decisions).mean(-1),
                "shaft_power": (acc["shaft_power_sum"] / decisions).mean(-1),
                "collisions": acc["collisions"],
                "violations": acc["violations"],
                "overflow": acc["overflow"],
            },
            batch_size=acc.batch_size,
            device=acc.device,
        )
