"""Checks of a recipe's configuration before any work starts: every error names the key.

Examples:
    >>> check_choices({"env": {"sea_state": "calm"}})
    Traceback (most recent call last):
    ...
    ValueError: env.sea_state must be one of ['es', 'ideal', 'ves'], got 'calm'
"""

from __future__ import annotations

import importlib.util
import math
import warnings
from collections.abc import Mapping

from torchrl_auv.control import available_controllers
from torchrl_auv.modules import CANDIDATE_PICKS, SAMPLERS
from torchrl_auv.modules.lyapunov_forms import FORMS
from torchrl_auv.objectives import LR_SCHEDULES
from torchrl_auv.objectives.lyapunov import CONSTRAINTS, MULTIPLIERS
from torchrl_auv.physics.acoustics import RATE_MODELS
from torchrl_auv.physics.ocean import SEA_STATES
from torchrl_auv.training.candidates import check_selection
from torchrl_auv.training.collectors import COLLECTOR_BACKENDS, check_ray_backend
from torchrl_auv.training.networks import LYAPUNOV_INPUTS
from torchrl_auv.training.proposer_finetuning import check_finetune
from torchrl_auv.training.residual import check_residual

__all__ = [
    "LOGGER_BACKENDS",
    "check_choices",
    "check_config",
    "check_endpoint",
    "resolve_config",
]

#: ``logger.backend`` values: TorchRL's ``get_logger`` types this project installs and tests
#: (empty: no logger)
LOGGER_BACKENDS = ("wandb", "csv", "tensorboard", "")

POSITIVE_INTEGERS = (
    "collector.total_frames",
    "collector.frames_per_batch",
    "collector.num_workers",
    "optim.updates_per_batch",
    "env.num_envs",
    "replay_buffer.size",
    "replay_buffer.batch_size",
    "proposer.num_candidates",
    "proposer.alone_candidates",
    "proposer.alone_replan_every",
    "eval.every_frames",
    "eval.workers",
    "eval.curve_envs",
    "eval.curve_steps",
    "network.critics",
)

#: counts that may be zero
NON_NEGATIVE_INTEGERS = (
    "demonstrations.frames",
    "collector.init_random_frames",
    "eval.video_steps",
)


