"""Replay a REMUS-100 reference CSV through the 6-DoF model.

python -m torchrl_auv.cli.remus100 replay IN.csv OUT.csv [--dtype float32] [--dt 0.05]
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

import torch

from torchrl_auv.physics.remus100 import replay


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point: ``python -m torchrl_auv.cli.remus100 replay IN OUT``."""
    parser = argparse.ArgumentParser(prog="python -m torchrl_auv.cli.remus100")
    sub = parser.add_subparsers(dest="command", required=True)
    rep = sub.add_parser("replay", help="simulate a reference CSV's commands from its row 0")
    rep.add_argument("input", help="CSV in the reference format")
    rep.add_argument("output", help="where to write the simulated CSV")
    rep.add_argument("--dtype", choices=("float64", "float32"), default="float64")
    rep.add_argument("--dt", type=float, default=0.05, help="step in seconds (default 0.05)")
    args = parser.parse_args(argv)
    replay(args.input, args.output, dtype=getattr(torch, args.dtype), dt=args.dt)
    return 0


if __name__ == "__main__":
    sys.exit(main())
