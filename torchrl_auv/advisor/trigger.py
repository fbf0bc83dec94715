"""``AdvisorTrigger``: when to consult the advisor, how to apply its decision, and the log.

Any training loop calls :meth:`AdvisorTrigger.step` with the current frame count, the latest
:class:`~torchrl_auv.advisor.TrainingFeedback` and the loss (anything with
``spec``/``set_lyapunov_spec``, e.g. :class:`~torchrl_auv.objectives.LyapunovActorCriticLoss`).

**Policy.** Consult at the first call ("start"). Afterwards consult when the feedback crosses a
threshold (``oscillation_index >= oscillation``, ``violation_rate >= violation``,
``return_trend <= -worsening``, ``collisions > 0``), but not within ``cooldown`` frames of the
previous consultation. An accepted decision that differs from the loss's spec is applied with
``set_lyapunov_spec`` (the loss keeps its parameters, dual variables and optimiser state).

**Decision log.** Every consultation appends one JSON line to ``log_path`` (never truncated):
frame, trigger, task text, feedback, the spec before, the raw answer, the parsed decision,
whether it was applied, the reasons and the latency. A run resumed from a checkpoint appends an
``"event": "restored"`` line (the last consultation the checkpoint holds and the count): the
decisions above it with a later frame were made by a session that stopped before its next
checkpoint, and were rolled back with it. With a TorchRL ``WandbLogger`` the log is
also sent as a ``wandb.Table`` (``advisor/decisions``); any TorchRL logger gets
``advisor/alpha`` and ``advisor/form_index`` scalars (the spec in force after the consultation;
the index is the form's place in :data:`~torchrl_auv.advisor.FORM_ORDER`, gentle to
aggressive: log 0, softplus 1, squared 2).
"""

from __future__ import annotations

import json
import logging
import re
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

from torchrl.record.loggers.wandb import WandbLogger

from torchrl_auv.advisor.decision import Advisor, AdvisorDecision
from torchrl_auv.advisor.feedback import TrainingFeedback
from torchrl_auv.advisor.rules import FORM_ORDER, OSCILLATION_HIGH, VIOLATION_HIGH, WORSENING

log = logging.getLogger(__name__)

__all__ = ["AdvisorTrigger", "decisions_in_force"]


