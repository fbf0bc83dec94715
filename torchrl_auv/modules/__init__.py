"""Neural modules: the diffusion proposer, its noise models and noise schedules.

Owns the TensorDict modules policies are built from. Independent of our envs: a module reads
keys and specs, so it works on any TorchRL env with the right keys.
"""

from __future__ import annotations

from torchrl_auv.modules.consensus import (
    CANDIDATE_PICKS,
    ProposerAlone,
    medoid_index,
    pick_candidate,
)
from torchrl_auv.modules.diffusion_schedule import SAMPLERS, SCHEDULES, NoiseSchedule
from torchrl_auv.modules.noise_models import (
    MLPNoiseModel,
    SinusoidalEmbedding,
    TemporalUNet1d,
    make_noise_model,
)
from torchrl_auv.modules.proposer import DiffusionProposer

__all__ = [
    "CANDIDATE_PICKS",
    "SAMPLERS",
    "SCHEDULES",
    "DiffusionProposer",
    "MLPNoiseModel",
    "NoiseSchedule",
    "ProposerAlone",
    "SinusoidalEmbedding",
    "TemporalUNet1d",
    "make_noise_model",
    "medoid_index",
    "pick_candidate",
]
