"""Checks of a recipe's configuration before any work starts: every error names the key.

Examples:
    >>> check_choices({"env": {"sea_state": "calm"}})
    Traceback (most recent call last):
    ...
    ValueError: env.sea_state must be one of ['es', 'ideal', 'ves'], got 'calm'
"""

from __future__ import annotations

from collections.abc import Mapping

from torchrl_auv.control import available_controllers
from torchrl_auv.physics.acoustics import RATE_MODELS
from torchrl_auv.physics.ocean import SEA_STATES

__all__ = ["COLLECTOR_BACKENDS", "check_choices"]

#: Collector backends a recipe accepts (more arrive with the scale-out recipes).
COLLECTOR_BACKENDS = ("single",)
POSITIVE_INTEGERS = (
    "collector.total_frames",
    "collector.frames_per_batch",
    "collector.num_workers",
    "env.num_envs",
    "replay_buffer.size",
    "replay_buffer.batch_size",
)


def _choices() -> dict[str, tuple[str, ...]]:
    return {
        "env.sea_state": tuple(sorted(SEA_STATES)),
        "env.controller": available_controllers(),
        "env.rate_model": RATE_MODELS,
        "collector.backend": COLLECTOR_BACKENDS,
        "replay_buffer.storage": ("memory", "memmap"),
        "device": ("cpu", "cuda"),
    }


def _get(cfg: Mapping, dotted: str):
    node = cfg
    for part in dotted.split("."):
        if not isinstance(node, Mapping) or part not in node:
            return None
        node = node[part]
    return node


def check_choices(cfg: Mapping) -> None:
    """Raise ``ValueError`` naming the first key whose value is not one of its choices
    (keys absent from ``cfg`` are skipped), or whose number is out of range."""
    for key, choices in _choices().items():
        value = _get(cfg, key)
        if value is not None and value not in choices:
            raise ValueError(f"{key} must be one of {sorted(choices)}, got {value!r}")
    eval_seas = _get(cfg, "eval.sea_states") or ()
    for sea in eval_seas:
        if sea not in SEA_STATES:
            raise ValueError(f"eval.sea_states must be in {sorted(SEA_STATES)}, got {sea!r}")
    for key in POSITIVE_INTEGERS:
        value = _get(cfg, key)
        if value is not None and (not isinstance(value, int) or value < 1):
            raise ValueError(f"{key} must be an integer >= 1, got {value!r}")
    workers = _get(cfg, "collector.num_workers")
    if workers not in (None, 1):
        raise ValueError(
            f"collector.num_workers must be 1 with the 'single' backend, got {workers}"
        )
    if _get(cfg, "device") == "cuda":
        import torch

        if not torch.cuda.is_available():
            raise ValueError("device is 'cuda' but torch sees no CUDA device; use device=cpu")
