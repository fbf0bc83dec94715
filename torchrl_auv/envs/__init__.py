"""TorchRL environments and transforms: where TorchRL starts.

Owns the ``EnvBase`` classes that wire physics, control, estimation and the sensor network
together (thin by design: task logic lives in the layers below), their transforms (the
state-action history the diffusion proposer reads), the scripted expert and the reference
policies beside it (idle, lazy), gymnasium ids, and offline datasets of them in Minari's format.
"""

from __future__ import annotations

from torchrl_auv.envs.data_collection import SIM_KEY, DataCollectionEnv
from torchrl_auv.envs.experts import ScriptedExpert
from torchrl_auv.envs.gym import DataCollectionGymEnv, TrackingGymEnv, register_gymnasium_ids
from torchrl_auv.envs.history import StateActionHistory, history_key_for
from torchrl_auv.envs.minari_datasets import MinariReplay, create_minari_dataset
from torchrl_auv.envs.reference_policies import IdlePolicy, LazyExpert
from torchrl_auv.envs.tracking import AUVTrackingEnv

__all__ = [
    "SIM_KEY",
    "AUVTrackingEnv",
    "DataCollectionEnv",
    "DataCollectionGymEnv",
    "IdlePolicy",
    "LazyExpert",
    "MinariReplay",
    "ScriptedExpert",
    "StateActionHistory",
    "TrackingGymEnv",
    "create_minari_dataset",
    "history_key_for",
    "register_gymnasium_ids",
]
