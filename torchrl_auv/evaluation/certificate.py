r"""The Lyapunov certificate of a policy: does the decrease condition hold on the transitions
it executes in held-out scenes?

For each AUV and each decision :math:`t` of an evaluation episode that belongs to an approach
leg (:mod:`torchrl_auv.iout.legs`: not in service, the same target kept or reached), with the
executed actions :math:`a_t, a_{t+1}`, the stability cost :math:`c_t` of the decision and a
Lyapunov function :math:`L` with weight :math:`\alpha`,

.. math::

    \Delta L_t = (1 - e_t)(1 - d_t)\, L(s_{t+1}, a_{t+1}) - L(s_t, a_t) + \alpha\, c_t,

with :math:`e_t = 1` where the decision starts service (the leg's absorbing equilibrium,
:math:`L = 0`) and :math:`d_t = 1` where the AUV ended the episode. The condition holds at
:math:`t` when :math:`\Delta L_t \le 0`. A decision whose successor lies past the evaluated
decisions (and that neither starts service nor ends the episode) is not counted.

:class:`LyapunovCertificate` computes, for one evaluation row, ``lyapunov_transitions``
(:math:`n`), ``lyapunov_decrease_holds`` (the fraction that satisfy the condition),
``lyapunov_violation_upper95`` (the one-sided 95 % Clopper-Pearson upper bound on the
violation rate, :func:`clopper_pearson_upper`) and ``lyapunov_delta_mean``, and what
decides the fraction: ``lyapunov_change_std``, the standard deviation of the change
:math:`(1 - e_t)(1 - d_t) L(s_{t+1}, a_{t+1}) - L(s_t, a_t)`, against
``lyapunov_margin_mean``, the mean :math:`\alpha c_t` it must fall below (where the
change's spread is many times the margin, about half of the transitions violate whatever
the mean).

**Per leg.** A leg is a run of counted transitions of one AUV, each the successor of the last,
up to the first that is absorbed or whose successor is not counted (a target switch, the end
of the evaluated decisions). Its :math:`\Delta L_t` telescope to :math:`(1 - e)(1 - d)
L(s_{end}) - L(s_{start}) + \alpha \sum_t c_t`: the condition over the whole leg, in which
the decisions' noise averages out. ``lyapunov_legs`` counts them,
``lyapunov_leg_decrease_holds`` is the share whose sum is :math:`\le 0` and
``lyapunov_legs_arrived`` the share that ended by starting service. The bound treats
the transitions as independent draws; consecutive decisions of one AUV are not, so it is an
optimistic bound (the scenes, 16 by default, are the independent units).

Examples:
    >>> round(clopper_pearson_upper(0, 100), 4)  # 1 - 0.05 ** (1 / 100)
    0.0295
    >>> clopper_pearson_upper(5, 5)
    1.0
"""

from __future__ import annotations

import math

import torch
from tensordict import NestedKey, TensorDictBase

from torchrl_auv.envs.keys import (
    AGENT_ACTION,
    AGENT_APPROACH,
    AGENT_OBSERVATION,
    AGENT_SERVICE_START,
    AGENT_STABILITY_COST,
)
from torchrl_auv.modules.lyapunov_filter import critic_values
from torchrl_auv.modules.lyapunov_forms import LyapunovSpec

__all__ = ["CERTIFICATE_KEYS", "LyapunovCertificate", "clopper_pearson_upper"]

#: the row keys :class:`LyapunovCertificate` adds
CERTIFICATE_KEYS = (
    "lyapunov_transitions",
    "lyapunov_decrease_holds",
    "lyapunov_violation_upper95",
    "lyapunov_delta_mean",
    "lyapunov_change_std",
    "lyapunov_margin_mean",
    "lyapunov_legs",
    "lyapunov_leg_decrease_holds",
    "lyapunov_legs_arrived",
)


