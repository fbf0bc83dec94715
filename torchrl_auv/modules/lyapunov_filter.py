r"""``LyapunovFilter``: the decrease condition applied to the action that is executed.

At decision :math:`t`, with the previous decision's state :math:`s_{t-1}`, its executed action
:math:`a_{t-1}` and its cost :math:`c_{t-1}` (the state-action history's last pair and the
env's cost observation), a candidate first action :math:`a_k` is **feasible** when executing
it keeps the Lyapunov decrease condition of the transition just made,

.. math::

    L(s_t, a_k) - L(s_{t-1}, a_{t-1}) + \alpha\, c_{t-1} \le 0 .

The filter applies where the previous decision was part of an approach leg that goes on (the
``on_leg`` flag set, the ``equilibrium`` flag not: :mod:`torchrl_auv.iout.legs`) and the
history holds that pair; elsewhere (after a reset, in service, after a target switch) every
candidate is feasible. Where it applies and no candidate is feasible, the fallback is the
candidate of least :math:`L(s_t, a_k)`, the one that violates least. The
:class:`~torchrl_auv.modules.CandidateSelector` that holds a filter ranks the feasible
candidates with its own critic (e.g. a task critic): the constraint decides what may be
executed, the task decides what is. Two ways to rank (``mode``, :data:`FILTER_MODES`):

- ``"rank"``: the selector's rule among the feasible candidates (an anchored rule keeps its
  anchor unless a feasible candidate beats it, or the anchor is infeasible);
- ``"veto"``: the anchor (the prior's choice) wherever it is feasible; where it is not, the
  rule's choice among the feasible ones. The critic ranks only where the constraint vetoes the
  prior, so a noisy task critic moves only the decisions the prior gets wrong.

Examples:
    >>> from tensordict import TensorDict
    >>> from tensordict.nn import TensorDictModule
    >>> critic = TensorDictModule(lambda o, a: o[..., :1] + a[..., :1],  # L = (o0 + a0)^2
    ...                           ["observation", "action"], ["raw"])
    >>> screen = LyapunovFilter(critic, spec=LyapunovSpec(form="squared", alpha=0.5),
    ...                         raw_key="raw")
    >>> td = TensorDict({"observation": torch.ones(1, 1), "cost": torch.ones(1, 1),
    ...     "approach": torch.ones(1, 1, dtype=torch.bool),
    ...     "service_start": torch.zeros(1, 1, dtype=torch.bool),
    ...     ("history", "observation"): torch.full((1, 3, 1), 2.0),
    ...     ("history", "action"): torch.zeros(1, 3, 1),
    ...     ("history", "mask"): torch.ones(1, 3, dtype=torch.bool)}, [1])
    >>> feasible, values, applies = screen(td, torch.tensor([[[0.0], [1.5], [-3.0]]]))
    >>> values.tolist(), feasible.tolist(), applies.tolist()  # bound: (2 + 0)^2 - 0.5 = 3.5
    ([[1.0, 6.25, 4.0]], [[True, False, False]], [True])
"""

from __future__ import annotations

import torch
from tensordict import NestedKey, TensorDict, TensorDictBase, unravel_key
from tensordict.nn import TensorDictModuleBase

from torchrl_auv.modules.lyapunov_forms import LyapunovSpec, LyapunovSpecState, lyapunov_value

__all__ = [
    "FILTER_MODES",
    "INFEASIBLE_SCORE",
    "LyapunovFilter",
    "allowed_candidates",
    "critic_values",
    "filtered_choice",
]

#: how a filtered selection ranks the feasible candidates (module docstring)
FILTER_MODES = ("rank", "veto")
#: the score a candidate the filter excludes gets (finite: differences of two stay 0, not nan)
INFEASIBLE_SCORE = -1.0e9


def critic_values(
    critic,
    spec: LyapunovSpec,
    observation: torch.Tensor,
    actions: torch.Tensor,
    *,
    observation_key: NestedKey,
    action_key: NestedKey,
    raw_key: NestedKey,
) -> torch.Tensor:
    """:math:`L(o, a_k)` ``[*B, K]`` of a Lyapunov ``critic`` (raw output at ``raw_key``, the
    form and prior ``spec``'s) for ``observation`` ``[*B, d]`` and ``actions`` ``[*B, K, A]``,
    without gradient."""
    k = actions.shape[-2]
    obs = observation.unsqueeze(-2).expand(*observation.shape[:-1], k, observation.shape[-1])
    td = TensorDict({observation_key: obs, action_key: actions}, batch_size=actions.shape[:-1])
    with torch.no_grad():
        raw = critic(td)[raw_key]
    return lyapunov_value(raw, spec, obs if spec.prior else None)[..., 0]


