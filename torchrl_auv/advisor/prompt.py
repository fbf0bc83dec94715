"""The advisor's prompt, the answer's JSON schema, and JSON recovery from free text."""

from __future__ import annotations

import json
from typing import Any

from torchrl_auv.advisor.decision import ALPHA_RANGE
from torchrl_auv.advisor.feedback import TrainingFeedback
from torchrl_auv.objectives import FORMS, PRIORS, LyapunovSpec

__all__ = ["DECISION_SCHEMA", "build_messages", "json_from_text"]

#: the structured answer every strategy asks for
DECISION_SCHEMA: dict[str, Any] = {
    "type": "object",
    "properties": {
        "form": {"type": "string", "enum": sorted(FORMS)},
        "prior": {"type": ["string", "null"], "enum": [*sorted(PRIORS), None]},
        "alpha": {"type": "number", "minimum": ALPHA_RANGE[0], "maximum": ALPHA_RANGE[1]},
        "rationale": {"type": "string"},
    },
    "required": ["form", "prior", "alpha", "rationale"],
    "additionalProperties": False,
}

_SYSTEM = (
    "You tune the Lyapunov function of a Lyapunov actor-critic that controls an autonomous "
    "underwater vehicle. You choose the Lyapunov function form, an optional state prior and the "
    "stability weight alpha. Answer with one JSON object only."
)

_FEEDBACK_MEANING = {
    "return_trend": "relative change of the step reward, later vs earlier (>0 improving)",
    "position_oscillation": "zero-crossing rate per step of position errors (0 calm, 1 max)",
    "velocity_oscillation": "zero-crossing rate per step of velocity/rate entries",
    "violation_rate": "fraction of transitions violating the Lyapunov decrease condition",
    "lambda_trend": "change of the Lagrange multiplier over the window",
    "lyapunov_trend": "relative change of the mean Lyapunov value (>0 rising)",
    "collisions": "collision events in the window",
    "steps": "transitions summarised",
    "oscillation_index": "larger of the two oscillation rates",
}


def build_messages(
    task: str, feedback: TrainingFeedback | None, current: LyapunovSpec
) -> list[dict[str, str]]:
    """Chat messages stating the task, the form library, the feedback and the current spec."""
    forms = "\n".join(f"- {name}: {text}" for name, text in FORMS.items())
    priors = "\n".join(f"- {name}: {text}" for name, text in PRIORS.items())
    if feedback is None:
        seen = "No training feedback yet: this is the start of training."
    else:
        seen = "Training feedback over the last window:\n" + "\n".join(
            f"- {k} = {v:.4g} ({_FEEDBACK_MEANING[k]})" for k, v in feedback.as_dict().items()
        )
    user = (
        f"Task:\n{task.strip() or '(no description)'}\n\n"
        f"Lyapunov function forms:\n{forms}\n\nOptional priors (or null):\n{priors}\n\n"
        f"Stability weight alpha: a number in [{ALPHA_RANGE[0]}, {ALPHA_RANGE[1]}]; larger "
        "demands a faster decrease of the Lyapunov value.\n\n"
        f"Current choice: form={current.form}, prior={current.prior}, alpha={current.alpha:g}\n\n"
        f"{seen}\n\n"
        'Reply with JSON: {"form": ..., "prior": ... or null, "alpha": ..., "rationale": ...}'
    )
    return [{"role": "system", "content": _SYSTEM}, {"role": "user", "content": user}]


def json_from_text(text: str) -> Any:
    """The first JSON object in ``text`` (plain, fenced or surrounded by prose), else raise.

    Examples:
        >>> json_from_text('Sure! ```json\\n{"form": "log", "alpha": 0.2}\\n``` done')
        {'form': 'log', 'alpha': 0.2}
    """
    decoder = json.JSONDecoder()
    start = text.find("{")
    while start != -1:
        try:
            value, _ = decoder.raw_decode(text, start)
            return value
        except json.JSONDecodeError:
            start = text.find("{", start + 1)
    raise ValueError("no JSON object in the answer")
