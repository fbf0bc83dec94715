"""One entry point for every framework, and the script the sweeps run.

    .venv/bin/python recipes/train.py framework=sac preset=quick run_dir=runs/sac-quick
    .venv/bin/python recipes/train.py -m +sweeps=tiny run_root=runs/tiny

``framework`` picks the recipe ``recipes/<framework>/train.py`` and ``preset`` (``paper``,
``quick``, ``fast``) its config ``recipes/<framework>/<preset>.yaml``; every other key is the
recipe's own. Every folder here with a ``train.py`` and a ``paper.yaml`` is a framework
(:func:`recipe_names`, registered as ``framework/<name>`` in Hydra's ConfigStore): a new recipe
is one folder, and ``--help`` lists it. A sweep (``recipes/sweeps/``) is a Hydra multirun over
these keys: one run folder per job, the jobs' values checked before the first starts, on this
machine or, with ``hydra/launcher=ray``, as tasks on a Ray cluster (``recipes/README.md``).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import hydra
from hydra.core.config_store import ConfigStore
from omegaconf import DictConfig, OmegaConf

import torchrl_auv.training  # noqa: F401  (registers the run_folder resolver the presets use)

HERE = Path(__file__).resolve().parent


def recipe_names() -> list[str]:
    """The frameworks: the folders beside this script with a ``train.py`` and a
    ``paper.yaml``."""
    return sorted(
        folder.name
        for folder in HERE.iterdir()
        if (folder / "train.py").is_file() and (folder / "paper.yaml").is_file()
    )


def sweep_names() -> list[str]:
    """The sweeps of ``recipes/sweeps/`` (``_common.yaml`` is included by each, not one)."""
    return sorted(p.stem for p in (HERE / "sweeps").glob("*.yaml") if not p.stem.startswith("_"))


def register_frameworks() -> None:
    """``framework/<name>`` for each of :func:`recipe_names`: the recipe's config
    ``<name>/<preset>.yaml`` at the top of the config, and ``framework: <name>``."""
    store = ConfigStore.instance()
    for name in recipe_names():
        node = {"defaults": [{f"/{name}@_here_": "${preset}"}], "framework": name}
        store.store(group="framework", name=name, node=node, package="_global_")


register_frameworks()
OmegaConf.register_new_resolver("recipe_names", lambda: "|".join(recipe_names()), replace=True)
OmegaConf.register_new_resolver("sweep_names", lambda: ", ".join(sweep_names()), replace=True)


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
