"""Held-out evaluation on the data-collection task: reference policies, episode statistics and
the worker pool that evaluates rows side by side.

==========================  ========================================================================
module                      holds
==========================  ========================================================================
``episodes``                :func:`episode_stats`: one rollout summarised by the task's metrics
``policies``                the reference policies by name (expert, lazy, idle, random, exit)
``pool``                    rows evaluated in worker processes; :class:`RowWorker` for curves
``held_out``                :func:`evaluate`: every policy in every sea state on the same scenes
``certificate``             :class:`LyapunovCertificate`: the decrease condition on executed legs
==========================  ========================================================================

It sits above the environments, modules and objectives and below ``training``, which builds
the rows of a run's evaluation from its config (imports: torch, torchrl, tensordict and the
layers below; ``tqdm`` only for ``evaluate(progress=True)``).
"""

from __future__ import annotations

from torchrl_auv.evaluation.certificate import (
    CERTIFICATE_KEYS,
    LyapunovCertificate,
    clopper_pearson_upper,
)
from torchrl_auv.evaluation.episodes import (
    SE_METRICS,
    TRACKING_METRICS,
    episode_stats,
    first_episode,
)
from torchrl_auv.evaluation.held_out import SameRowAs, evaluate
from torchrl_auv.evaluation.policies import (
    POLICIES,
    exit_policy,
    expert_policy,
    idle_policy,
    lazy_policy,
    make_policy,
    random_policy,
    reference_policies,
)
from torchrl_auv.evaluation.pool import RowWorker, evaluate_row, evaluate_rows

__all__ = [
    "CERTIFICATE_KEYS",
    "POLICIES",
    "SE_METRICS",
    "TRACKING_METRICS",
    "LyapunovCertificate",
    "RowWorker",
    "SameRowAs",
    "clopper_pearson_upper",
    "episode_stats",
    "evaluate",
    "evaluate_row",
    "evaluate_rows",
    "exit_policy",
    "expert_policy",
    "first_episode",
    "idle_policy",
    "lazy_policy",
    "make_policy",
    "random_policy",
    "reference_policies",
]
