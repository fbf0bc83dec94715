"""Record an expert episode of the data-collection id with gymnasium's RecordVideo.

    .venv/bin/python examples/record_video.py --steps 300 --out videos/

``gymnasium.make("torchrl_auv/DataCollection-v2", render_mode="rgb_array")`` renders the top
view of the scene (``torchrl_auv.envs.render.top_view``): the seabed, the area's edge, the
nodes filled by the data waiting in them, each AUV (ringed while in service) with its track and
a line to its assigned node, and the surface vessel. Writes ``rl-video-episode-0.mp4``
(``pip install moviepy``, in the lock) and the last frame as ``last_frame.png``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium
import matplotlib.pyplot as plt
import torch
from gymnasium.wrappers import RecordVideo
from tensordict import TensorDict

from torchrl_auv.envs import ScriptedExpert


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=300, help="decisions (1 s each)")
    parser.add_argument("--sea", default="ideal", choices=["ideal", "es", "ves"])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default="videos")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)

    env = gymnasium.make(
        "torchrl_auv/DataCollection-v2",
        render_mode="rgb_array",
        max_steps=args.steps,
        sea_state=args.sea,
    )
    env = RecordVideo(env, args.out, episode_trigger=lambda _: True, disable_logger=True)
    expert = ScriptedExpert(env.unwrapped._env)
    obs, _ = env.reset(seed=args.seed)
    done, info = False, {}
    while not done:
        action = expert(TensorDict(observation=torch.as_tensor(obs)))["action"].numpy()
        obs, _, terminated, truncated, info = env.step(action)
        done = terminated or truncated
    frame = env.render()
    env.close()
    plt.imsave(Path(args.out) / "last_frame.png", frame)
    print(f"SDR {info['metrics']['sdr']:.2f} Mbit, SSN {info['metrics']['ssn']:.0f}")
    print(f"video: {Path(args.out) / 'rl-video-episode-0.mp4'}")


if __name__ == "__main__":
    main()
