"""The core layers (physics, envs, modules, objectives) run with torch, torchrl, tensordict,
gymnasium and numpy alone (issue [25/26]): in a process where the packages of the recipes,
plots, datasets and extras cannot be imported, the envs roll out and one LAC update runs on
their data through TorchRL's own modules."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

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
loaded = sorted(m for m in sys.modules if m.split(".")[0] in NOT_CORE and sys.modules[m])
assert not loaded, loaded
print("core ok", sorted(k for k in out.keys() if k.startswith("loss_")))
"""


def test_the_core_layers_run_without_the_recipes_plots_and_extras_packages():
    script = f"NOT_CORE = {NOT_CORE!r}\n" + textwrap.dedent(SCRIPT)
    done = subprocess.run(
        [sys.executable, "-c", script],
        env={**os.environ, "OMP_NUM_THREADS": "1"},
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert "core ok ['loss_actor', 'loss_beta', 'loss_lambda', 'loss_lyapunov']" in done.stdout
