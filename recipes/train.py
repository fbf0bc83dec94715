"""One entry point for every framework, and the script the sweeps run.

    .venv/bin/python recipes/train.py framework=sac preset=quick run_dir=runs/sac-quick
    .venv/bin/python recipes/train.py -m +sweeps=tiny run_root=runs/tiny

``framework`` (``sac``, ``diffusion``, ``diffusion_rl``, ``diffusion_lac``) picks the recipe
``recipes/<framework>/train.py`` and ``preset`` (``paper``, ``quick``) its config; every other
key is the recipe's own. A sweep (``recipes/sweeps/``) is a Hydra multirun over these keys:
one run folder per job, the jobs' values checked before the first starts, on this machine or,
with ``hydra/launcher=ray``, as tasks on a Ray cluster (``recipes/README.md``).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import hydra
from omegaconf import DictConfig

import torchrl_auv.training  # noqa: F401  (registers the run_folder resolver the presets use)

HERE = Path(__file__).resolve().parent


def recipe_main(framework: str):
    """The ``main`` of ``recipes/<framework>/train.py`` (loaded from its file: the recipes
    are scripts, not an installed package)."""
    path = HERE / framework / "train.py"
    spec = importlib.util.spec_from_file_location(f"_recipe_{framework}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.main


@hydra.main(config_path=".", config_name="train", version_base="1.3")
def main(cfg: DictConfig) -> None:
    recipe_main(cfg.framework)(cfg)  # a Hydra main called with a config runs on that config


if __name__ == "__main__":
    main()
