"""The data-collection top view (``render_mode="rgb_array"``) and gymnasium's RecordVideo."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
import torch
from tensordict import TensorDict

from torchrl_auv.envs import DataCollectionEnv, ScriptedExpert
from torchrl_auv.envs.render import AUV_COLOURS, top_view

SIZE = 260  # pixels over the area (200 m) and 15 % beyond each side: 1 pixel per metre


def pixel(north: float, east: float) -> tuple[int, int]:
    """Row and column of a point: the view spans -30..230 m both ways, north up."""
    return int(230 - north), int(east + 30)


@pytest.fixture(scope="module")
def scene():
    env = DataCollectionEnv(batch_size=[], seed=0)
    sim = env.reset()["sim"].clone()
    sim["truth", "eta"][:, :2] = torch.tensor([[50.0, 40.0], [150.0, 160.0]])
    sim["truth", "eta"][:, 5] = 0.0  # heading north: the tick points up from the centre
    sim["asv"][:2] = torch.tensor([100.0, 100.0])
    return env, sim


def test_the_auvs_are_drawn_where_they_are_in_their_colours(scene):
    env, sim = scene
    image = top_view(sim, env.config.area_m, size=SIZE)
    assert image.shape == (SIZE, SIZE, 3) and image.dtype == np.uint8
    for k, (north, east) in enumerate([(50, 40), (150, 160)]):
        row, col = pixel(north, east)
        below = image[row + 2 : row + 4, col - 1 : col + 1].reshape(-1, 3)  # south of the tick
        assert (below == AUV_COLOURS[k]).all(), (k, below)
    row, col = pixel(100, 100)
    assert (image[row, col] == 255).all()  # the ASV, white
    assert (image[5, 5] == 200).all() and (image[-5, -5] == 200).all()  # outside the area
    inside = image[pixel(190, 120)[0], pixel(190, 120)[1]]
    assert inside[2] > inside[0]  # the seabed, blue


def test_nodes_are_filled_by_their_buffers(scene):
    env, sim = scene
    sim = sim.clone()
    nodes = sim["task", "nodes"]
    far = (nodes["position"][:, :2] - torch.tensor([100.0, 100.0])).norm(dim=-1).argmax()
    nodes["buffer"][:] = 0.0
    empty = top_view(sim, env.config.area_m, size=SIZE)
    nodes["buffer"][far] = 1.0
    full = top_view(sim, env.config.area_m, size=SIZE)
    row, col = pixel(*nodes["position"][far, :2].tolist())
    assert (empty[row, col] == 255).all()  # an empty node is white
    assert full[row, col].tolist() == [0, 255, 0]  # the fullest node is green


def test_bad_input_is_named(scene):
    env, sim = scene
    with pytest.raises(ValueError, match="size must be an int >= 32"):
        top_view(sim, env.config.area_m, size=8)
    with pytest.raises(ValueError, match="sim must be one unbatched scene"):
        top_view(torch.stack([sim, sim]), env.config.area_m)


def test_the_gymnasium_view_renders_each_decision():
    env = gymnasium.make("torchrl_auv/DataCollection-v2", render_mode="rgb_array", max_steps=5)
    env.reset(seed=1)
    first = env.render()
    env.step(env.action_space.sample())
    second = env.render()
    assert first.shape == (400, 400, 3) and first.dtype == np.uint8
    assert (first != second).any()
    plain = gymnasium.make("torchrl_auv/DataCollection-v2", max_steps=5)
    plain.reset(seed=1)
    assert plain.render() is None
    with pytest.raises(ValueError, match="render_mode must be None or one of"):
        gymnasium.make("torchrl_auv/Tracking-v0", render_mode="rgb_array")


def test_record_video_of_an_expert_episode(tmp_path):
    pytest.importorskip("moviepy")
    from gymnasium.wrappers import RecordVideo

    env = gymnasium.make("torchrl_auv/DataCollection-v2", render_mode="rgb_array", max_steps=12)
    env = RecordVideo(env, str(tmp_path), episode_trigger=lambda _: True, disable_logger=True)
    expert = ScriptedExpert(env.unwrapped._env)
    obs, _ = env.reset(seed=0)
    done, steps = False, 0
    while not done:
        action = expert(TensorDict(observation=torch.as_tensor(obs)))["action"].numpy()
        obs, _, terminated, truncated, _ = env.step(action)
        done, steps = terminated or truncated, steps + 1
    env.close()
    video = tmp_path / "rl-video-episode-0.mp4"
    assert steps == 12 and video.stat().st_size > 1000
    import imageio.v3 as iio

    frames = iio.imread(video)
    assert frames.shape == (steps + 1, 400, 400, 3)  # the reset's frame and one per decision