def _binomial_cdf(k: int, n: int, p: float) -> float:
    """:math:`P(X \\le k)` for :math:`X \\sim B(n, p)`, summed in log space (float64)."""
    if p <= 0.0:
        return 1.0
    if p >= 1.0:
        return 1.0 if k >= n else 0.0
    i = torch.arange(k + 1, dtype=torch.float64)
    log_pmf = (
        math.lgamma(n + 1)
        - torch.lgamma(i + 1)
        - torch.lgamma(n - i + 1)
        + i * math.log(p)
        + (n - i) * math.log1p(-p)
    )
    return float(torch.logsumexp(log_pmf, 0).exp().clamp(max=1.0))


def clopper_pearson_upper(violations: int, n: int, confidence: float = 0.95) -> float:
    """The one-sided Clopper-Pearson upper bound on a rate from ``violations`` out of ``n``:
    the :math:`p` at which :math:`P(X \\le k) = 1 - \\text{confidence}` (bisection to
    1e-12; the Beta(k + 1, n - k) quantile, computed without scipy). 1 for ``n = 0`` or
    ``k = n``.

    Raises:
        ValueError: ``violations`` outside ``[0, n]`` or ``confidence`` outside (0, 1).
    """
    if not 0 <= violations <= n:
        raise ValueError(f"violations must be in [0, n={n}], got {violations}")
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    if n == 0 or violations == n:
        return 1.0
    tail = 1.0 - confidence
    low, high = violations / n, 1.0
    while high - low > 1e-12:
        mid = 0.5 * (low + high)
        if _binomial_cdf(violations, n, mid) > tail:
            low = mid
        else:
            high = mid
    return high


