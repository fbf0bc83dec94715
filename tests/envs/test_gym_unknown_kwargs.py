"""Unknown keyword arguments raise Python's usual TypeError, so TorchRL's GymEnv builds our ids.

``torchrl.envs.libs.gym.GymEnv`` passes ``frameskip`` to ``gymnasium.make`` and drops it only
when the constructor raises ``TypeError: ... got an unexpected keyword argument 'frameskip'``.
"""

from __future__ import annotations

import gymnasium
import pytest
import torch
from torchrl.envs.libs.gym import GymEnv

import torchrl_auv.envs  # noqa: F401 - registers the gymnasium ids
from torchrl_auv.envs import AUVTrackingEnv, DataCollectionEnv
from torchrl_auv.envs.gym import DATA_COLLECTION_ID, TRACKING_ID

IDS = [TRACKING_ID, DATA_COLLECTION_ID]


def _ours():
    return sorted(i for i in gymnasium.registry if i.startswith("torchrl_auv/"))


def test_every_registered_id_is_covered():
    assert _ours() == sorted(IDS)


@pytest.mark.parametrize("cls", [AUVTrackingEnv, DataCollectionEnv])
@pytest.mark.parametrize("name", ["frameskip", "no_such_argument"])
def test_env_classes_raise_unexpected_keyword_type_error(cls, name):
    message = rf"__init__\(\) got an unexpected keyword argument '{name}'"
    with pytest.raises(TypeError, match=message):
        cls(**{name: 1})


def test_data_collection_still_takes_iout_config_fields():
    env = DataCollectionEnv(num_auvs=2, area_m=(300.0, 300.0))
    assert env.config.area_m == (300.0, 300.0)


@pytest.mark.parametrize("env_id", IDS)
@pytest.mark.parametrize("name", ["frameskip", "no_such_argument", "batch_size"])
def test_gymnasium_make_raises_unexpected_keyword_type_error(env_id, name):
    with pytest.raises(TypeError, match=rf"unexpected keyword argument '{name}'"):
        gymnasium.make(env_id, **{name: 1})


def test_data_collection_id_still_refuses_flatten_agents():
    with pytest.raises(ValueError, match="flatten_agents is always True"):
        gymnasium.make(DATA_COLLECTION_ID, flatten_agents=True)


@pytest.mark.parametrize(
    ("env_id", "obs_dim", "act_dim", "kwargs"),
    [
        (TRACKING_ID, 16, 3, {"sea_state": "es"}),
        (DATA_COLLECTION_ID, 76, 6, {"num_auvs": 2}),
    ],
)
def test_torchrl_gym_env_builds_and_rolls_out(env_id, obs_dim, act_dim, kwargs):
    env = GymEnv(f"torchrl_auv.envs:{env_id}", **kwargs)
    assert env.wrapper_frame_skip == 1  # frameskip was offered, refused and dropped
    env.set_seed(0)
    td = env.rollout(3)
    assert td["observation"].shape == (3, obs_dim) and td["action"].shape == (3, act_dim)
    assert torch.isfinite(td["next", "reward"]).all()


def test_torchrl_gym_env_frame_skip_is_handled_by_the_wrapper():
    env = GymEnv(f"torchrl_auv.envs:{TRACKING_ID}", frame_skip=2)
    assert env.wrapper_frame_skip == 2
    assert env.rollout(3)["observation"].shape == (3, 16)


def test_torchrl_gym_env_still_raises_on_a_real_unknown_argument():
    with pytest.raises(TypeError, match="unexpected keyword argument 'no_such_argument'"):
        GymEnv(f"torchrl_auv.envs:{DATA_COLLECTION_ID}", no_such_argument=1)
