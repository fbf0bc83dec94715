"""Losses: the proposer's denoising loss, the Lyapunov actor-critic, candidate filtering, SAC
on the executed candidates or on a residual actor.

Owns TorchRL ``LossModule`` classes; they read keys set with ``set_keys`` and work with any env
whose data carries those keys.
"""

from __future__ import annotations

from torchrl_auv.objectives.candidate_backup import BACKUPS, CandidateBackupSACLoss
from torchrl_auv.objectives.denoising import DenoisingLoss
from torchrl_auv.objectives.lyapunov import MODES, LyapunovActorCriticLoss
from torchrl_auv.objectives.lyapunov_forms import (
    FORMS,
    PRIORS,
    LyapunovSpec,
    LyapunovSpecState,
    lyapunov_value,
)
from torchrl_auv.objectives.pretraining import (
    LR_SCHEDULES,
    PretrainResult,
    heldout_denoising_loss,
    pretrain_proposer,
)
from torchrl_auv.objectives.q_filter import Q_REDUCTIONS, QEnsembleCritic
from torchrl_auv.objectives.residual import (
    ResidualLACLoss,
    ResidualPenalty,
    ResidualSACLoss,
    residual_offset,
)
from torchrl_auv.objectives.selection import SELECTION_MODES, CandidateSelector
from torchrl_auv.objectives.selection_rule import ANCHORS, SelectionRule

__all__ = [
    "ANCHORS",
    "BACKUPS",
    "FORMS",
    "LR_SCHEDULES",
    "MODES",
    "PRIORS",
    "Q_REDUCTIONS",
    "SELECTION_MODES",
    "CandidateBackupSACLoss",
    "CandidateSelector",
    "DenoisingLoss",
    "LyapunovActorCriticLoss",
    "LyapunovSpec",
    "LyapunovSpecState",
    "PretrainResult",
    "QEnsembleCritic",
    "ResidualLACLoss",
    "ResidualPenalty",
    "ResidualSACLoss",
    "SelectionRule",
    "heldout_denoising_loss",
    "lyapunov_value",
    "pretrain_proposer",
    "residual_offset",
]
