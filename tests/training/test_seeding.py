"""One seeding helper for every recipe: python, numpy and torch seeded together."""

from __future__ import annotations

import random
from pathlib import Path

import numpy as np
import pytest
import torch

from torchrl_auv.training import Run, configure_threads, seed_everything


def _draws():
    return random.random(), float(np.random.rand()), torch.rand(1).item()  # noqa: NPY002


def test_seed_everything_seeds_python_numpy_and_torch():
    seed_everything(3)
    first = _draws()
    seed_everything(3)
    assert _draws() == first
    seed_everything(4)
    assert all(a != b for a, b in zip(_draws(), first, strict=True))


@pytest.mark.parametrize("seed", [-1, 1.5, "0", True])
def test_seed_everything_names_a_bad_seed(seed):
    with pytest.raises(ValueError, match="seed must be an int >= 0"):
        seed_everything(seed)


@pytest.mark.parametrize("threads", [0, 2.0])
def test_configure_threads_names_a_bad_count(threads):
    with pytest.raises(ValueError, match="num_threads must be an int >= 1"):
        configure_threads(threads)


def test_a_run_seeds_every_rng(tmp_path):
    from hydra import compose, initialize_config_dir

    folder = Path(__file__).resolve().parents[2] / "recipes" / "sac"
    with initialize_config_dir(config_dir=str(folder), version_base=None):
        cfg = compose("quick", [f"run_dir={tmp_path / 'run'}", "seed=5", "logger.backend="])
    Run(cfg)
    after_start = _draws()
    seed_everything(5)
    assert _draws() == after_start


def test_a_run_stopped_before_its_first_checkpoint_is_named_and_resumable(tmp_path):
    """Killed while its first checkpoint was being written (only a staged save left): a new
    start in that folder says so and how to go on; resume= starts it again from frame 0."""
    from hydra import compose, initialize_config_dir

    run = tmp_path / "run"
    (run / "checkpoints" / ".stage-checkpoint-000000000200").mkdir(parents=True)
    folder = Path(__file__).resolve().parents[2] / "recipes" / "sac"
    with initialize_config_dir(config_dir=str(folder), version_base=None):
        fresh = compose("quick", [f"run_dir={run}", "logger.backend="])
        resumed = compose("quick", [f"resume={run}", "logger.backend="])
    with pytest.raises(ValueError, match=r"stopped before its first checkpoint.*resume="):
        Run(fresh)
    assert Run(resumed).dir == run
