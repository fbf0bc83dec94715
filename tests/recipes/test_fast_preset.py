"""``preset=fast``: the paper preset with only its speed levers changed (recipes/README.md)."""

from __future__ import annotations

from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from torchrl_auv.training import first_stage_values

RECIPES = Path(__file__).resolve().parents[2] / "recipes"

#: what the fast preset may change: scenes per batch, the update's compilation, the acting
#: proposer's sampler and steps (none of them part of the first stage's key)
SPEED_LEVERS = {"env.num_envs", "optim.compile", "proposer.sampler", "proposer.num_inference_steps"}


def _flat(cfg) -> dict:
    flat = {}

    def walk(node, prefix):
        for key, value in node.items():
            if isinstance(value, dict):
                walk(value, f"{prefix}{key}.")
            else:
                flat[f"{prefix}{key}"] = value

    walk(OmegaConf.to_container(cfg, resolve=False), "")
    return flat


@pytest.mark.parametrize("framework", ["sac", "diffusion", "diffusion_rl", "diffusion_lac"])
def test_the_fast_preset_differs_from_the_paper_preset_only_in_its_speed_levers(framework):
    with initialize_config_dir(config_dir=str(RECIPES), version_base="1.3"):
        paper = compose("train", [f"framework={framework}", "preset=paper"])
        fast = compose("train", [f"framework={framework}", "preset=fast"])
    paper_flat, fast_flat = _flat(paper), _flat(fast)
    assert paper_flat.keys() == fast_flat.keys()
    changed = {key for key in paper_flat if paper_flat[key] != fast_flat[key]}
    assert changed and changed <= SPEED_LEVERS, changed
    assert fast.env.num_envs > paper.env.num_envs
    if "optim" in fast:  # the proposer-alone recipe trains nothing after its first stage
        assert fast.optim.compile is True and paper.optim.compile is False
    if framework != "sac":
        assert fast.proposer.num_inference_steps < paper.proposer.num_inference_steps
        assert paper.proposer.num_inference_steps == 50 and paper.proposer.sampler == "ddpm"
        # one first-stage artefact serves both presets
        assert first_stage_values(fast) == first_stage_values(paper)
