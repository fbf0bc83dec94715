"""Neural modules: the diffusion proposer (its noise models and noise schedules), the candidate
selector, its selection rule and its Lyapunov filter, the Q ensemble, the Lyapunov forms and
the one Lyapunov spec that a loss and its selectors share.

Owns the TensorDict modules policies are built from (``objectives`` holds the losses, which
train them). Independent of our envs: a module reads keys and specs, so it works on any TorchRL
env with the right keys.
"""

from __future__ import annotations

from torchrl_auv.modules.candidate_selector import SELECTION_MODES, CandidateSelector
from torchrl_auv.modules.consensus import (
    CANDIDATE_PICKS,
    ProposerAlone,
    medoid_index,
    pick_candidate,
)
from torchrl_auv.modules.diffusion_schedule import SAMPLERS, SCHEDULES, NoiseSchedule
from torchrl_auv.modules.lyapunov_filter import (
    FILTER_MODES,
    LyapunovFilter,
    allowed_candidates,
    critic_values,
    filtered_choice,
)
from torchrl_auv.modules.lyapunov_forms import (
    FORMS,
    PRIORS,
    LyapunovSpec,
    LyapunovSpecState,
    lyapunov_value,
)
from torchrl_auv.modules.noise_models import (
    MLPNoiseModel,
    SinusoidalEmbedding,
    TemporalUNet1d,
    make_noise_model,
)
from torchrl_auv.modules.proposer import DiffusionProposer
from torchrl_auv.modules.q_ensemble import Q_REDUCTIONS, QEnsembleCritic
from torchrl_auv.modules.selection_rule import ANCHORS, DOMINANCE, SelectionRule

__all__ = [
    "ANCHORS",
    "CANDIDATE_PICKS",
    "DOMINANCE",
    "FILTER_MODES",
    "FORMS",
    "PRIORS",
    "Q_REDUCTIONS",
    "SAMPLERS",
    "SCHEDULES",
    "SELECTION_MODES",
    "CandidateSelector",
    "DiffusionProposer",
    "LyapunovFilter",
    "LyapunovSpec",
    "LyapunovSpecState",
    "MLPNoiseModel",
    "NoiseSchedule",
    "ProposerAlone",
    "QEnsembleCritic",
    "SelectionRule",
    "SinusoidalEmbedding",
    "TemporalUNet1d",
    "allowed_candidates",
    "critic_values",
    "filtered_choice",
    "lyapunov_value",
    "make_noise_model",
    "medoid_index",
    "pick_candidate",
]
