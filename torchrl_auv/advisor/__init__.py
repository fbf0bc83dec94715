"""Lyapunov advisors: choose the Lyapunov form, prior and stability weight (paper §III-C).

An advisor reads the task text and a :class:`TrainingFeedback` and returns an
:class:`AdvisorDecision`; :class:`AdvisorTrigger` decides when to ask, applies the decision to
the loss through its :class:`~torchrl_auv.modules.LyapunovSpec` and keeps a JSONL decision
log. :class:`RuleBasedAdvisor` is the offline default (rules, not an LLM);
:class:`OpenAICompatibleAdvisor` asks any OpenAI-compatible model. This package knows the loss
only through ``spec`` / ``set_lyapunov_spec`` and never executes text it receives.
"""

from __future__ import annotations

from torchrl_auv.advisor.decision import (
    ALPHA_RANGE,
    Advisor,
    AdvisorDecision,
    FixedAdvisor,
    validate_answer,
)
from torchrl_auv.advisor.feedback import TrainingFeedback, feedback_from_training
from torchrl_auv.advisor.openai_compatible import STRATEGIES, OpenAICompatibleAdvisor
from torchrl_auv.advisor.prompt import DECISION_SCHEMA, build_messages, json_from_text
from torchrl_auv.advisor.rules import FORM_ORDER, RuleBasedAdvisor
from torchrl_auv.advisor.trigger import AdvisorTrigger, decisions_in_force
from torchrl_auv.objectives import LyapunovSpec

__all__ = [
    "ALPHA_RANGE",
    "DECISION_SCHEMA",
    "FORM_ORDER",
    "STRATEGIES",
    "Advisor",
    "AdvisorDecision",
    "AdvisorTrigger",
    "FixedAdvisor",
    "LyapunovSpec",
    "OpenAICompatibleAdvisor",
    "RuleBasedAdvisor",
    "TrainingFeedback",
    "build_messages",
    "decisions_in_force",
    "feedback_from_training",
    "json_from_text",
    "validate_answer",
]
