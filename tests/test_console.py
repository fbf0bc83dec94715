"""``torchrl-auv``, the console entry point: each command runs its recipe script."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from torchrl_auv.cli.main import COMMANDS, command_line, main, recipes_dir

CONSOLE = Path(sys.executable).parent / "torchrl-auv"


def test_every_command_names_a_script_of_the_recipes_folder():
    for command, (script, _) in COMMANDS.items():
        assert (recipes_dir() / script).is_file(), command
    assert command_line(["train", "framework=sac"]) == [
        str(recipes_dir() / "train.py"),
        "framework=sac",
    ]
    assert command_line(["paper", "budget=quick"])[0].endswith("paper/run_all.py")


WRONG = [
    (["trian"], "command must be one of"),
    ([], "command must be one of"),
    (["sweep"], "sweep needs the sweep's name"),
    (["sweep", "seed=1"], "sweep needs the sweep's name"),
]


@pytest.mark.parametrize(("argv", "named"), WRONG)
def test_a_wrong_command_is_named(argv, named):
    with pytest.raises(ValueError, match=named):
        command_line(argv)


def test_usage_and_a_wrong_command_exit_with_the_usage(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["--help"])
    assert stop.value.code == 0 and "torchrl-auv COMMAND" in capsys.readouterr().out
    with pytest.raises(SystemExit) as stop:
        main(["trian", "framework=sac"])
    assert stop.value.code == 2 and "got 'trian'" in capsys.readouterr().err


@pytest.mark.skipif(not CONSOLE.is_file(), reason="the package is not installed in this venv")
def test_train_runs_the_recipe_from_any_folder(tmp_path):
    env = {**os.environ, "OMP_NUM_THREADS": "1", "WANDB_MODE": "offline"}
    run_dir = tmp_path / "run"
    done = subprocess.run(
        [
            str(CONSOLE),
            "train",
            "framework=sac",
            "preset=quick",
            "collector.total_frames=200",
            "collector.frames_per_batch=100",
            "collector.init_random_frames=100",
            "optim.updates_per_batch=4",
            "eval.steps=20",
            "logger.backend=",
            f"run_dir={run_dir}",
        ],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert "- frames: 200" in (run_dir / "summary.md").read_text()


def test_train_help_names_the_frameworks_presets_and_sweeps_it_takes():
    """``train --help`` lists this script's choices, read here from the recipes folder, and
    not the other scripts' configs (Hydra's own list named every folder of recipes/)."""
    done = subprocess.run(
        [
            sys.executable,
            str(recipes_dir() / "train.py"),
            "framework=sac",
            "preset=quick",
            "--help",
        ],
        env={**os.environ, "OMP_NUM_THREADS": "1"},
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    choices, config = done.stdout.split("== Config", 1)
    frameworks = [  # every folder of recipes/ with a train.py and a paper.yaml
        p.parent.name
        for p in recipes_dir().glob("*/train.py")
        if (p.parent / "paper.yaml").is_file()
    ]
    presets = sorted(p.stem for p in (recipes_dir() / "preset").glob("*.yaml"))
    sweeps = [p.stem for p in (recipes_dir() / "sweeps").glob("*.yaml") if p.stem[0] != "_"]
    assert f"framework={'|'.join(sorted(frameworks, key=choices.index))}" in choices
    assert f"preset={'|'.join(sorted(presets, key=choices.index))}" in choices
    assert all(f" {name}" in choices for name in sweeps)
    assert "config: main" not in done.stdout and "wandb_sweeps" not in done.stdout
    assert "run_dir: ${run_root}/sac/" in config  # the chosen framework's own config
