"""Collect scripted-expert demonstrations into a folder (TorchRL replay-buffer storage).

python -m torchrl_auv.cli.demonstrations --env tracking --episodes 8 --out demos/
python -m torchrl_auv.cli.demonstrations --env data_collection --episodes 4 --out demos_dc/
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import torch

from torchrl_auv.envs.demonstrations import ENVS, collect_demonstrations, save_demonstrations


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m torchrl_auv.cli.demonstrations --env {tracking,data_collection} --episodes N
    --out DIR``."""
    parser = argparse.ArgumentParser(prog="python -m torchrl_auv.cli.demonstrations")
    parser.add_argument("--env", choices=ENVS, default="tracking")
    parser.add_argument("--episodes", type=int, required=True)
    parser.add_argument("--out", required=True)
    parser.add_argument("--max-steps", type=int, default=300)
    parser.add_argument("--horizon", type=int, default=8)
    parser.add_argument("--history", type=int, default=10)
    parser.add_argument("--sea-state", default="ideal")
    parser.add_argument("--controller", default="s_surface")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    options = {k: v for k, v in vars(args).items() if k != "out"}
    out = Path(args.out)
    if out.exists() and any(out.iterdir()):
        parser.error(f"--out {out} exists and is not empty; choose a new folder")
    try:
        data = collect_demonstrations(**options)
    except ValueError as err:
        parser.error(str(err))
    save_demonstrations(data, out, metadata=options)
    return 0


if __name__ == "__main__":
    sys.exit(main())
