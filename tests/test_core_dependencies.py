"""The core layers (physics, envs, modules, objectives) and the evaluation run with torch,
torchrl, tensordict, gymnasium and numpy alone (issue [25/26]): in a process where the packages
of the recipes, plots, datasets and extras cannot be imported, the envs roll out, one LAC update
runs on their data through TorchRL's own modules and the reference policies are evaluated."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest

#: what the core must not need (the recipes', the plots', the extras')
NOT_CORE = (
    "matplotlib",
    "hydra",
    "omegaconf",
    "wandb",
    "tqdm",
    "minari",
    "h5py",
    "moviepy",
    "imageio",
    "scipy",
    "pandas",
    "rliable",
    "openai",
    "ray",
    "filterpy",
)

SCRIPT = """
import sys

for name in NOT_CORE:  # as if not installed: `import name` raises ModuleNotFoundError
    sys.modules[name] = None

import torch
from tensordict import TensorDict
from tensordict.nn import NormalParamExtractor, TensorDictModule
from torchrl.modules import MLP, ProbabilisticActor, TanhNormal, ValueOperator

import torchrl_auv.envs, torchrl_auv.modules, torchrl_auv.objectives, torchrl_auv.physics
from torchrl_auv.envs import AUVTrackingEnv, DataCollectionEnv, ScriptedExpert
from torchrl_auv.objectives import LyapunovActorCriticLoss

fleet = DataCollectionEnv(batch_size=[2], seed=0, num_sensors=5, flatten_agents=True)
data = fleet.rollout(4, ScriptedExpert(fleet))
assert data["next", "cost"].shape == (2, 4, 1)
env = AUVTrackingEnv(batch_size=[2], seed=0, max_steps=8)
data = env.rollout(8).reshape(-1)
obs, act = env.observation_spec["observation"].shape[-1], env.action_spec.shape[-1]
net = torch.nn.Sequential(MLP(obs, 2 * act, num_cells=[16]), NormalParamExtractor())
actor = ProbabilisticActor(
    TensorDictModule(net, ["observation"], ["loc", "scale"]),
    in_keys=["loc", "scale"],
    distribution_class=TanhNormal,
    return_log_prob=True,
)
critic = ValueOperator(MLP(obs + act, 1, num_cells=[16]), ["observation", "action"])
loss = LyapunovActorCriticLoss(actor, critic)
out = loss(data)
total = sum(v for k, v in out.items() if k.startswith("loss_"))
total.backward()
torch.optim.Adam(loss.parameters(), 1e-3).step()
from torchrl_auv.evaluation import evaluate, reference_policies

def scenes(sea_state, seed):
    return DataCollectionEnv(batch_size=[1], sea_state=sea_state, seed=seed, max_steps=3)

rows = evaluate(scenes, reference_policies(), ["ideal"], seed=100, steps=3)
assert [row["policy"] for row in rows] == ["expert", "idle", "random"]
loaded = sorted(m for m in sys.modules if m.split(".")[0] in NOT_CORE and sys.modules[m])
assert not loaded, loaded
print("core ok", sorted(k for k in out.keys() if k.startswith("loss_")))
"""


def _python(script: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", script],
        env={**os.environ, "OMP_NUM_THREADS": "1"},
        capture_output=True,
        text=True,
        timeout=600,
    )


def test_the_core_layers_run_without_the_recipes_plots_and_extras_packages():
    done = _python(f"NOT_CORE = {NOT_CORE!r}\n" + textwrap.dedent(SCRIPT))
    assert done.returncode == 0, done.stderr[-3000:]
    assert "core ok ['loss_actor', 'loss_beta', 'loss_lambda', 'loss_lyapunov']" in done.stdout


EXTRAS_SCRIPT = """
import sys

for name in ("hydra", "omegaconf", "tqdm", "wandb", "matplotlib"):
    sys.modules[name] = None  # as if only the core were installed

try:
    import torchrl_auv.training
except ImportError as error:
    print("training:", error)
try:
    import torchrl_auv.report
except ImportError as error:
    print("report:", error)
from torchrl_auv.cli.main import main, missing_recipe_packages

print("missing:", missing_recipe_packages())
try:
    main(["train", "framework=sac"])
except SystemExit as stop:
    print("exit:", stop.code)
"""


def test_without_the_extras_each_part_that_needs_one_names_it():
    """Only the core installed: importing the training layer or the report, and the
    console's recipes each say which extra to install (the core imports, as above)."""
    done = _python(EXTRAS_SCRIPT)
    assert done.returncode == 0, done.stderr[-3000:]
    lines = dict(line.split(": ", 1) for line in done.stdout.splitlines() if ": " in line)
    assert "pip install 'torchrl-auv[recipes]'" in lines["training"]
    assert "missing: hydra-core, tqdm" in lines["training"]
    assert "pip install 'torchrl-auv[recipes]'" in lines["report"]
    assert lines["missing"] == "['hydra-core', 'matplotlib', 'tqdm', 'wandb']"
    assert lines["exit"] == "2"
    assert "the recipes need the recipes extra" in done.stderr
    assert "missing: hydra-core, matplotlib, tqdm, wandb" in done.stderr


def test_a_wandb_logger_without_wandb_is_refused_before_any_work(monkeypatch):
    import importlib.util

    from torchrl_auv.training import check_config

    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "wandb" else real(name, *a)
    )
    with pytest.raises(ValueError, match=r"logger.backend='wandb' needs wandb.*logger.backend=csv"):
        check_config({"logger": {"backend": "wandb"}})
    check_config({"logger": {"backend": "csv"}})
