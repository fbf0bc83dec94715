"""RuleBasedAdvisor: decisions follow the documented table; validation snaps and rejects."""

from __future__ import annotations

import pytest

from torchrl_auv.advisor import (
    FORM_ORDER,
    AdvisorDecision,
    RuleBasedAdvisor,
    TrainingFeedback,
    validate_answer,
)
from torchrl_auv.objectives import LyapunovSpec

START = [
    ("Hold depth in very extreme seas", ("squared", None, 0.2)),
    ("Aggressive heading tracking", ("squared", None, 0.2)),
    ("Smooth, energy-efficient data collection", ("log", None, 0.1)),
    ("Collect data from sensor nodes", ("softplus", None, 0.1)),
    ("Keep the surge speed steady", ("softplus", "velocity", 0.1)),
    ("Fast turns with a tight yaw rate", ("squared", "velocity", 0.2)),
]


@pytest.mark.parametrize(("task", "expected"), START)
def test_start_decision_follows_the_task_text(task, expected):
    d = RuleBasedAdvisor().propose(task, None, LyapunovSpec(form="log", alpha=0.3))
    assert (d.form, d.prior, d.alpha) == expected and d.accepted and d.source == "rules"


CURRENT = LyapunovSpec(form="softplus", alpha=0.2)
FEEDBACK = [
    # (feedback, expected (form, prior, alpha))
    (TrainingFeedback(violation_rate=0.7), ("log", None, 0.1)),
    (TrainingFeedback(violation_rate=0.7, position_oscillation=0.9), ("log", None, 0.1)),
    (
        TrainingFeedback(position_oscillation=0.4, velocity_oscillation=0.1),
        ("squared", "position", 0.3),
    ),
    (
        TrainingFeedback(position_oscillation=0.1, velocity_oscillation=0.45),
        ("squared", "velocity", 0.3),
    ),
    (TrainingFeedback(collisions=2), ("softplus", "position", 0.3)),
    (TrainingFeedback(return_trend=-0.3, lyapunov_trend=0.2), ("softplus", None, 0.3)),
    (TrainingFeedback(return_trend=-0.3, lyapunov_trend=-0.2), ("softplus", None, 0.2)),
    (TrainingFeedback(), ("softplus", None, 0.2)),
]


@pytest.mark.parametrize(("feedback", "expected"), FEEDBACK)
def test_feedback_decisions_follow_the_table(feedback, expected):
    d = RuleBasedAdvisor().propose("any task", feedback, CURRENT)
    assert (d.form, d.prior, d.alpha) == pytest.approx(expected)


def test_forms_saturate_and_alpha_stays_in_range():
    advisor = RuleBasedAdvisor()
    gentle = advisor.propose(
        "", TrainingFeedback(violation_rate=1.0), LyapunovSpec(form="log", alpha=0.05)
    )
    assert (gentle.form, gentle.alpha) == ("log", 0.05) and "snapped" in gentle.reasons[0]
    strong = advisor.propose(
        "", TrainingFeedback(position_oscillation=1.0), LyapunovSpec(form="squared", alpha=0.5)
    )
    assert (strong.form, strong.alpha) == ("squared", 0.5)


def test_the_rules_pick_only_the_allowed_forms():
    """forms=("softplus", "squared"): gentler stops at softplus (alpha still halves), a
    gentle task's log becomes softplus, a current log form moves from its nearest allowed;
    the form set is checked."""
    no_log = RuleBasedAdvisor(forms=["squared", "softplus"])  # any order: gentle to aggressive
    assert no_log.forms == ("softplus", "squared")
    high = TrainingFeedback(violation_rate=0.7)
    gentler = no_log.propose("", high, LyapunovSpec(form="squared", alpha=0.2))
    assert (gentler.form, gentler.alpha) == ("softplus", 0.1)
    floor = no_log.propose("", high, CURRENT)
    assert (floor.form, floor.alpha) == ("softplus", 0.1)
    start = no_log.propose("Smooth, energy-efficient data collection", None, CURRENT)
    assert (start.form, start.alpha) == ("softplus", 0.1)
    oscillating = TrainingFeedback(position_oscillation=0.9)
    assert no_log.propose("", oscillating, LyapunovSpec(form="log")).form == "squared"
    only = RuleBasedAdvisor(forms=("squared",))
    assert only.propose("Collect data", None, CURRENT).form == "squared"
    for bad in ((), ("softplus", "cubic")):
        with pytest.raises(ValueError, match="forms must be a non-empty subset"):
            RuleBasedAdvisor(forms=bad)
    from torchrl_auv.training import advisor_from_config

    configured = advisor_from_config({"advisor": {"backend": "rules", "forms": ["softplus"]}})
    assert configured.forms == ("softplus",)
    assert advisor_from_config({"advisor": {"backend": "rules"}}).forms == FORM_ORDER


def test_thresholds_are_arguments():
    fb = TrainingFeedback(violation_rate=0.5)
    assert RuleBasedAdvisor().propose("", fb, CURRENT).form == "softplus"
    assert RuleBasedAdvisor(violation_high=0.4).propose("", fb, CURRENT).form == "log"
    with pytest.raises(ValueError, match="violation_high"):
        RuleBasedAdvisor(violation_high=0.0)


VALIDATION = [
    ({"form": "log", "prior": "velocity", "alpha": 0.2}, True, ("log", "velocity", 0.2), ""),
    ({"form": "log", "alpha": "0.3"}, True, ("log", None, 0.3), ""),
    ({"form": "log", "alpha": 0.01}, True, ("log", None, 0.05), "snapped"),
    ({"form": "log", "prior": "angle", "alpha": 0.2}, True, ("log", None, 0.2), "unknown prior"),
    ({"form": "cubic", "alpha": 0.2}, False, ("squared", None, 0.3), "unknown form"),
    ({"form": "log", "alpha": "lots"}, False, ("squared", None, 0.3), "not a finite number"),
    ({"form": "log", "alpha": float("nan")}, False, ("squared", None, 0.3), "not a finite"),
    ({"form": "log", "alpha": True}, False, ("squared", None, 0.3), "not a finite number"),
    (["log", 0.2], False, ("squared", None, 0.3), "not a JSON object"),
]


@pytest.mark.parametrize(("answer", "accepted", "expected", "reason"), VALIDATION)
def test_validation_snaps_or_rejects_with_a_reason(answer, accepted, expected, reason):
    current = LyapunovSpec(form="squared", alpha=0.3)
    d = validate_answer(answer, current, "test")
    assert d.accepted is accepted and (d.form, d.prior, d.alpha) == expected
    assert reason in " ".join(d.reasons)
    assert isinstance(d.to_spec(current), LyapunovSpec)


def test_decision_and_feedback_construct_by_keyword_with_defaults():
    assert AdvisorDecision().form == "softplus" and TrainingFeedback().steps == 0
    assert LyapunovSpec().alpha == 0.1
