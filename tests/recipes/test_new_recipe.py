"""A new recipe is one folder: ``recipes/<name>/`` with a ``train.py`` and a ``paper.yaml``
runs through ``recipes/train.py framework=<name>`` and is listed by its ``--help``, with no
other file touched."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

RECIPES = Path(__file__).resolve().parents[2] / "recipes"

TRAIN = """import hydra


@hydra.main(config_path=".", config_name="paper", version_base="1.3")
def main(cfg):
    print(f"ran {cfg.framework} with {cfg.greeting} in {cfg.preset}")


if __name__ == "__main__":
    main()
"""


def _train(recipes: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(recipes / "train.py"), *args],
        env={**os.environ, "OMP_NUM_THREADS": "1"},
        capture_output=True,
        text=True,
        timeout=300,
        cwd=recipes.parent,
    )


def test_a_recipe_folder_is_a_framework_of_the_entry_point(tmp_path):
    recipes = tmp_path / "recipes"
    shutil.copytree(RECIPES, recipes, ignore=shutil.ignore_patterns("__pycache__"))
    before = {p.relative_to(recipes) for p in recipes.rglob("*")}
    folder = recipes / "hello"
    folder.mkdir()
    (folder / "train.py").write_text(TRAIN)
    (folder / "paper.yaml").write_text("greeting: hi\npreset: paper\n")
    (folder / "quick.yaml").write_text("defaults:\n  - paper\n  - _self_\npreset: quick\n")
    touched = {p.relative_to(recipes) for p in recipes.rglob("*")} - before
    assert touched == {
        Path("hello"),
        *(Path("hello") / f for f in ("train.py", "paper.yaml", "quick.yaml")),
    }

    run_dir = f"hydra.run.dir={tmp_path / 'out'}"
    for preset in ("paper", "quick"):
        done = _train(recipes, "framework=hello", f"preset={preset}", run_dir)
        assert done.returncode == 0, done.stderr[-3000:]
        assert f"ran hello with hi in {preset}" in done.stdout
    helped = _train(recipes, "framework=hello", "--help")
    assert helped.returncode == 0, helped.stderr[-3000:]
    choices = helped.stdout.split("== Config", 1)[0]
    assert "hello" in choices.split("framework=", 1)[1].split()[0].split("|")
