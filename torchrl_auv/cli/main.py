"""``torchrl-auv``: the training recipes from an installed wheel.

The recipes are scripts with Hydra configs (``recipes/`` in the repository, shipped inside the
wheel as ``torchrl_auv/recipes/``). Each command runs one of them in place of this process, with
the arguments that follow it, exactly as ``python recipes/<script> ARGS`` would:

* ``torchrl-auv train ARGS``: ``recipes/train.py ARGS``, one training run (Hydra overrides:
  ``framework=``, ``preset=paper|quick|fast``, any config key);
* ``torchrl-auv sweep NAME ARGS``: ``recipes/train.py -m +sweeps=NAME ARGS``, a sweep of
  ``recipes/sweeps/``;
* ``torchrl-auv aggregate ARGS``: ``recipes/aggregate.py ARGS``, a sweep's table;
* ``torchrl-auv paper ARGS``: ``recipes/paper/run_all.py ARGS``, the paper's experiments;
* ``torchrl-auv tracking ARGS``: ``recipes/main.py ARGS``, the fixed-schedule tracking table;
* ``torchrl-auv recipes``: prints the recipes folder (to read or copy its configs).

Example (a short quick run; outputs under ``runs/`` of the current folder)::

    torchrl-auv train framework=diffusion_lac preset=quick collector.total_frames=400

>>> recipes_dir().joinpath("train.py").is_file()
True
>>> command_line(["sweep", "tiny", "run_root=runs/tiny"])[1:]
['-m', '+sweeps=tiny', 'run_root=runs/tiny']
"""

from __future__ import annotations

import importlib.util
import os
import sys
from collections.abc import Sequence
from pathlib import Path

import torchrl_auv

__all__ = [
    "COMMANDS",
    "RECIPE_PACKAGES",
    "command_line",
    "main",
    "missing_recipe_packages",
    "recipes_dir",
]

#: command -> (script under the recipes folder, what it is for)
COMMANDS = {
    "train": (
        "train.py",
        "one training run: framework=..., preset=paper|quick|fast, any config key",
    ),
    "sweep": ("train.py", "a sweep of recipes/sweeps/: torchrl-auv sweep NAME [overrides]"),
    "aggregate": ("aggregate.py", "one table from a sweep's runs: torchrl-auv aggregate DIR"),
    "paper": ("paper/run_all.py", "the paper's experiments: budget=quick|paper, experiments=[..]"),
    "tracking": ("main.py", "the fixed-schedule tracking table (Table III layout)"),
}


def recipes_dir() -> Path:
    """The recipes folder: ``torchrl_auv/recipes`` in an installed wheel, else ``recipes/``
    beside the package in a repository checkout."""
    package = Path(torchrl_auv.__file__).resolve().parent
    for folder in (package / "recipes", package.parent / "recipes"):
        if (folder / "train.py").is_file():
            return folder
    raise FileNotFoundError(
        f"no recipes folder with train.py in {package / 'recipes'} or "
        f"{package.parent / 'recipes'}: reinstall torchrl-auv"
    )


#: what the recipe scripts import beyond the core package: import name -> distribution
RECIPE_PACKAGES = {
    "hydra": "hydra-core",
    "omegaconf": "hydra-core",
    "tqdm": "tqdm",
    "wandb": "wandb",
    "matplotlib": "matplotlib",
}


def missing_recipe_packages() -> list[str]:
    """The distributions of :data:`RECIPE_PACKAGES` that cannot be imported (sorted; empty
    with the ``recipes`` extra installed)."""
    return sorted(
        {dist for name, dist in RECIPE_PACKAGES.items() if importlib.util.find_spec(name) is None}
    )


def command_line(argv: Sequence[str]) -> list[str]:
    """The script and its arguments for ``torchrl-auv ARGV`` (``argv[0]`` a key of
    :data:`COMMANDS`)."""
    if not argv or argv[0] not in COMMANDS:
        got = repr(argv[0]) if argv else "nothing"
        raise ValueError(f"command must be one of {sorted(COMMANDS)}, got {got}")
    command, *rest = argv
    script = str(recipes_dir() / COMMANDS[command][0])
    if command == "sweep":
        if not rest or "=" in rest[0]:
            raise ValueError(
                "sweep needs the sweep's name first (a file of recipes/sweeps/, "
                "e.g. `torchrl-auv sweep tiny`)"
            )
        name, *rest = rest
        return [script, "-m", f"+sweeps={name}", *rest]
    return [script, *rest]


def _usage() -> str:
    lines = ["usage: torchrl-auv COMMAND [ARGS...]", "", "commands:"]
    lines += [f"  {name:<10} {what}" for name, (_, what) in COMMANDS.items()]
    lines += [
        "  recipes    print the recipes folder (scripts and Hydra configs)",
        "",
        "Each command runs its recipe script with ARGS; `torchrl-auv train --help` shows "
        "the config.",
    ]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> None:
    """The console entry point: replaces this process with the recipe's (the same signals,
    exit status and output as running the script)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(_usage())
        raise SystemExit(0 if argv else 2)
    if argv[0] == "recipes":
        print(recipes_dir())
        return
    try:
        line = command_line(argv)
    except ValueError as error:
        print(f"torchrl-auv: {error}\n\n{_usage()}", file=sys.stderr)
        raise SystemExit(2) from None
    missing = missing_recipe_packages()
    if missing:
        print(
            f"torchrl-auv: the recipes need the recipes extra: pip install "
            f"'torchrl-auv[recipes]' (missing: {', '.join(missing)})",
            file=sys.stderr,
        )
        raise SystemExit(2)
    sys.stdout.flush()
    os.execv(sys.executable, [sys.executable, *line])


if __name__ == "__main__":
    main()
