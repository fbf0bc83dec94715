"""Roll the data-collection env out with the scripted expert and plot the episode.

    .venv/bin/python examples/rollout_expert.py --steps 300 --out expert.png

Two REMUS-100 AUVs, 60 sensor nodes, the ``("agents", ...)`` layout; prints the episode's
paper metrics (SDR in Mbit, SSN, EC in W, collisions, violations) per scene and writes a top
view and depth profile (``torchrl_auv.report.plot_episode``).
"""

from __future__ import annotations

import argparse

import torch

from torchrl_auv.envs import DataCollectionEnv, ScriptedExpert
from torchrl_auv.report import plot_episode


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=300, help="decisions (1 s each)")
    parser.add_argument("--sea", default="ideal", choices=["ideal", "es", "ves"])
    parser.add_argument("--out", default="expert_episode.png")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)

    env = DataCollectionEnv(batch_size=[2], sea_state=args.sea, seed=0)
    rollout = env.rollout(args.steps, ScriptedExpert(env), break_when_any_done=False)
    metrics = rollout["next", "metrics"][:, -1]  # cumulative: the values at the last decision
    for name in ("sdr", "ssn", "ec", "collisions", "violations"):
        print(f"{name}: {metrics[name].tolist()}")
    print(f"plot: {plot_episode(rollout, args.out)}")


if __name__ == "__main__":
    main()
