"""``device=cuda``: the env, the proposer, both learners and the recipes on a CUDA device.

Marked ``gpu`` and skipped where torch sees no CUDA device (CI has none; a developer with a GPU
runs ``pytest -m gpu tests/test_cuda.py``). The env draws its scenes and noise on a CPU
generator, so a CUDA env sees the same scenes as a CPU env of the same seed; its physics runs
in float32 on another device, so the comparisons allow float32 round-off.
"""

from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch
from tensordict import TensorDict
from torchrl.envs.utils import ExplorationType, set_exploration_type

from torchrl_auv.modules import DiffusionProposer
from torchrl_auv.training import (
    expert_policy,
    make_actor,
    make_env,
    make_lac_loss,
    make_lyapunov_critic,
    make_q_critic,
    make_sac_loss,
    select_for_replay,
)

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device"),
]

REPO = Path(__file__).resolve().parents[1]
CUDA = "cuda"


def _expert_rollout(device: str, steps: int = 10):
    env = make_env("ves", seed=3, num_envs=2, max_steps=steps, device=device)
    return env.rollout(steps, expert_policy(env))


def test_the_env_on_cuda_sees_the_cpu_scenes_and_steps_alike():
    cpu, cuda = _expert_rollout("cpu"), _expert_rollout(CUDA)
    assert cuda.device.type == "cuda" and cuda["agents", "observation"].is_cuda
    # the first observation: the same scene, drawn on the CPU generator
    torch.testing.assert_close(
        cuda["agents", "observation"][:, 0].cpu(),
        cpu["agents", "observation"][:, 0],
        rtol=1e-4,
        atol=1e-4,
    )
    # ten decisions of 20 Hz physics later: the same costs within float32 round-off
    torch.testing.assert_close(
        cuda["next", "agents", "cost"].cpu(), cpu["next", "agents", "cost"], rtol=1e-3, atol=1e-3
    )


def test_the_proposer_proposes_on_cuda():
    proposer = DiffusionProposer(6, 3, num_candidates=5, horizon=8, num_inference_steps=4).to(CUDA)
    out = proposer(TensorDict({"observation": torch.zeros(4, 6, device=CUDA)}, batch_size=[4]))
    candidates = out["proposer", "candidates"]
    assert candidates.is_cuda and candidates.shape == (4, 5, 8, 3)
    assert bool(torch.isfinite(candidates).all())


@pytest.mark.parametrize("learner", ["sac", "lac"])
def test_a_learner_updates_its_parameters_on_cuda(learner):
    env = make_env("ideal", seed=0, num_envs=2, max_steps=6, device=CUDA)
    actor = make_actor(env, (32, 32)).to(CUDA)
    if learner == "sac":
        loss, _ = make_sac_loss(actor, make_q_critic(env, (32, 32)).to(CUDA), env)
    else:
        # no .to() on the loss: the task critic and the dual variables follow the actor
        loss = make_lac_loss(
            actor, make_lyapunov_critic(env, (32,)).to(CUDA), env, cost="stability", hidden=(32,)
        )
    with set_exploration_type(ExplorationType.RANDOM):
        batch = select_for_replay(env.rollout(6, actor)).reshape(-1)
    before = [p.detach().clone() for p in loss.parameters()]
    optimiser = torch.optim.Adam(loss.parameters(), lr=1e-3)
    out = loss(batch)
    total = sum(value for key, value in out.items() if key.startswith("loss_"))
    total.backward()
    optimiser.step()
    assert all(p.is_cuda for p in loss.parameters())
    assert bool(torch.isfinite(total)) and any(
        not torch.equal(a, b) for a, b in zip(before, loss.parameters(), strict=True)
    )


TINY = {
    "sac": [
        "collector.frames_per_batch=100",
        "collector.init_random_frames=100",
        "optim.updates_per_batch=4",
    ],
    "diffusion_lac": [
        "collector.frames_per_batch=100",
        "proposer.demo_episodes=2",
        "proposer.demo_steps=30",
        "proposer.pretrain_steps=20",
        "proposer.dagger_steps=10",
        "proposer.num_inference_steps=2",
        "optim.updates_per_batch=2",
    ],
}


@pytest.mark.parametrize("recipe", sorted(TINY))
def test_a_recipe_trains_and_evaluates_with_device_cuda(tmp_path, recipe):
    run_dir = tmp_path / "run"
    command = [
        sys.executable,
        f"recipes/{recipe}/train.py",
        "--config-name=quick",
        "device=cuda",
        "collector.total_frames=200",
        "eval.steps=10",
        "logger.backend=",
        f"run_dir={run_dir}",
        *TINY[recipe],
    ]
    if recipe != "sac":
        command.append(f"proposer.cache_dir={tmp_path / 'first_stage'}")
    env = {**os.environ, "OMP_NUM_THREADS": "1", "WANDB_MODE": "offline"}
    result = subprocess.run(command, cwd=REPO, env=env, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-4000:]
    with open(run_dir / "eval.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert rows[0]["policy"] == recipe and float(rows[0]["decisions"]) == 10.0