class LyapunovCertificate:
    """The decrease condition on a rollout's executed approach transitions (module
    docstring): a ``transition_stats`` hook of
    :func:`~torchrl_auv.evaluation.episode_stats` (picklable with its critic, for evaluation
    workers).

    Args:
        critic: a module reading ``observation_key`` and ``action_key`` and writing
            ``raw_key``, the Lyapunov critic's raw output (the form is ``spec``'s).
        spec: the Lyapunov form, prior and :math:`\\alpha` (e.g. the loss's ``spec``).
        raw_key: the critic's output key.
        cost_key: the cost the critic learns (under ``"next"``; default the stability cost).
        observation_key, action_key: the per-AUV observation and the executed action.

    Examples:
        >>> from tensordict.nn import TensorDictModule
        >>> from torchrl_auv.envs import DataCollectionEnv
        >>> from torchrl_auv.evaluation import episode_stats, reference_policies
        >>> env = DataCollectionEnv(batch_size=[2], sea_state="ideal", seed=3, max_steps=30)
        >>> distance = TensorDictModule(  # a hand-made L: the target distance, any action
        ...     lambda o, a: o[..., 3:4], [("agents", "observation"), ("agents", "action")],
        ...     [("agents", "raw")])
        >>> certify = LyapunovCertificate(distance, LyapunovSpec(form="squared", alpha=0.1),
        ...                               raw_key=("agents", "raw"))
        >>> row = episode_stats(env, reference_policies()["expert"](env), 30,
        ...                     transition_stats=certify)
        >>> row["lyapunov_transitions"] > 0, 0 <= row["lyapunov_decrease_holds"] <= 1
        (True, True)
    """

    def __init__(
        self,
        critic,
        spec: LyapunovSpec,
        *,
        raw_key: NestedKey,
        cost_key: NestedKey = AGENT_STABILITY_COST,
        observation_key: NestedKey = AGENT_OBSERVATION,
        action_key: NestedKey = AGENT_ACTION,
    ) -> None:
        self.critic, self.spec = critic, spec
        self.raw_key, self.cost_key = raw_key, cost_key
        self.observation_key, self.action_key = observation_key, action_key

    def values(self, rollout: TensorDictBase) -> torch.Tensor:
        """:math:`L(s_t, a_t)` ``[B, T, N]`` of the executed actions."""
        observation, action = rollout[self.observation_key], rollout[self.action_key]
        parameters = getattr(self.critic, "parameters", None)
        first = next(iter(parameters()), None) if parameters is not None else None
        if first is not None:  # a critic on a GPU reads the rollout (on the CPU) there
            observation, action = observation.to(first.device), action.to(first.device)
        values = critic_values(
            self.critic,
            self.spec,
            observation,
            action.unsqueeze(-2),
            observation_key=self.observation_key,
            action_key=self.action_key,
            raw_key=self.raw_key,
        )
        return values[..., 0].cpu()

    def deltas(
        self, rollout: TensorDictBase, mask: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """:math:`\\Delta L_t` ``[B, T, N]`` and the mask of the counted transitions
        (module docstring); ``mask`` ``[B, T]``: the decisions of each scene's first
        episode."""
        value = self.values(rollout)
        nxt = rollout["next"]
        approach = nxt[AGENT_APPROACH][..., 0]
        absorbed = nxt[AGENT_SERVICE_START][..., 0] | nxt["agents", "terminated"][..., 0]
        cost = nxt[self.cost_key][..., 0]
        after = torch.cat([value[:, 1:], torch.zeros_like(value[:, :1])], 1)
        # the successor is in the same episode (not past the rollout, not a reset's)
        next_in_episode = torch.cat([mask[:, 1:], torch.zeros_like(mask[:, :1])], 1)
        delta = torch.where(absorbed, 0.0, after) - value + self.spec.alpha * cost
        counted = approach & mask[..., None] & (next_in_episode[..., None] | absorbed)
        return delta, counted

    @staticmethod
    def legs(
        delta: torch.Tensor, counted: torch.Tensor, arrived: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Each leg's summed :math:`\\Delta L` and whether it arrived (module docstring), from
        ``delta``, ``counted`` and ``arrived`` (service starts at the transition) ``[B, T, N]``;
        legs ordered by scene, AUV, then time.

        Examples:
            >>> delta = torch.tensor([1.0, -3.0, 2.0, 0.5, -1.0]).view(1, 5, 1)
            >>> counted = torch.tensor([True, True, True, False, True]).view(1, 5, 1)
            >>> arrived = torch.tensor([False, True, False, False, False]).view(1, 5, 1)
            >>> sums, ended = LyapunovCertificate.legs(delta, counted, arrived)
            >>> sums.tolist(), ended.tolist()
            ([-2.0, 2.0, -1.0], [True, False, False])
        """
        series = counted.transpose(1, 2).reshape(-1, counted.shape[1])  # [B N, T]
        closes = (arrived & counted).transpose(1, 2).reshape(series.shape)
        before = torch.cat([torch.zeros_like(series[:, :1]), series[:, :-1]], 1)
        closed_before = torch.cat([torch.zeros_like(closes[:, :1]), closes[:, :-1]], 1)
        starts = series & ~(before & ~closed_before)
        # each counted transition's leg: the legs started up to it, series after series
        index = (starts.reshape(-1).long().cumsum(0) - 1)[series.reshape(-1)]
        n = int(starts.sum())
        values = delta.transpose(1, 2).reshape(series.shape)[series].double()
        sums = torch.zeros(n, dtype=torch.float64).index_add_(0, index, values)
        ended = torch.zeros(n, dtype=torch.bool).index_put_((index,), closes[series], True)
        return sums, ended

    def __call__(self, rollout: TensorDictBase, mask: torch.Tensor) -> dict[str, float]:
        delta, counted = self.deltas(rollout, mask)
        n = int(counted.sum())
        violations = int((counted & (delta > 0)).sum())
        nxt = rollout["next"]
        counted_delta = delta[counted].double()
        margin = (self.spec.alpha * nxt[self.cost_key][..., 0])[counted].double()
        sums, ended = self.legs(delta, counted, nxt[AGENT_SERVICE_START][..., 0])
        legs, nan = sums.numel(), float("nan")
        return {
            "lyapunov_transitions": float(n),
            "lyapunov_decrease_holds": (n - violations) / n if n else nan,
            "lyapunov_violation_upper95": clopper_pearson_upper(violations, n),
            "lyapunov_delta_mean": counted_delta.mean().item() if n else nan,
            "lyapunov_change_std": (counted_delta - margin).std().item() if n > 1 else nan,
            "lyapunov_margin_mean": margin.mean().item() if n else nan,
            "lyapunov_legs": float(legs),
            "lyapunov_leg_decrease_holds": (sums <= 0).double().mean().item() if legs else nan,
            "lyapunov_legs_arrived": ended.double().mean().item() if legs else nan,
        }
