"""TorchRL's own multi-agent scripts on the data-collection env, only the constructor swapped
(``recipes/marl/use_torchrl_script.py``; issue [26/26])."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
_SPEC = importlib.util.spec_from_file_location(
    "_use_torchrl_script", REPO / "recipes" / "marl" / "use_torchrl_script.py"
)
_TOOL = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(_TOOL)
SCRIPTS, main, swap_constructor = _TOOL.SCRIPTS, _TOOL.main, _TOOL.swap_constructor

VMAS_LIKE = """from torchrl.envs.libs.vmas import VmasEnv


def train(cfg):
    env = VmasEnv(
        scenario=cfg.env.scenario_name,
        num_envs=cfg.env.vmas_envs,
        **cfg.env.scenario,
    )
    env = wrap(env, f(env.reward_key))

    env_test = VmasEnv(scenario=cfg.env.scenario_name, num_envs=g(cfg.eval.evaluation_episodes))
    return env, env_test
"""


def test_only_the_two_constructors_change():
    out = swap_constructor(VMAS_LIKE)
    removed = set(VMAS_LIKE.splitlines()) - set(out.splitlines())
    assert removed == {
        "    env = VmasEnv(",
        "        scenario=cfg.env.scenario_name,",
        "        num_envs=cfg.env.vmas_envs,",
        "        **cfg.env.scenario,",
        "    env_test = VmasEnv(scenario=cfg.env.scenario_name, "
        "num_envs=g(cfg.eval.evaluation_episodes))",
    }
    assert "    env = wrap(env, f(env.reward_key))" in out.splitlines()
    assert "        batch_size=[cfg.eval.evaluation_episodes]," in out.splitlines()
    assert out.count("DataCollectionEnv(") == 2 and "per_agent_done=False" in out
    compile(out, "swapped", "exec")  # still Python


def test_a_script_that_is_not_a_vmas_one_is_refused(tmp_path, capsys):
    with pytest.raises(ValueError, match="does not import VmasEnv"):
        swap_constructor("import torch\n")
    folder = tmp_path / "rl" / "sota-implementations" / "multiagent"
    folder.mkdir(parents=True)
    (folder / "sac.py").write_text("import torch\n")
    with pytest.raises(SystemExit):
        main(["--torchrl", str(tmp_path / "rl"), "--script", "sac", "--out", str(tmp_path / "o")])
    assert "--script sac: the script does not import VmasEnv" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["--torchrl", str(tmp_path), "--script", "sac", "--out", str(tmp_path / "o")])
    assert "no sota-implementations/multiagent/sac.py in it" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.parametrize("script", SCRIPTS)
def test_torchrls_multi_agent_script_trains_on_the_env(script, tmp_path):
    """Set TORCHRL_CHECKOUT to a TorchRL checkout (its sota-implementations are not in the
    pip package); two short iterations of the script, its own code, our env."""
    checkout = os.environ.get("TORCHRL_CHECKOUT")
    if not checkout:
        pytest.skip("TORCHRL_CHECKOUT (a TorchRL checkout with sota-implementations/) not set")
    assert main(["--torchrl", checkout, "--script", script, "--out", str(tmp_path)]) == 0
    command = [
        sys.executable,
        f"{script}.py",
        "logger.backend=",
        "collector.frames_per_batch=400",
        "collector.n_iters=2",
        "train.minibatch_size=100",
        "train.num_epochs=2",
        "eval.evaluation_episodes=2",
        "env.scenario.n_agents=2",
    ]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(REPO)}
    done = subprocess.run(
        command, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=900
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert "Iteration 1" in done.stdout + done.stderr
