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
from torchrl_auv.modules import CANDIDATE_PICKS, SAMPLERS
from torchrl_auv.objectives import LR_SCHEDULES
from torchrl_auv.objectives.lyapunov_forms import FORMS
from torchrl_auv.physics.acoustics import RATE_MODELS
from torchrl_auv.physics.ocean import SEA_STATES
from torchrl_auv.training.collectors import COLLECTOR_BACKENDS, check_ray_backend

__all__ = ["check_choices", "check_config", "resolve_config"]

POSITIVE_INTEGERS = (
    "collector.total_frames",
    "collector.frames_per_batch",
    "collector.num_workers",
    "env.num_envs",
    "replay_buffer.size",
    "replay_buffer.batch_size",
    "proposer.num_candidates",
    "proposer.alone_candidates",
    "proposer.alone_replan_every",
    "eval.every_frames",
    "eval.curve_envs",
    "eval.curve_steps",
)


def _choices() -> dict[str, tuple[str, ...]]:
    return {
        "env.sea_state": tuple(sorted(SEA_STATES)),
        "env.controller": available_controllers(),
        "env.rate_model": RATE_MODELS,
        "collector.backend": COLLECTOR_BACKENDS,
        "replay_buffer.storage": ("memory", "memmap"),
        "advisor.backend": ("rules", "fixed", "openai"),
        "advisor.form": tuple(sorted(FORMS)),
        "device": ("cpu", "cuda"),
        "proposer.sampler": SAMPLERS,
        "proposer.alone_pick": CANDIDATE_PICKS,
        "proposer.lr_schedule": LR_SCHEDULES,
        "selection.include_actor": (True, False),
        "eval.ranks": (True, False),
        "optim.loss_function": ("l2", "smooth_l1"),
        "lyapunov.cost": ("task", "stability"),
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
    replan, horizon = _get(cfg, "proposer.alone_replan_every"), _get(cfg, "proposer.horizon")
    if replan is not None and horizon is not None and replan > horizon:
        raise ValueError(f"proposer.alone_replan_every must be <= proposer.horizon ({horizon}): "
                         f"a plan is one chunk; got {replan}")  # fmt: skip
    if _get(cfg, "device") == "cuda":
        import torch

        if not torch.cuda.is_available():
            raise ValueError("device is 'cuda' but torch sees no CUDA device; use device=cpu")


def resolve_config(cfg) -> dict:
    """``cfg`` (an OmegaConf config) as a resolved dict. Where an interpolation fails, the
    choice keys that do resolve are checked first, so an unknown value another key is looked
    up by (``env.sea_state=calm`` under ``proposer.dagger_rounds_per_sea``) is named as such.

    Examples:
        >>> from omegaconf import OmegaConf
        >>> resolve_config(OmegaConf.create({"env": {"sea_state": "calm"},
        ...                                  "n": "${by_sea.${env.sea_state}}", "by_sea": {}}))
        Traceback (most recent call last):
        ...
        ValueError: env.sea_state must be one of ['es', 'ideal', 'ves'], got 'calm'
    """
    from omegaconf import OmegaConf
    from omegaconf.errors import InterpolationResolutionError

    try:
        return OmegaConf.to_container(cfg, resolve=True)
    except InterpolationResolutionError:
        chosen: dict = {}
        for key in _choices():
            value = OmegaConf.select(cfg, key, default=None, throw_on_resolution_failure=False)
            if value is not None:
                section, name = key.rsplit(".", 1) if "." in key else ("", key)
                node = chosen
                for part in filter(None, section.split(".")):
                    node = node.setdefault(part, {})
                node[name] = value
        check_choices(chosen)
        raise


def check_config(cfg: Mapping) -> None:
    """:func:`check_choices`, and with ``collector.backend`` ``"ray"`` that Ray is installed
    and ``collector.ray_address`` (else ``RAY_ADDRESS``) answers: what a recipe checks before
    any work, and a sweep before its first job."""
    check_choices(cfg)
    if _get(cfg, "collector.backend") == "ray":
        check_ray_backend(_get(cfg, "collector.ray_address"))
