"""Threads and seeds of a run: one place that pins torch's threads and seeds every RNG.

Examples:
    >>> import random, torch
    >>> seed_everything(7)
    >>> a = (random.random(), torch.rand(1).item())
    >>> seed_everything(7)
    >>> a == (random.random(), torch.rand(1).item())
    True
"""

from __future__ import annotations

import os
import random

import numpy as np
import torch

__all__ = ["configure_threads", "seed_everything"]


def configure_threads(num_threads: int = 1) -> None:
    """Pin torch's intra-op threads (default 1) and ``OMP_NUM_THREADS`` for child processes.

    On the 2-core machines this project is developed on, two torch threads made small batched
    ops 4-50x slower than one, so recipes default to one; raise it on larger machines.
    """
    if isinstance(num_threads, bool) or not isinstance(num_threads, int) or num_threads < 1:
        raise ValueError(f"num_threads must be an int >= 1, got {num_threads!r}")
    os.environ["OMP_NUM_THREADS"] = str(num_threads)
    torch.set_num_threads(num_threads)


def seed_everything(seed: int) -> None:
    """Seed python's, numpy's legacy and torch's global RNGs with ``seed`` (an int >= 0).

    Every recipe calls this once before building anything; components that own a generator
    (the env, the proposer's sampling) are seeded from their own arguments.
    """
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed must be an int >= 0, got {seed!r}")
    random.seed(seed)
    np.random.seed(seed % 2**32)  # noqa: NPY002 - the legacy global RNG, seeded on purpose
    torch.manual_seed(seed)
