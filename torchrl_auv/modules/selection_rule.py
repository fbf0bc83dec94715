r"""``SelectionRule``: which of K scored candidates is executed, shared by the acting selector
and the critics' backup so that both mean the same policy.

Two rules (``anchor``):

- ``None``: the best candidate, :math:`\arg\max_k \underline s_k` (the pessimistic score: the
  minimum over a critic ensemble, or the one critic's score).
- ``"medoid"``: a safe improvement on the prior. The prior's own choice, the medoid of its
  candidates (:func:`~torchrl_auv.modules.medoid_index`), is executed unless the best
  candidate's pessimistic score beats the medoid's optimistic one by more than ``margin``:

  .. math::

      k^* = \arg\max_k \underline s_k,\qquad
      \text{execute } k^* \text{ if } \underline s_{k^*} - m > \overline s_{\text{medoid}},
      \text{ else the medoid,}

  with :math:`\underline s, \overline s` the minimum and maximum over the critic ensemble
  (``dominance="interval"``: the critic deviates only where its advantage exceeds its own
  disagreement). With one critic :math:`\underline s = \overline s` and only ``margin``
  protects the medoid.

  ``dominance="paired"`` compares the members' advantages instead of their values: with
  :math:`s_{jk}` member :math:`j`'s score of candidate :math:`k` and
  :math:`A_{jk} = s_{jk} - s_{j,\text{medoid}}`,

  .. math::

      k^* = \arg\max_k \min_j A_{jk},\qquad
      \text{execute } k^* \text{ if } \min_j A_{jk^*} > m, \text{ else the medoid:}

  every member must prefer :math:`k^*` to the medoid by more than ``margin``. An error a
  member makes in the state's value is shared by all its candidates and cancels in
  :math:`A_{jk}`, so the test is weaker than interval dominance
  (:math:`\underline s_k - \overline s_{\text{medoid}} \le \min_j A_{jk}`), yet it still
  needs the whole ensemble's agreement. It needs the members' scores (``members``).

The buffer ``deviate`` (``True`` by default) switches deviation off altogether: while it is
``False`` the rule executes the anchor (a warm-up in which the critics learn the prior's
values before they choose). As a buffer it travels with the weights a collector copies to its
workers.

Examples:
    >>> rule = SelectionRule(anchor="medoid")
    >>> lower = torch.tensor([[0.0, 2.0, 1.0]])
    >>> upper = torch.tensor([[0.5, 3.0, 1.2]])
    >>> rule.choose(lower, upper, anchor_index=torch.tensor([2])).tolist()  # 2.0 > 1.2
    [1]
    >>> rule.choose(lower, upper, anchor_index=torch.tensor([0])).tolist()  # 2.0 > 0.5
    [1]
    >>> SelectionRule(anchor="medoid", margin=1.0).choose(lower, upper, torch.tensor([2])).tolist()
    [2]
    >>> SelectionRule().choose(lower, upper).tolist()
    [1]
    >>> members = torch.tensor([[[0.0, 2.0, 1.0]], [[0.5, 3.0, 1.2]]])  # [n, *B, K]
    >>> paired = SelectionRule(anchor="medoid", dominance="paired")
    >>> paired.choose(lower, upper, torch.tensor([2]), members=members).tolist()  # 1.0, 1.8 > 0
    [1]
"""

from __future__ import annotations

import torch

__all__ = ["ANCHORS", "DOMINANCE", "SelectionRule"]

#: ``anchor`` values: ``None`` (argmax) or ``"medoid"`` (the prior's consensus candidate)
ANCHORS = (None, "medoid")
#: ``dominance`` values: how an anchored rule decides that a candidate beats the anchor
DOMINANCE = ("interval", "paired")


class SelectionRule(torch.nn.Module):
    """The executed candidate's index from pessimistic and optimistic scores (module docstring).

    Args:
        anchor: ``None`` (the best pessimistic score) or ``"medoid"``.
        margin: how much (in the critic's score units, >= 0) the best candidate must beat the
            anchor by before the rule deviates (in the sense of ``dominance``).
        dominance: ``"interval"`` (its pessimistic score over the anchor's optimistic one) or
            ``"paired"`` (every member's advantage over the anchor; module docstring).
    """

    def __init__(
        self, anchor: str | None = None, margin: float = 0.0, dominance: str = "interval"
    ) -> None:
        super().__init__()
        if anchor not in ANCHORS:
            raise ValueError(f"anchor must be one of {ANCHORS}, got {anchor!r}")
        if not margin >= 0:
            raise ValueError(f"margin must be >= 0, got {margin}")
        if dominance not in DOMINANCE:
            raise ValueError(f"dominance must be one of {DOMINANCE}, got {dominance!r}")
        self.anchor, self.margin, self.dominance = anchor, float(margin), dominance
        self.register_buffer("deviate", torch.tensor(True))

    @property
    def anchored(self) -> bool:
        return self.anchor is not None

    @property
    def may_leave_anchor(self) -> torch.Tensor:
        """Whether the rule may execute anything but its anchor now (a bool tensor): its
        ``deviate`` switch for an anchored rule (off during a warm-up), always for the plain
        argmax. A filter's fallback (:class:`~torchrl_auv.modules.LyapunovFilter`) follows it."""
        return self.deviate if self.anchored else torch.ones_like(self.deviate)

    def choose(
        self,
        lower: torch.Tensor,
        upper: torch.Tensor | None = None,
        anchor_index: torch.Tensor | None = None,
        members: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """The executed index ``[*B]`` (int64) of scores ``[*B, K]`` (higher is better).

        ``upper`` defaults to ``lower`` (one critic); ``anchor_index`` ``[*B]`` is required
        by an anchored rule, and ignored otherwise; ``members`` ``[n, *B, K]`` (each member's
        scores) by ``dominance="paired"``, which ignores ``lower`` and ``upper`` where it
        deviates.
        """
        if not self.anchored:
            return lower.argmax(-1)
        if anchor_index is None:
            raise ValueError(f"an anchored rule (anchor={self.anchor!r}) needs anchor_index")
        anchor_index = anchor_index.to(lower.device)
        if self.dominance == "paired":
            if members is None:
                raise ValueError("a rule with dominance='paired' needs the members' scores")
            at_anchor = anchor_index.unsqueeze(-1).expand(*members.shape[:-1], 1)
            advantage = (members - members.gather(-1, at_anchor)).min(0).values  # [*B, K]
            gain, best = advantage.max(-1)
        else:
            upper = lower if upper is None else upper
            best_lower, best = lower.max(-1)
            gain = best_lower - upper.gather(-1, anchor_index.unsqueeze(-1)).squeeze(-1)
        deviates = self.deviate & (gain > self.margin)
        return torch.where(deviates, best, anchor_index)

    def extra_repr(self) -> str:
        return f"anchor={self.anchor!r}, margin={self.margin:g}, dominance={self.dominance!r}"
