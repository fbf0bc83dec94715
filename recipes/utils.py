"""Small helpers of the command-line recipes: threads and seeding."""

from __future__ import annotations

import logging
import os
import random

import numpy as np
import torch

log = logging.getLogger(__name__)


def configure_threads(num_threads: int = 1) -> None:
    """Pin torch's intra-op threads (default 1).

    On the 2-core machines this project is developed on, two torch threads made small batched
    ops 4-50x slower than one, so recipes default to one; raise it on larger machines.
    """
    if num_threads < 1:
        raise ValueError(f"num_threads must be >= 1, got {num_threads}")
    os.environ["OMP_NUM_THREADS"] = str(num_threads)
    torch.set_num_threads(num_threads)


def seed_everything(seed: int) -> torch.Generator:
    """Seed python, numpy and torch's global RNGs; return a fresh generator for the recipe."""
    random.seed(seed)
    np.random.seed(seed % 2**32)  # noqa: NPY002 - recipes seed the legacy global RNG on purpose
    torch.manual_seed(seed)
    return torch.Generator().manual_seed(seed)