def _choices() -> dict[str, tuple[str, ...]]:
    return {
        "env.sea_state": tuple(sorted(SEA_STATES)),
        "env.controller": available_controllers(),
        "env.rate_model": RATE_MODELS,
        "collector.backend": COLLECTOR_BACKENDS,
        "logger.backend": LOGGER_BACKENDS,
        "replay_buffer.storage": ("memory", "memmap"),
        "advisor.backend": ("rules", "fixed", "openai"),
        "lyapunov.form": tuple(sorted(FORMS)),
        "device": ("cpu", "cuda"),
        "proposer.sampler": SAMPLERS,
        "proposer.alone_pick": CANDIDATE_PICKS,
        "proposer.lr_schedule": LR_SCHEDULES,
        "selection.include_actor": (True, False),
        "eval.ranks": (True, False),
        "eval.curve_background": (True, False),
        "optim.loss_function": ("l2", "smooth_l1"),
        "optim.compile": (True, False),
        "network.layer_norm": (True, False),
        "lyapunov.cost": ("task", "stability"),
        "lyapunov.legs": (True, False),
        "lyapunov.filter": ("off", "rank", "veto"),
        "lyapunov.inputs": LYAPUNOV_INPUTS,
        "optim.multiplier": MULTIPLIERS,
        "optim.constraint": CONSTRAINTS,
        "optim.critic_cost": ("task", "stability"),
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
    for key in NON_NEGATIVE_INTEGERS:
        value = _get(cfg, key)
        if value is not None and (
            isinstance(value, bool) or not isinstance(value, int) or value < 0
        ):
            raise ValueError(f"{key} must be an integer >= 0, got {value!r}")
    selection = _get(cfg, "selection")
    if isinstance(selection, Mapping):
        check_selection(selection)
    residual = _get(cfg, "residual")
    if isinstance(residual, Mapping):
        check_residual(residual, _get(cfg, "proposer.alone_replan_every"))
    weight = _get(cfg, "lyapunov.stability_weight")
    if weight is not None and (
        isinstance(weight, bool)
        or not isinstance(weight, int | float)
        or not (weight > 0 and math.isfinite(weight))
    ):
        raise ValueError(f"lyapunov.stability_weight must be a finite number > 0, got {weight!r}")
    check_lac_values(cfg)
    forms = _get(cfg, "advisor.forms")
    if forms is not None and (not forms or any(f not in FORMS for f in forms)):
        raise ValueError(
            f"advisor.forms must be a non-empty list of {sorted(FORMS)}, got {list(forms)!r}"
        )
    finetune = _get(cfg, "finetune")
    if isinstance(finetune, Mapping):
        check_finetune(finetune)
        if finetune.get("steps") and _get(cfg, "residual.bound"):
            raise ValueError(
                "finetune.steps > 0 fine-tunes the proposer on the selection's candidates: "
                "it needs the selection (residual.bound=0), got residual.bound="
                f"{_get(cfg, 'residual.bound')!r}"
            )
    replan, horizon = _get(cfg, "proposer.alone_replan_every"), _get(cfg, "proposer.horizon")
    if replan is not None and horizon is not None and replan > horizon:
        raise ValueError(
            f"proposer.alone_replan_every must be <= proposer.horizon ({horizon}): "
            f"a plan is one chunk; got {replan}"
        )
    total, random = _get(cfg, "collector.total_frames"), _get(cfg, "collector.init_random_frames")
    if total is not None and random and total <= random:
        warnings.warn(
            f"collector.total_frames ({total}) <= collector.init_random_frames "
            f"({random}): the run collects random actions only and makes no gradient "
            "update",
            stacklevel=2,
        )
    if _get(cfg, "device") == "cuda":
        import torch

        if not torch.cuda.is_available():
            raise ValueError("device is 'cuda' but torch sees no CUDA device; use device=cpu")


def check_lac_values(cfg: Mapping) -> None:
    """The values of the LAC learner that depend on each other: the multiplier's
    (``optim.lambda_init``, ``optim.lambda_max``, ``optim.pid_gains``), ``lyapunov.legs``
    (the stability cost's) and ``lyapunov.filter`` (the stability cost, the candidate backup,
    the anchor for ``veto``, the selection): a ``ValueError`` naming the key."""
    init, cap = _get(cfg, "optim.lambda_init"), _get(cfg, "optim.lambda_max")
    multiplier = _get(cfg, "optim.multiplier")
    for key, value in (("optim.lambda_init", init), ("optim.lambda_max", cap)):
        if value is not None and (
            isinstance(value, bool) or not isinstance(value, int | float) or not value >= 0
        ):
            raise ValueError(f"{key} must be a number >= 0, got {value!r}")
    if multiplier == "dual" and init is not None and not init > 0:
        raise ValueError(f"optim.lambda_init must be > 0 with optim.multiplier=dual, got {init!r}")
    if init is not None and cap is not None and init > cap:
        raise ValueError(f"optim.lambda_init ({init}) must be <= optim.lambda_max ({cap})")
    budget = _get(cfg, "optim.violation_budget")
    if budget is not None:
        if isinstance(budget, bool) or not isinstance(budget, int | float) or not 0 <= budget < 1:
            raise ValueError(f"optim.violation_budget must be null or in [0, 1), got {budget!r}")
        if multiplier not in (None, "pid"):
            raise ValueError(
                "optim.violation_budget sets the PID multiplier's error: it needs "
                f"optim.multiplier=pid, got {multiplier!r}"
            )
    gains = _get(cfg, "optim.pid_gains")
    if gains is not None and (
        len(gains) != 3
        or any(isinstance(g, bool) or not isinstance(g, int | float) or not g >= 0 for g in gains)
    ):
        raise ValueError(f"optim.pid_gains must be three numbers >= 0 (kp, ki, kd), got {gains!r}")
    lyapunov_gamma = _get(cfg, "lyapunov.gamma")
    if lyapunov_gamma is not None and (
        isinstance(lyapunov_gamma, bool)
        or not isinstance(lyapunov_gamma, int | float)
        or not 0 < lyapunov_gamma <= 1
    ):
        raise ValueError(f"lyapunov.gamma must be null or in (0, 1], got {lyapunov_gamma!r}")
    if _get(cfg, "lyapunov.legs") and _get(cfg, "lyapunov.cost") == "task":
        raise ValueError(
            "lyapunov.legs=true ends the Lyapunov critic's TD target at service start, where "
            "only the stability cost is 0: it needs lyapunov.cost=stability, got task"
        )
    mode = _get(cfg, "lyapunov.filter")
    if mode not in (None, "off"):
        needs = {
            "lyapunov.cost": ("stability", "the task critic ranks the feasible candidates"),
            "selection.backup": ("candidates", "the critics bootstrap on the filtered choice"),
        }
        for key, (value, why) in needs.items():
            if _get(cfg, key) not in (None, value):
                raise ValueError(
                    f"lyapunov.filter={mode} needs {key}={value} ({why}), got {_get(cfg, key)!r}"
                )
        if mode == "veto" and _get(cfg, "selection.anchor") is None and _get(cfg, "selection"):
            raise ValueError(
                "lyapunov.filter=veto keeps the medoid where it keeps the decrease condition: "
                "it needs selection.anchor=medoid, got null"
            )
        if _get(cfg, "residual.bound"):
            raise ValueError(
                f"lyapunov.filter={mode} filters the selection's candidates: it needs the "
                f"selection (residual.bound=0), got residual.bound={_get(cfg, 'residual.bound')!r}"
            )


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
    if _get(cfg, "logger.backend") == "wandb" and importlib.util.find_spec("wandb") is None:
        raise ValueError(
            "logger.backend='wandb' needs wandb: pip install 'torchrl-auv[recipes]', "
            "or logger.backend=csv (or empty: no logger)"
        )
    if _get(cfg, "collector.backend") == "ray":
        check_ray_backend(_get(cfg, "collector.ray_address"))
    if _get(cfg, "advisor.backend") == "openai":
        check_endpoint(_get(cfg, "advisor.base_url"), "advisor.base_url")


def check_endpoint(url: object, key: str, timeout_s: float = 5.0) -> None:
    """Raise ``ValueError`` naming ``key`` unless an HTTP server answers at ``url`` (any HTTP
    status counts: the advisor's own requests report authentication and model errors).

    >>> check_endpoint("ftp://x", "advisor.base_url")
    Traceback (most recent call last):
    ...
    ValueError: advisor.base_url must be an http(s) URL, got 'ftp://x'
    """
    import urllib.error
    import urllib.request

    if not isinstance(url, str) or not url.startswith(("http://", "https://")):
        raise ValueError(f"{key} must be an http(s) URL, got {url!r}")
    try:
        urllib.request.urlopen(url.rstrip("/") + "/models", timeout=timeout_s).close()
    except urllib.error.HTTPError:
        return  # the server answered
    except (urllib.error.URLError, OSError) as error:
        reason = getattr(error, "reason", error)
        raise ValueError(
            f"{key} {url} does not answer ({reason}): start the server, or use "
            "advisor.backend=rules (the offline advisor)"
        ) from None
