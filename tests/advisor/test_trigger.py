"""AdvisorTrigger's policy, threshold by threshold, and its scalars in TorchRL's CSV logger.

The documented policy (trigger.py): consult at the first call; afterwards when
``violation_rate >= violation``, ``return_trend <= -worsening`` or ``collisions > 0``, but not
within ``cooldown`` frames of the previous consultation. Non-default thresholds are used so
that a trigger comparing against the defaults (0.6, 0.1) instead of its arguments is caught.
"""

from __future__ import annotations

import csv

import pytest
from torchrl.record.loggers.csv import CSVLogger

from torchrl_auv.advisor import AdvisorDecision, AdvisorTrigger, RuleBasedAdvisor, TrainingFeedback
from torchrl_auv.objectives import LyapunovSpec

VIOLATION, WORSENING = 0.4, 0.2  # not the defaults


class _Loss:
    def __init__(self, spec=None):
        self.spec = spec or LyapunovSpec()

    def set_lyapunov_spec(self, spec):
        self.spec = spec


class _Counting:
    """An advisor that keeps the spec and counts its consultations."""

    def __init__(self):
        self.calls = 0

    def propose(self, task, feedback, current) -> AdvisorDecision:
        self.calls += 1
        return AdvisorDecision.keep(current, "counting", "kept")


def _trigger(tmp_path, cooldown=0):
    advisor = _Counting()
    trigger = AdvisorTrigger(
        advisor,
        "hold depth",
        log_path=tmp_path / "advisor.jsonl",
        cooldown=cooldown,
        violation=VIOLATION,
        worsening=WORSENING,
    )
    assert trigger.step(0, None, _Loss()) is not None and advisor.calls == 1  # the start
    return trigger, advisor


# (feedback field, [(value, fires?)]): fires exactly on the documented side of the threshold
CROSSINGS = {
    "violation_rate": [
        (0.0, False),
        (0.39, False),
        (VIOLATION, True),
        (0.5, True),
        (1.0, True),
    ],
    "return_trend": [  # fires when return_trend <= -WORSENING = -0.2
        (0.5, False),
        (0.0, False),
        (-0.15, False),
        (-0.19, False),
        (-WORSENING, True),
        (-0.5, True),
    ],
    "collisions": [(0.0, False), (1.0, True), (3.0, True)],
}


@pytest.mark.parametrize("field", list(CROSSINGS))
def test_each_threshold_fires_exactly_when_crossed(tmp_path, field):
    trigger, advisor = _trigger(tmp_path, cooldown=0)
    loss = _Loss()
    for frame, (value, fires) in enumerate(CROSSINGS[field], start=1):
        calls = advisor.calls
        decision = trigger.step(frame, TrainingFeedback(**{field: value}), loss)
        assert (decision is not None) is fires, (field, value)
        assert advisor.calls == calls + fires  # consulted exactly when it fires
        if fires:
            assert trigger.records[-1]["trigger"].startswith(field)
            assert trigger.records[-1]["frame"] == frame
    assert len(trigger.records) == 1 + sum(fires for _, fires in CROSSINGS[field])


FIRING = {"violation_rate": 0.5, "return_trend": -0.5, "collisions": 1.0}


@pytest.mark.parametrize("field", list(FIRING))
def test_each_threshold_respects_the_cooldown(tmp_path, field):
    trigger, advisor = _trigger(tmp_path, cooldown=100)
    crossing, loss = TrainingFeedback(**{field: FIRING[field]}), _Loss()
    # frame -> consulted? (start at 0; then never within 100 frames of the previous one)
    expected = {1: False, 99: False, 100: True, 150: False, 199: False, 200: True, 260: False}
    for frame, fires in expected.items():
        assert (trigger.step(frame, crossing, loss) is not None) is fires, frame
    assert advisor.calls == 3
    assert [r["frame"] for r in trigger.records] == [0, 100, 200]
    assert all(r["trigger"].startswith(field) for r in trigger.records[1:])


def _scalars(folder, name):
    """(step, value) rows of a CSVLogger scalar file."""
    with open(folder / "scalars" / f"{name}.csv") as f:
        return [(int(step), float(value)) for step, value in csv.reader(f)]


def test_alpha_and_form_index_reach_the_csv_logger(tmp_path):
    """RuleBasedAdvisor's table (rules.py): "tight" -> squared, alpha 0.2; then a violation
    rate >= 0.6 twice -> one form gentler and alpha x 0.5 each time. form_index is the form's
    place in the documented gentle-to-aggressive order log < softplus < squared."""
    logger = CSVLogger(exp_name="advisor-test", log_dir=str(tmp_path / "logs"))
    trigger = AdvisorTrigger(
        RuleBasedAdvisor(),
        "tight depth hold",
        log_path=tmp_path / "advisor.jsonl",
        cooldown=500,
        logger=logger,
    )
    loss = _Loss(LyapunovSpec(form="log", alpha=0.3))
    violating = TrainingFeedback(violation_rate=0.7)
    trigger.step(0, None, loss)  # start: squared, 0.2
    trigger.step(100, violating, loss)  # within the cooldown: nothing logged
    trigger.step(1000, violating, loss)  # softplus, 0.1
    trigger.step(2000, violating, loss)  # log, 0.05
    folder = tmp_path / "logs" / "advisor-test"
    alpha, form_index = _scalars(folder, "advisor/alpha"), _scalars(folder, "advisor/form_index")
    assert [step for step, _ in alpha] == [0, 1000, 2000]
    assert [value for _, value in alpha] == pytest.approx([0.2, 0.1, 0.05])
    assert form_index == [(0, 2.0), (1000, 1.0), (2000, 0.0)]


def test_the_csv_logger_gets_the_spec_in_force_after_a_rejected_decision(tmp_path):
    """A rejected answer keeps the spec: the logged alpha and form are the kept ones."""

    class Rejecting:
        def propose(self, task, feedback, current) -> AdvisorDecision:
            return AdvisorDecision(form="log", alpha=0.5, accepted=False, reasons=("no",))

    logger = CSVLogger(exp_name="rejected", log_dir=str(tmp_path / "logs"))
    trigger = AdvisorTrigger(Rejecting(), "x", log_path=tmp_path / "a.jsonl", logger=logger)
    trigger.step(7, None, _Loss(LyapunovSpec(form="softplus", alpha=0.15)))
    folder = tmp_path / "logs" / "rejected"
    assert _scalars(folder, "advisor/alpha") == [(7, 0.15)]
    assert _scalars(folder, "advisor/form_index") == [(7, 1.0)]
