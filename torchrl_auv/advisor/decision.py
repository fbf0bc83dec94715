"""What an advisor returns, how any answer is validated, and the ``Advisor`` protocol.

Whatever an advisor (rules or a language model) answers is checked here before the loss sees
it: the form must be a name of :data:`~torchrl_auv.modules.FORMS` (otherwise the answer is
rejected and the current spec kept), the prior ``None`` or a name of
:data:`~torchrl_auv.modules.PRIORS` (otherwise snapped to ``None``), alpha a finite number
(otherwise rejected) snapped into :data:`ALPHA_RANGE` = [0.05, 0.5]. Every snap and rejection is
recorded in ``reasons``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, replace
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

from torchrl_auv.modules.lyapunov_forms import ALPHA_RANGE
from torchrl_auv.objectives import FORMS, PRIORS, LyapunovSpec

if TYPE_CHECKING:
    from torchrl_auv.advisor.feedback import TrainingFeedback

__all__ = ["ALPHA_RANGE", "Advisor", "AdvisorDecision", "validate_answer"]


@dataclass(frozen=True)
class AdvisorDecision:
    """One decision: the Lyapunov form, prior and stability weight to use next.

    Attributes:
        form, prior, alpha: the (validated) choice; equal to the current spec when rejected.
        rationale: the advisor's own words (never executed, never used as a path).
        source: who decided (``"rules"``, ``"openai:<model>:<strategy>"``).
        accepted: ``False`` when the answer was rejected or the advisor failed.
        reasons: every snap, rejection or failure, in order.
        raw: the raw answer text (for the decision log).
    """

    form: str = "softplus"
    prior: str | None = None
    alpha: float = 0.1
    rationale: str = ""
    source: str = ""
    accepted: bool = True
    reasons: tuple[str, ...] = ()
    raw: str = ""

    def to_spec(self, current: LyapunovSpec) -> LyapunovSpec:
        """The spec to apply: this decision's form, prior and alpha, the rest of ``current``."""
        return replace(current, form=self.form, prior=self.prior, alpha=self.alpha)

    def as_dict(self) -> dict[str, Any]:
        return {**asdict(self), "reasons": list(self.reasons)}

    @classmethod
    def keep(
        cls, current: LyapunovSpec, source: str, *reasons: str, raw: str = ""
    ) -> AdvisorDecision:
        """A rejection: the current spec, with the reasons."""
        return cls(
            form=current.form,
            prior=current.prior,
            alpha=current.alpha,
            source=source,
            accepted=False,
            reasons=tuple(reasons),
            raw=raw,
        )


@runtime_checkable
class Advisor(Protocol):
    """Anything with ``propose(task, feedback, current) -> AdvisorDecision``.

    ``feedback`` is ``None`` at the start of training. ``propose`` must not raise for a bad
    answer or a failed service: it returns ``AdvisorDecision.keep(current, ...)`` instead.
    """

    def propose(
        self, task: str, feedback: TrainingFeedback | None, current: LyapunovSpec
    ) -> AdvisorDecision: ...


class FixedAdvisor:
    """An advisor that never changes the spec: the Lyapunov form and weight stay as the loss
    was built (the alpha and form studies, paper Fig. 10-11). Consultations are still logged.

    Examples:
        >>> FixedAdvisor().propose("any task", None, LyapunovSpec(form="log")).form
        'log'
    """

    def propose(
        self, task: str, feedback: TrainingFeedback | None, current: LyapunovSpec
    ) -> AdvisorDecision:
        # accepted: keeping the spec is this advisor's answer, not a failure
        fixed = "the spec is fixed for this run"
        return AdvisorDecision(
            form=current.form,
            prior=current.prior,
            alpha=current.alpha,
            source="fixed",
            reasons=(fixed,),
        )


def validate_answer(
    answer: Any, current: LyapunovSpec, source: str, raw: str = ""
) -> AdvisorDecision:
    """Check an answer ``{"form", "prior", "alpha", "rationale"}`` (module docstring).

    Examples:
        >>> current = LyapunovSpec()
        >>> d = validate_answer({"form": "log", "alpha": 0.9}, current, "test")
        >>> d.form, d.alpha, d.accepted, d.reasons
        ('log', 0.5, True, ('alpha 0.9 snapped into [0.05, 0.5]',))
        >>> validate_answer({"form": "cubic", "alpha": 0.2}, current, "test").accepted
        False
    """
    if not isinstance(answer, Mapping):
        return AdvisorDecision.keep(current, source, "answer is not a JSON object", raw=raw)
    form = answer.get("form")
    if form not in FORMS:
        return AdvisorDecision.keep(
            current,
            source,
            f"unknown form {str(form)[:40]!r} (expected one of {sorted(FORMS)})",
            raw=raw,
        )
    reasons: list[str] = []
    prior = answer.get("prior")
    if prior in ("", "none", "None", "null"):
        prior = None
    if prior is not None and prior not in PRIORS:
        reasons.append(f"unknown prior {str(prior)[:40]!r} snapped to None")
        prior = None
    alpha = answer.get("alpha")
    if isinstance(alpha, str):
        try:
            alpha = float(alpha)
        except ValueError:
            alpha = None
    if isinstance(alpha, bool) or not isinstance(alpha, int | float) or not math.isfinite(alpha):
        return AdvisorDecision.keep(
            current,
            source,
            f"alpha {str(answer.get('alpha'))[:40]!r} is not a finite number",
            raw=raw,
        )
    low, high = ALPHA_RANGE
    if not low <= alpha <= high:
        reasons.append(f"alpha {alpha:g} snapped into [{low:g}, {high:g}]")
        alpha = min(max(float(alpha), low), high)
    rationale = str(answer.get("rationale", ""))[:1000]
    return AdvisorDecision(
        form=form,
        prior=prior,
        alpha=float(alpha),
        rationale=rationale,
        source=source,
        reasons=tuple(reasons),
        raw=raw,
    )
