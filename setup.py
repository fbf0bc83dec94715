"""The package list, which pyproject.toml cannot state: ``torchrl_auv`` and its subpackages,
and the repository's ``recipes/`` (scripts and Hydra configs, each folder a package of data)
shipped inside the wheel as ``torchrl_auv/recipes/``, so that ``torchrl-auv train ...`` runs
from an installed wheel while the recipes stay readable scripts in the repository (as
TorchRL's sota-implementations). Everything else is in pyproject.toml."""

from pathlib import Path

from setuptools import find_packages, setup

RECIPES = Path("recipes")
recipe_folders = sorted(
    ".".join(("torchrl_auv", *folder.parts))
    for folder in [RECIPES, *RECIPES.rglob("*")]
    if folder.is_dir() and folder.name != "__pycache__"
)

setup(
    packages=[*find_packages(include=["torchrl_auv", "torchrl_auv.*"]), *recipe_folders],
    package_dir={"torchrl_auv.recipes": "recipes"},
    package_data={name: ["*.yaml", "*.md"] for name in recipe_folders},
)
