r"""``RuleBasedAdvisor``: the offline default. A rule-based stand-in for the LLM, not an LLM.

Deterministic and dependency-free. It reads the task text once (at the start, when there is no
feedback yet) and afterwards only the :class:`~torchrl_auv.advisor.TrainingFeedback`. Forms are
ordered from gentle to aggressive: ``log`` < ``softplus`` < ``squared`` (paper Fig. 11).

At the start (``feedback is None``), keywords of the task text, first match wins:

=================================================  ================================
task text mentions                                 decision
=================================================  ================================
"very extreme", "aggressive", "tight", "fast"      ``squared``, alpha 0.2
"smooth", "gentle", "energy", "efficien"           ``log``, alpha 0.1
anything else                                      ``softplus``, alpha 0.1 (eq. 21)
=================================================  ================================

plus the ``velocity`` prior when the text mentions "velocity", "speed" or "rate".

With feedback, the first rule that fires (thresholds are constructor arguments):

=====================================================  =========================================
feedback                                               decision
=====================================================  =========================================
``violation_rate >= violation_high`` (0.6)             one form gentler, alpha x 0.5
``oscillation_index >= oscillation_high`` (0.3)        one form more aggressive, alpha x 1.5;
                                                       ``velocity`` prior if the velocity
                                                       oscillation dominates, else ``position``
``collisions > 0``                                     alpha x 1.5, ``position`` prior
``return_trend <= -worsening`` (-0.1) and
``lyapunov_trend > 0``                                 alpha x 1.5
otherwise                                              keep the current spec
=====================================================  =========================================

Alpha always stays in [0.05, 0.5].

``forms`` (default all of :data:`FORM_ORDER`) narrows the forms the rules may pick, gentle to
aggressive as above: "one form gentler" stops at the gentlest allowed, a keyword's form
outside them becomes the nearest allowed. The data-collection legs need it: a leg's Lyapunov
value is 10-40, which ``log`` (:math:`\log(1 + z^2)`) reaches only at :math:`|z|` of
:math:`e^5` to :math:`e^{20}`, where its gradient :math:`2 / |z|` has vanished.
"""

from __future__ import annotations

from torchrl_auv.advisor.decision import AdvisorDecision, validate_answer
from torchrl_auv.advisor.feedback import TrainingFeedback
from torchrl_auv.objectives import LyapunovSpec

__all__ = ["FORM_ORDER", "RuleBasedAdvisor"]

#: forms from gentle to aggressive
FORM_ORDER = ("log", "softplus", "squared")
#: default thresholds, shared with :class:`~torchrl_auv.advisor.AdvisorTrigger`
OSCILLATION_HIGH, VIOLATION_HIGH, WORSENING = 0.3, 0.6, 0.1

_AGGRESSIVE_WORDS = ("very extreme", "aggressive", "tight", "fast")
_GENTLE_WORDS = ("smooth", "gentle", "energy", "efficien")
_VELOCITY_WORDS = ("velocity", "speed", "rate")


def _nearest(form: str, forms: tuple[str, ...]) -> str:
    """``form`` if allowed, else the allowed form nearest to it in :data:`FORM_ORDER` (the
    gentler one on a tie)."""
    if form in forms:
        return form
    rank = FORM_ORDER.index(form)
    return min(forms, key=lambda f: (abs(FORM_ORDER.index(f) - rank), FORM_ORDER.index(f)))


def _shift(form: str, steps: int, forms: tuple[str, ...]) -> str:
    i = forms.index(_nearest(form, forms)) + steps
    return forms[min(max(i, 0), len(forms) - 1)]


class RuleBasedAdvisor:
    """The rules of the module docstring.

    Args:
        violation_high: violation rate above which the form gets gentler.
        oscillation_high: oscillation index above which the form gets more aggressive.
        worsening: return-trend drop that, with a rising Lyapunov value, raises alpha.
        forms: the forms the rules may pick (module docstring; a non-empty subset of
            :data:`FORM_ORDER`, default all).

    Examples:
        >>> advisor = RuleBasedAdvisor()
        >>> advisor.propose("hold depth in very extreme seas", None, LyapunovSpec()).form
        'squared'
        >>> d = advisor.propose("", TrainingFeedback(violation_rate=0.8),
        ...                     LyapunovSpec(form="squared", alpha=0.2))
        >>> d.form, d.alpha
        ('softplus', 0.1)
        >>> no_log = RuleBasedAdvisor(forms=("softplus", "squared"))
        >>> no_log.propose("", TrainingFeedback(violation_rate=0.8), LyapunovSpec()).form
        'softplus'
    """

    source = "rules"

    def __init__(
        self,
        *,
        violation_high: float = VIOLATION_HIGH,
        oscillation_high: float = OSCILLATION_HIGH,
        worsening: float = WORSENING,
        forms: tuple[str, ...] | list[str] = FORM_ORDER,
    ) -> None:
        unknown = [f for f in forms if f not in FORM_ORDER]
        if not forms or unknown:
            raise ValueError(
                f"forms must be a non-empty subset of {FORM_ORDER}, got {list(forms)!r}"
            )
        self.forms = tuple(f for f in FORM_ORDER if f in forms)
        for name, value in (
            ("violation_high", violation_high),
            ("oscillation_high", oscillation_high),
            ("worsening", worsening),
        ):
            if not 0 < value <= 1:
                raise ValueError(f"{name} must be in (0, 1], got {value}")
        self.violation_high = violation_high
        self.oscillation_high = oscillation_high
        self.worsening = worsening

    def propose(
        self, task: str, feedback: TrainingFeedback | None, current: LyapunovSpec
    ) -> AdvisorDecision:
        form, prior, alpha = current.form, current.prior, current.alpha
        if feedback is None:
            text = task.lower()
            if any(w in text for w in _AGGRESSIVE_WORDS):
                form, alpha, why = "squared", 0.2, "the task asks for tight, aggressive control"
            elif any(w in text for w in _GENTLE_WORDS):
                form, alpha, why = "log", 0.1, "the task asks for smooth, energy-aware control"
            else:
                form, alpha, why = "softplus", 0.1, "no preference in the task: the paper's default"
            form = _nearest(form, self.forms)
            prior = "velocity" if any(w in text for w in _VELOCITY_WORDS) else None
        elif feedback.violation_rate >= self.violation_high:
            form, alpha = _shift(form, -1, self.forms), alpha * 0.5
            why = f"violation rate {feedback.violation_rate:.2f} persistently high: gentler"
        elif feedback.oscillation_index >= self.oscillation_high:
            form, alpha = _shift(form, +1, self.forms), alpha * 1.5
            velocity = feedback.velocity_oscillation > feedback.position_oscillation
            prior = "velocity" if velocity else "position"
            why = (
                f"oscillation {feedback.oscillation_index:.2f} ({prior} dominant): more aggressive"
            )
        elif feedback.collisions > 0:
            alpha, prior = alpha * 1.5, "position"
            why = f"{feedback.collisions:g} collisions: stronger position stabilisation"
        elif feedback.return_trend <= -self.worsening and feedback.lyapunov_trend > 0:
            alpha *= 1.5
            why = "return falling while the Lyapunov value rises: larger stability weight"
        else:
            why = "feedback within thresholds: keep the current spec"
        answer = {"form": form, "prior": prior, "alpha": round(alpha, 4), "rationale": why}
        decision = validate_answer(answer, current, self.source)
        return decision
