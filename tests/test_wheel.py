"""The wheel on its own: built from this checkout, installed into a fresh venv outside it.

What a pip user gets (the sdist, and the wheel built from it), checked the way they would use
it (slow: a venv with torch, TorchRL and their dependencies from the package index, then a
short training run; about 5-10 minutes):
torch pinned first (as the Makefile does), the wheel next with its declared (core) dependencies,
then, from a folder outside the checkout with nothing of the checkout on ``sys.path``: the
package imports, ships ``py.typed`` and its recipes, registers both gymnasium ids, builds both
envs; the console refuses the recipes, naming the ``recipes`` extra; the Pendulum composition
example (LAC) runs on the core alone; with the ``recipes`` extra installed, ``torchrl-auv train
framework=diffusion_lac preset=quick`` trains a few hundred frames and writes its summary.
"""

from __future__ import annotations

import os
import subprocess
import sys
import venv
from pathlib import Path

import pytest

from torchrl_auv.report.paper.grid import Job

REPO = Path(__file__).resolve().parents[1]
TORCH = "torch==2.13.0"

IMPORT_CHECK = """
import importlib.resources, sys
import gymnasium, torch
import torchrl_auv
assert "{repo}" not in torchrl_auv.__file__, torchrl_auv.__file__
package = importlib.resources.files("torchrl_auv")
assert package.joinpath("py.typed").is_file()
assert package.joinpath("recipes", "train.py").is_file()
assert package.joinpath("recipes", "sac", "paper.yaml").is_file()
import torchrl_auv.envs  # registers the gymnasium ids
from torchrl_auv.envs import AUVTrackingEnv, DataCollectionEnv
for env_id in ("torchrl_auv/Tracking-v0", "torchrl_auv/DataCollection-v2"):
    env = gymnasium.make(env_id)
    obs, _ = env.reset(seed=0)
    obs, *_ = env.step(env.action_space.sample())
    print(env_id, "observation", obs.shape)
for env in (AUVTrackingEnv(batch_size=[2], seed=0), DataCollectionEnv(batch_size=[2], seed=0)):
    td = env.rollout(3)
    print(type(env).__name__, "rollout", tuple(td.batch_size))
print("torchrl_auv", torchrl_auv.__version__, "from", torchrl_auv.__file__)
"""


def _run(argv: list[str], cwd: Path, env: dict[str, str], timeout: int = 1800) -> str:
    done = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, (
        f"{argv} exited {done.returncode}:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    )
    return done.stdout


@pytest.mark.slow
def test_the_wheel_installs_and_trains_outside_the_checkout(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env.update(
        OMP_NUM_THREADS="1",
        MKL_NUM_THREADS="1",
        WANDB_MODE="offline",
        HOME=str(tmp_path / "home"),
        PIP_DISABLE_PIP_VERSION_CHECK="1",
    )
    dist = tmp_path / "dist"
    # an sdist, then the wheel built from it (what `python -m build` does): what the wheel
    # needs must be in the sdist too
    _run([sys.executable, "-m", "build", "--outdir", str(dist), str(REPO)], cwd=tmp_path, env=env)
    (wheel,) = dist.glob("torchrl_auv-*.whl")

    venv.create(tmp_path / "venv", with_pip=True)
    python = tmp_path / "venv" / "bin" / "python"
    _run([str(python), "-m", "pip", "install", "--quiet", TORCH], cwd=tmp_path, env=env)
    # the core alone: torch, torchrl, tensordict, gymnasium, numpy
    _run([str(python), "-m", "pip", "install", "--quiet", TORCH, str(wheel)], cwd=tmp_path, env=env)

    work = tmp_path / "user"
    work.mkdir()
    out = _run([str(python), "-c", IMPORT_CHECK.format(repo=REPO)], cwd=work, env=env)
    print(out)
    assert "torchrl_auv/DataCollection-v2 observation (76,)" in out
    assert "DataCollectionEnv rollout (2, 3)" in out
    console = str(tmp_path / "venv" / "bin" / "torchrl-auv")
    refused = subprocess.run(
        [console, "train"], cwd=work, env=env, capture_output=True, text=True, timeout=300
    )
    assert refused.returncode == 2 and "pip install 'torchrl-auv[recipes]'" in refused.stderr
    # LAC on the core alone (TorchRL's Pendulum and the tracking env)
    out = _run(
        [
            str(python),
            str(REPO / "examples" / "lac_vs_sac.py"),
            "--env",
            "pendulum",
            "--frames",
            "1000",
        ],
        cwd=work,
        env=env,
    )
    print(out)

    # then the recipes extra
    _run(
        [str(python), "-m", "pip", "install", "--quiet", TORCH, f"{wheel}[recipes]"],
        cwd=tmp_path,
        env=env,
    )

    job = Job("diffusion_lac", "ideal", "s_surface", 0)
    overrides = job.overrides("quick", root=work, frames=400)
    out = _run([console, "train", *overrides], cwd=work, env=env)
    summary = work / "jobs" / job.name / "summary.md"
    text = summary.read_text()
    print(text)
    assert "- frames: 400" in text
    assert "| ideal | diffusion_lac |" in text