class AdvisorTrigger:
    """Consult an advisor at start and on threshold crossings, with a cooldown (module docs).

    Args:
        advisor: a :class:`~torchrl_auv.advisor.decision.Advisor`.
        task: the task text given to the advisor.
        log_path: the JSONL decision log (appended; parent folders created).
        cooldown: frames between consultations after the start.
        oscillation, violation, worsening: the thresholds of the policy.
        logger: an optional TorchRL logger.

    Examples:
        >>> import tempfile
        >>> from torchrl_auv.advisor import RuleBasedAdvisor
        >>> from torchrl_auv.objectives import LyapunovSpec
        >>> class Loss:  # anything with spec / set_lyapunov_spec
        ...     spec = LyapunovSpec()
        ...     def set_lyapunov_spec(self, spec): self.spec = spec
        >>> loss, folder = Loss(), tempfile.mkdtemp()
        >>> trigger = AdvisorTrigger(RuleBasedAdvisor(), "tight depth hold",
        ...                          log_path=f"{folder}/advisor.jsonl")
        >>> trigger.step(0, None, loss).form, loss.spec.form
        ('squared', 'squared')
        >>> trigger.step(100, TrainingFeedback(), loss) is None  # no threshold crossed
        True
    """

    def __init__(
        self,
        advisor: Advisor,
        task: str,
        *,
        log_path: str | Path,
        cooldown: int = 10_000,
        oscillation: float = OSCILLATION_HIGH,
        violation: float = VIOLATION_HIGH,
        worsening: float = WORSENING,
        logger=None,
    ) -> None:
        if not isinstance(advisor, Advisor):
            raise ValueError(f"advisor must have propose(task, feedback, current), got {advisor!r}")
        if cooldown < 0:
            raise ValueError(f"cooldown must be >= 0 frames, got {cooldown}")
        self.advisor, self.task = advisor, str(task)
        self.log_path = Path(log_path)
        self.log_path.parent.mkdir(parents=True, exist_ok=True)
        self.cooldown = int(cooldown)
        self.oscillation, self.violation, self.worsening = oscillation, violation, worsening
        self.logger = logger
        #: this session's consultations (the full record of every session is ``log_path``)
        self.records: list[dict[str, Any]] = []
        #: consultations over the whole run, resumed sessions included (kept by state_dict)
        self.consultations = 0
        #: failed or rejected consultations by kind (the first reason, numbers blanked), over the
        #: whole run
        self.failures: dict[str, int] = {}
        self._last_frame: int | None = None

    def state_dict(self) -> dict[str, Any]:
        """What a resumed run needs: the frame of the last consultation (``-1``: none yet) and
        the run's consultation and failure counts. The spec in force lives in the loss;
        checkpoint it with the loss's owner."""
        return {
            "last_frame": -1 if self._last_frame is None else int(self._last_frame),
            "consultations": self.consultations,
            "failures": dict(self.failures),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        last = int(state["last_frame"])
        self._last_frame = None if last < 0 else last
        # checkpoints written before the counts were kept hold only the frame
        self.consultations = int(state.get("consultations", 0))
        self.failures = {str(k): int(v) for k, v in state.get("failures", {}).items()}
        with self.log_path.open("a", encoding="utf-8") as f:  # where a resumed session starts
            f.write(
                json.dumps(
                    {
                        "time": time.time(),
                        "event": "restored",
                        "last_consultation_frame": last,
                        "consultations": self.consultations,
                    }
                )
                + "\n"
            )

    def reason(self, frame: int, feedback: TrainingFeedback | None) -> str | None:
        """Why to consult now (``"start"``, a threshold), or ``None``."""
        if self._last_frame is None:
            return "start"
        if feedback is None or frame - self._last_frame < self.cooldown:
            return None
        if feedback.oscillation_index >= self.oscillation:
            return f"oscillation_index {feedback.oscillation_index:.3f} >= {self.oscillation}"
        if feedback.violation_rate >= self.violation:
            return f"violation_rate {feedback.violation_rate:.3f} >= {self.violation}"
        if feedback.return_trend <= -self.worsening:
            return f"return_trend {feedback.return_trend:.3f} <= -{self.worsening}"
        if feedback.collisions > 0:
            return f"collisions {feedback.collisions:g} > 0"
        return None

    def step(self, frame: int, feedback: TrainingFeedback | None, loss) -> AdvisorDecision | None:
        """Consult if the policy says so; apply and log the decision. ``None`` if not consulted."""
        why = self.reason(frame, feedback)
        if why is None:
            return None
        self._last_frame = frame
        self.consultations += 1
        before = loss.spec
        start = time.perf_counter()
        try:
            decision = self.advisor.propose(self.task, feedback, before)
        except Exception as err:  # an advisor must not crash training: keep the spec
            why = f"advisor raised {type(err).__name__}: {err}"
            decision = AdvisorDecision.keep(before, type(self.advisor).__name__, why)
        latency = time.perf_counter() - start
        if not decision.accepted:
            self._report_failure(frame, decision)
        after = decision.to_spec(before) if decision.accepted else before
        applied = after != before
        if applied:
            loss.set_lyapunov_spec(after)
        record = {
            "time": time.time(),
            "task": self.task[:500],
            "frame": frame,
            "trigger": why,
            "feedback": None if feedback is None else feedback.as_dict(),
            "spec_before": {k: v for k, v in asdict(before).items() if k != "prior_indices"},
            "raw_answer": decision.raw,
            "decision": {k: v for k, v in decision.as_dict().items() if k != "raw"},
            "applied": applied,
            "reasons": list(decision.reasons),
            "latency_s": latency,
        }
        self.records.append(record)
        with self.log_path.open("a", encoding="utf-8") as f:
            f.write(json.dumps(record) + "\n")
        self._log(frame, record, loss.spec)
        return decision

    def _report_failure(self, frame: int, decision: AdvisorDecision) -> None:
        """Count a consultation that kept the spec; say the first of each kind on the console
        (with the advisor, e.g. its endpoint), since training goes on without its advice."""
        reasons = "; ".join(decision.reasons) or "no reason given"
        kind = re.sub(r"\d+(\.\d+)?", "#", decision.reasons[0] if decision.reasons else reasons)
        self.failures[kind] = self.failures.get(kind, 0) + 1
        if self.failures[kind] == 1:
            log.warning(
                "advisor %r kept the Lyapunov spec at frame %d: %s (said once per kind; "
                "training goes on with the spec in force)",
                self.advisor,
                frame,
                reasons,
            )

    def failure_summary(self) -> str:
        """``"none"``, or each kind of failed consultation with its count."""
        return "; ".join(f"{kind} (x{n})" for kind, n in self.failures.items()) or "none"

    def _log(self, frame: int, record: dict[str, Any], spec) -> None:
        if self.logger is None:
            return
        self.logger.log_scalar("advisor/alpha", spec.alpha, step=frame)
        self.logger.log_scalar("advisor/form_index", FORM_ORDER.index(spec.form), step=frame)
        if isinstance(self.logger, WandbLogger):
            import wandb

            columns = [
                "frame",
                "trigger",
                "form",
                "prior",
                "alpha",
                "applied",
                "source",
                "reasons",
                "latency_s",
                "rationale",
            ]
            rows = [
                [
                    r["frame"],
                    r["trigger"],
                    r["decision"]["form"],
                    str(r["decision"]["prior"]),
                    r["decision"]["alpha"],
                    r["applied"],
                    r["decision"]["source"],
                    "; ".join(r["reasons"]),
                    r["latency_s"],
                    r["decision"]["rationale"],
                ]
                for r in self.records
            ]
            self.logger.experiment.log(
                {"advisor/decisions": wandb.Table(columns=columns, data=rows)}
            )


def decisions_in_force(log_path: str | Path) -> list[dict[str, Any]]:
    """The consultations of a decision log that stand, in order: at each ``"restored"`` line
    those logged earlier with a frame after the checkpoint's last consultation are dropped
    (rolled back with the session that made them). ``[]`` for a missing log.

    Examples:
        >>> import json, pathlib, tempfile
        >>> log = pathlib.Path(tempfile.mkdtemp(), "advisor.jsonl")
        >>> lines = [{"frame": 0}, {"frame": 500},
        ...          {"event": "restored", "last_consultation_frame": 0}, {"frame": 600}]
        >>> _ = log.write_text("".join(json.dumps(line) + "\\n" for line in lines))
        >>> [r["frame"] for r in decisions_in_force(log)]
        [0, 600]
    """
    path = Path(log_path)
    if not path.exists():
        return []
    kept: list[dict[str, Any]] = []
    for line in path.read_text(encoding="utf-8").splitlines():
        if not line.strip():
            continue
        record = json.loads(line)
        if record.get("event") == "restored":
            last = int(record["last_consultation_frame"])
            kept = [r for r in kept if int(r["frame"]) <= last]
        elif "frame" in record:
            kept.append(record)
    return kept
