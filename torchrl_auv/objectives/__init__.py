"""Losses: the proposer's denoising loss, the Lyapunov actor-critic, SAC on the executed
candidates or on a residual actor.

Owns TorchRL ``LossModule`` classes; they read keys set with ``set_keys`` and work with any env
whose data carries those keys. The modules they train and share (the candidate selector and its
rule, the Q ensemble, the Lyapunov forms and spec) live in :mod:`torchrl_auv.modules` and are
re-exported here under their names.
"""

from __future__ import annotations

from torchrl_auv.modules.candidate_selector import SELECTION_MODES, CandidateSelector
from torchrl_auv.modules.lyapunov_forms import (
    FORMS,
    PRIORS,
    LyapunovSpec,
    LyapunovSpecState,
    lyapunov_value,
)
from torchrl_auv.modules.q_ensemble import Q_REDUCTIONS, QEnsembleCritic
from torchrl_auv.modules.selection_rule import ANCHORS, SelectionRule
from torchrl_auv.objectives.candidate_backup import BACKUPS, CandidateBackupSACLoss
from torchrl_auv.objectives.denoising import DenoisingLoss
from torchrl_auv.objectives.lyapunov import MODES, LyapunovActorCriticLoss
from torchrl_auv.objectives.pretraining import (
    LR_SCHEDULES,
    PretrainResult,
    heldout_denoising_loss,
    pretrain_proposer,
)
from torchrl_auv.objectives.residual import (
    ResidualLACLoss,
    ResidualPenalty,
    ResidualSACLoss,
    residual_offset,
)

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
