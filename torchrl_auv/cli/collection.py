"""The data-collection task's card: how the expert, random actions and an exit policy fare.

:func:`episode_stats` rolls a policy out in :class:`~torchrl_auv.envs.DataCollectionEnv` for one
episode per scene and returns the numbers the task is judged by (per scene, then averaged):
the paper's metrics (SDR in Mbit, SSN, EC), safety (violations per AUV-decision, collisions,
terminated episodes), station keeping (services that end within the service radius), the
localisation (the filter's and the raw USBL fixes' position error), the cost (mean per
AUV-decision, the share of each term, the discounted cost from reset for given discounts).
``python -m torchrl_auv.cli.collection`` prints them as a markdown table for every preset
and rate model.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence

import torch

from torchrl_auv.envs import DataCollectionEnv
from torchrl_auv.training.evaluation import (
    episode_stats,
    make_policy,
)

__all__ = ["main"]


def main(argv: Sequence[str] | None = None) -> list[dict]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presets", nargs="+", default=["ideal", "es", "ves"])
    parser.add_argument("--rate-models", nargs="+", default=["shannon", "paper"])
    parser.add_argument("--policies", nargs="+", default=["expert", "random"])
    parser.add_argument("--scenes", type=int, default=8)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    rows = []
    for preset in args.presets:
        for rate_model in args.rate_models:
            for name in args.policies:
                env = DataCollectionEnv(batch_size=[args.scenes], sea_state=preset,
                                        rate_model=rate_model, seed=args.seed)  # fmt: skip
                stats = episode_stats(env, make_policy(name, env), args.steps)
                rows.append({"preset": preset, "rate_model": rate_model, "policy": name, **stats})
                print(_row(rows[-1], header=len(rows) == 1), flush=True)
    return rows


def _row(row: dict, header: bool) -> str:
    keys = list(row)
    line = "| " + " | ".join(_fmt(row[k]) for k in keys) + " |"
    if not header:
        return line
    return "| " + " | ".join(keys) + " |\n|" + "---|" * len(keys) + "\n" + line


def _fmt(value) -> str:
    if isinstance(value, float):
        return "nan" if math.isnan(value) else f"{value:.3g}"
    return str(value)


if __name__ == "__main__":
    main()