class LyapunovFilter(torch.nn.Module):
    """Which candidates keep the decrease condition (module docstring).

    Args:
        critic: the Lyapunov critic, reading ``observation_key`` and ``action_key`` and
            writing ``raw_key`` (the form is ``spec``'s).
        spec: the form, prior and :math:`\\alpha` (share the loss's with
            :meth:`~torchrl_auv.objectives.LyapunovActorCriticLoss.share_spec`: an advisor's
            new spec then reaches the filter).
        raw_key: the critic's output key.
        observation_key, action_key: the critic's inputs.
        history_key: the :class:`~torchrl_auv.envs.StateActionHistory` entry (its
            ``observation``, ``action`` and ``mask``; the last pair is the previous decision).
        cost_key: the previous decision's cost the critic learns (an observation key of the
            env: the last decision's).
        on_leg_key, equilibrium_key: the previous decision's approach and service-start flags.
        mode: one of :data:`FILTER_MODES` (``"veto"`` needs an anchored selection rule).

    ``forward(tensordict, actions)`` with ``actions`` ``[*B, K, A]`` returns ``feasible``
    ``[*B, K]`` (bool), ``values`` ``[*B, K]`` (:math:`L(s_t, a_k)`; the fallback is their
    argmin) and ``applies`` ``[*B]`` (bool).
    """

    def __init__(
        self,
        critic: TensorDictModuleBase,
        *,
        spec: LyapunovSpec | None = None,
        raw_key: NestedKey = "state_action_value",
        observation_key: NestedKey = "observation",
        action_key: NestedKey = "action",
        history_key: NestedKey = "history",
        cost_key: NestedKey = "cost",
        on_leg_key: NestedKey = "approach",
        equilibrium_key: NestedKey = "service_start",
        mode: str = "rank",
    ) -> None:
        if mode not in FILTER_MODES:
            raise ValueError(f"mode must be one of {FILTER_MODES}, got {mode!r}")
        super().__init__()
        self.mode = mode
        self.critic = critic
        self.spec_state = LyapunovSpecState(spec)
        self.raw_key, self.observation_key = unravel_key(raw_key), unravel_key(observation_key)
        self.action_key, self.cost_key = unravel_key(action_key), unravel_key(cost_key)
        history = unravel_key(history_key)
        self.history_key = (history,) if isinstance(history, str) else tuple(history)
        self.on_leg_key = unravel_key(on_leg_key)
        self.equilibrium_key = unravel_key(equilibrium_key)

    @property
    def spec(self) -> LyapunovSpec:
        return self.spec_state.spec

    def extra_repr(self) -> str:
        return f"mode={self.mode!r}"

    def values(self, observation: torch.Tensor, actions: torch.Tensor) -> torch.Tensor:
        """:math:`L(o, a_k)` ``[*B, K]`` for ``observation`` ``[*B, d]`` and ``actions``
        ``[*B, K, A]`` (:func:`critic_values` with this filter's critic, spec and keys)."""
        return critic_values(
            self.critic,
            self.spec,
            observation,
            actions,
            observation_key=self.observation_key,
            action_key=self.action_key,
            raw_key=self.raw_key,
        )

    def forward(
        self, tensordict: TensorDictBase, actions: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        now = self.values(tensordict.get(self.observation_key), actions)
        history = tensordict.get(self.history_key)
        before = self.values(history["observation"][..., -1, :], history["action"][..., -1:, :])
        bound = before[..., 0] - self.spec.alpha * tensordict.get(self.cost_key)[..., 0]
        feasible = now <= bound.unsqueeze(-1)
        on_leg = tensordict.get(self.on_leg_key)[..., 0]
        arrived = tensordict.get(self.equilibrium_key)[..., 0]
        applies = on_leg & ~arrived & history["mask"][..., -1]
        return feasible | ~applies.unsqueeze(-1), now, applies


def allowed_candidates(feasible: torch.Tensor, anchor: torch.Tensor, mode: str) -> torch.Tensor:
    """The candidates ``[*B, K]`` a filtered selection may execute: the ``feasible`` ones
    (``"rank"``), or only the ``anchor`` ``[*B]`` where it is feasible and the feasible ones
    where it is not (``"veto"``; module docstring).

    Examples:
        >>> feasible = torch.tensor([[True, True, False], [False, True, True]])
        >>> allowed_candidates(feasible, torch.tensor([1, 0]), "veto").tolist()
        [[False, True, False], [False, True, True]]
    """
    if mode == "rank":
        return feasible
    anchor = anchor.unsqueeze(-1)
    only_anchor = torch.zeros_like(feasible).scatter(-1, anchor, True)
    return torch.where(feasible.gather(-1, anchor), only_anchor, feasible)


def filtered_choice(
    rule,
    scores: torch.Tensor,
    anchor: torch.Tensor | None,
    feasible: torch.Tensor,
    values: torch.Tensor,
    mode: str,
    *,
    upper: torch.Tensor | None = None,
    members: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """The index ``[*B]`` a filtered selection executes, and its ``scores`` ``[*B, K]`` with
    the excluded candidates at :data:`INFEASIBLE_SCORE`: ``rule``'s choice (a
    :class:`~torchrl_auv.modules.SelectionRule`, with ``upper`` and ``members`` masked
    alike) among :func:`allowed_candidates`, and the least ``values`` (:math:`L`) where no
    candidate is ``feasible`` and the rule may leave its anchor. The one rule of the selector
    (:class:`~torchrl_auv.modules.CandidateSelector`) and of the critics' backup
    (``LyapunovActorCriticLoss(filter_candidates=...)``).

    Examples:
        >>> from torchrl_auv.modules import SelectionRule
        >>> scores = torch.tensor([[3.0, 2.0, 1.0], [3.0, 2.0, 1.0]])
        >>> feasible = torch.tensor([[False, True, True], [False, False, False]])
        >>> values = torch.tensor([[5.0, 4.0, 6.0], [5.0, 4.0, 6.0]])
        >>> index, masked = filtered_choice(SelectionRule(), scores, None, feasible, values, "rank")
        >>> index.tolist(), masked[0].tolist()
        ([1, 1], [-1000000000.0, 2.0, 1.0])
    """
    allowed = allowed_candidates(feasible, anchor, mode)
    masked = [
        None if x is None else x.masked_fill(~allowed, INFEASIBLE_SCORE)
        for x in (scores, upper, members)
    ]
    index = rule.choose(masked[0], masked[1], anchor, members=masked[2])
    fallback = ~feasible.any(-1) & rule.may_leave_anchor
    return torch.where(fallback, values.argmin(-1), index), masked[0]
