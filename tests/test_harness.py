"""The test harness itself: the global-RNG guard catches a single draw from any global RNG."""

from __future__ import annotations

import random

import numpy as np
import pytest
import torch


@pytest.mark.parametrize(
    "draw",
    [
        lambda: torch.rand(1),
        lambda: np.random.rand(),  # noqa: NPY002 - the global RNG, on purpose
        lambda: np.random.randn(),  # noqa: NPY002 - also fills the gaussian cache
        lambda: random.random(),
    ],
    ids=["torch", "numpy", "numpy-gauss", "python"],
)
def test_the_guard_catches_one_draw_from_a_global_rng(global_rng_guard, draw):
    draw()  # mid-stream: numpy's key array now changes only every 624 draws
    with pytest.raises(AssertionError, match="global"):
        with global_rng_guard:
            draw()


def test_the_guard_lets_generator_draws_through(global_rng_guard):
    with global_rng_guard:
        torch.rand(3, generator=torch.Generator().manual_seed(0))
        np.random.default_rng(0).random(3)
        random.Random(0).random()
