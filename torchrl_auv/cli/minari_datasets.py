"""Create offline datasets in Minari's format (``pip install -e '.[datasets]'``).

python -m torchrl_auv.cli.minari_datasets --env data_collection --policy expert lazy random
python -m torchrl_auv.cli.minari_datasets --env tracking --policy expert random --episodes 50

Each policy becomes the dataset ``torchrl_auv/<env>/<policy>-v<version>`` under
``MINARI_DATASETS_PATH`` (Minari's default ``~/.minari/datasets``); load it with
``minari.load_dataset(id)`` or ``torchrl.data.datasets.MinariExperienceReplay(id, batch_size,
load_from_local_minari=True)``. See :mod:`torchrl_auv.envs.minari_datasets`.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

import torch

from torchrl_auv.envs.minari_datasets import DATASET_ENVS, POLICIES, create_minari_dataset


def dataset_id(env: str, policy: str, version: int) -> str:
    """``torchrl_auv/<env without underscores>/<policy>-v<version>``.

    >>> dataset_id("data_collection", "expert", 0)
    'torchrl_auv/datacollection/expert-v0'
    """
    return f"torchrl_auv/{env.replace('_', '')}/{policy}-v{version}"


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m torchrl_auv.cli.minari_datasets --env ENV --policy NAME [NAME ...]``."""
    parser = argparse.ArgumentParser(prog="python -m torchrl_auv.cli.minari_datasets")
    parser.add_argument("--env", choices=sorted(DATASET_ENVS), default="data_collection")
    parser.add_argument("--policy", nargs="+", choices=sorted(POLICIES), default=["expert"])
    parser.add_argument("--episodes", type=int, default=100, help="scenes, one episode each")
    parser.add_argument("--max-steps", type=int, default=None, help="the env's default if unset")
    parser.add_argument("--sea-state", default="ideal")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--ref-episodes", type=int, default=16)
    parser.add_argument("--version", type=int, default=0)
    parser.add_argument("--author", default=None)
    parser.add_argument("--author-email", default=None)
    parser.add_argument("--code-permalink", default=None)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    options = {"sea_state": args.sea_state}
    if args.max_steps is not None:
        options["max_steps"] = args.max_steps
    for policy in args.policy:
        name = dataset_id(args.env, policy, args.version)
        try:
            dataset = create_minari_dataset(
                name,
                env=args.env,
                policy=policy,
                episodes=args.episodes,
                seed=args.seed,
                ref_episodes=args.ref_episodes,
                author=args.author,
                author_email=args.author_email,
                code_permalink=args.code_permalink,
                **options,
            )
        except (ValueError, ImportError) as err:
            parser.error(str(err))
        meta = dataset.storage.metadata
        print(
            f"{name}: {dataset.total_episodes} episodes, {dataset.total_steps} steps, "
            f"ref_min_score {meta['ref_min_score']:.3f}, ref_max_score {meta['ref_max_score']:.3f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
