"""``recipes/diffusion_rl/rollout_oracle.py``: copies of a scene share the simulation's random
numbers, and the oracle keeps the prior's choice where no candidate scores better."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import torch
from torchrl.envs import step_mdp

from torchrl_auv.envs.data_collection import AGENT_OBSERVATION_FEATURES
from torchrl_auv.training.first_stage import untrained_proposer

SCRIPT = Path(__file__).resolve().parents[2] / "recipes" / "diffusion_rl" / "rollout_oracle.py"


def _script():
    spec = importlib.util.spec_from_file_location("_rollout_oracle", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _same_scene_twice(env):
    td = env.reset()
    return td[::2].unsqueeze(1).expand(td.batch_size[0] // 2, 2).clone().reshape(-1)


def _diverged(env, steps: int = 3) -> float:
    """Largest difference between the two copies of each scene after ``steps`` identical
    random actions."""
    td = _same_scene_twice(env)
    generator = torch.Generator().manual_seed(0)
    for _ in range(steps):
        action = torch.rand(td.batch_size[0] // 2, env.num_auvs, 3, generator=generator) * 2 - 1
        td.set(("agents", "action"), action.repeat_interleave(2, 0))
        td = step_mdp(env.step(td))
    eta = td["sim", "truth", "eta"].reshape(td.batch_size[0] // 2, 2, -1)
    return (eta[:, 0] - eta[:, 1]).abs().max().item()


def test_copies_of_a_scene_share_every_random_number_and_plain_scenes_do_not():
    script = _script()
    assert _diverged(script.scene_env("ves", 3, 4, copies=2)) == 0.0
    assert _diverged(script.scene_env("ves", 3, 4)) > 0.0  # the check can fail


def test_the_oracle_keeps_the_priors_choice_where_no_candidate_delivers_more(tmp_path):
    """In the first decisions no AUV reaches a node within the horizon: every candidate
    delivers nothing, and the tie keeps the prior's choice."""
    script = _script()
    folder = tmp_path / "stage"
    folder.mkdir()
    model = {"noise_model": "mlp", "hidden": 16, "cond_dim": 8, "depth": 1}
    model |= {"schedule": "linear", "num_train_steps": 100}
    proposer = untrained_proposer(
        len(AGENT_OBSERVATION_FEATURES), 3, history=10, horizon=4, model=model
    )
    proposer.save(folder / "proposer.pt")
    out = tmp_path / "oracle.json"
    args = ["--scenes", "1", "--decisions", "2", "--horizon", "2", "--alone", "3"]
    args += ["--candidates", "2", "--score", "sdr", "--out", str(out)]
    stats = script.main([str(folder), *args])
    assert stats["share_prior_choice"] == 1.0 and stats["score_spread_mean"] == 0.0
    assert json.loads(out.read_text())["decisions"] == 2.0
