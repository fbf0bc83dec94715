"""Print the held-out variance a supervised regressor explains of the expert's actions.

python -m torchrl_auv.cli.imitation --sea-states ideal es ves --scenes 32
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

import torch

from torchrl_auv.envs.demonstrations import collect_demonstrations
from torchrl_auv.report.imitation import INPUTS, explained_variance


def main(argv: Sequence[str] | None = None) -> list[dict]:
    """Print the markdown table of R^2 per sea state, input and action dimension."""
    parser = argparse.ArgumentParser(prog="python -m torchrl_auv.cli.imitation")
    parser.add_argument("--sea-states", nargs="+", default=["ideal", "es", "ves"])
    parser.add_argument("--scenes", type=int, default=32)
    parser.add_argument("--heldout-scenes", type=int, default=8)
    parser.add_argument("--steps", type=int, default=1000, help="decisions per scene")
    parser.add_argument("--fit-steps", type=int, default=6000)
    parser.add_argument("--inputs", nargs="+", default=list(INPUTS), choices=INPUTS)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--heldout-seed", type=int, default=1000)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    rows = []
    print(
        "| sea | inputs | samples | split | depth | heading | rpm |\n|---|---|---|---|---|---|---|"
    )
    for sea in args.sea_states:
        options = {"env": "data_collection", "max_steps": args.steps, "sea_state": sea}
        train = collect_demonstrations(episodes=args.scenes, seed=args.seed, **options)
        heldout = collect_demonstrations(
            episodes=args.heldout_scenes, seed=args.heldout_seed, **options
        )
        for inputs in args.inputs:
            r2 = explained_variance(train, heldout, inputs=inputs, steps=args.fit_steps)
            samples = int((~train["overridden"]).sum())
            for split in ("train", "heldout"):
                rows.append(
                    {
                        "sea_state": sea,
                        "inputs": inputs,
                        "samples": samples,
                        "split": split,
                        "r2": r2[split],
                    }
                )
                values = " | ".join(f"{v:.2f}" for v in r2[split])
                print(f"| {sea} | {inputs} | {samples} | {split} | {values} |", flush=True)
    return rows


if __name__ == "__main__":
    sys.exit(main())
