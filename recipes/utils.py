"""Small factories shared by the recipes: threads, seeding, loggers."""

from __future__ import annotations

import logging
import os
import random
from typing import Any

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


def make_logger(cfg: Any, run_dir: os.PathLike[str] | str):
    """A TorchRL logger from the ``logger`` config group (wandb offline by default).

    ``cfg.backend`` is any of TorchRL's logger types (``wandb``, ``csv``, ``tensorboard``, ...)
    or empty for no logger. The logger writes its files under ``run_dir`` (its log_dir).
    """
    from torchrl.record.loggers import get_logger

    if not cfg.backend:
        return None
    kwargs: dict[str, Any] = {}
    if cfg.backend == "wandb":
        kwargs["wandb_kwargs"] = {
            "offline": cfg.mode == "offline",
            "project": cfg.project,
            "config": dict(cfg.get("config", {}) or {}),
        }
    return get_logger(cfg.backend, logger_name=str(run_dir), experiment_name=cfg.exp_name, **kwargs)
