"""The first stage of the diffusion recipes: expert demonstrations, proposer pretraining and
DAgger rounds, one cached artefact per set of values (paper §III-A, §IV-B, Fig. 4).

Every diffusion recipe (``diffusion``, ``diffusion_rl``, ``diffusion_lac``) and every sweep job
starts from a pretrained :class:`~torchrl_auv.modules.DiffusionProposer`. It is built in
three steps:

1. **Demonstrations**: the scripted expert in ``demo_batches`` batches of ``demo_episodes``
   scenes of ``demo_steps`` decisions (``demo_workers`` processes).
2. **Pretraining** on them (behaviour cloning: the denoising loss, ``pretrain_steps``).
3. **DAgger** (Ross, Gordon and Bagnell 2011), ``dagger_rounds`` times: the proposer acts
   alone (the medoid of K = 5 candidates, ``dagger_inference_steps`` DDIM steps) in
   ``dagger_batches`` batches of new scenes, the expert labels every state it visits (the
   expert decides from the observation alone, so it can label any state), the samples join
   the data and the proposer is trained on the whole for ``dagger_steps`` more steps at
   ``dagger_lr``. Behaviour cloning alone sees only the expert's states; a proposer that
   strays from them in a 1 m/s current meets states it was never shown how to recover from
   and drifts out of the area (measured in ``recipes/README.md``).

The artefact is keyed by everything that shapes its weights (:func:`first_stage_values`: sea
state, controller, rate model, seed, the demonstrations, the noise model, the pretraining and
the DAgger rounds) and lives in ``proposer.cache_dir`` (default ``${run_root}/first_stage``)
under ``<sea>-<controller>-<rate model>-seed<seed>-<hash>``
(:class:`~torchrl_auv.training.first_stage.ArtefactCache`): jobs with the same values reuse
it in seconds, other values build their own, a folder whose stored values differ is refused.
The acting values (``num_candidates``, ``num_inference_steps``, ``sampler``, ``compile``, and
the recipes' ``alone_pick``) do not change the weights and are applied after loading, so a
sweep over them shares one artefact.

The folder holds ``proposer.pt`` (final), ``proposer_bc.pt`` (after pretraining, before
DAgger, when there are rounds), ``demonstrations/`` and ``dagger<r>/`` (TorchRL replay-buffer
storage), ``pretrain_loss.csv`` (the training and held-out denoising loss against the
optimiser step, per phase: the paper's Fig. 4; the held-out samples are whole scenes),
``loss.png`` when a plot function is given, ``metrics.json`` (sample counts, losses, wall
times) and ``values.json``.

A build cut short (a kill, the end of a sitting) goes on from its last finished phase the next
time the same values are asked for: the saved demonstrations and DAgger samples are read back
instead of collected and the proposer after each finished training phase is loaded instead of
trained again; every phase draws from its own seeds, so the artefact is the one an
uninterrupted build writes (tested bit for bit).

Examples:
    >>> values = first_stage_values({"seed": 0, "env": {"controller": "pid",
    ...     "rate_model": "paper"}, "proposer": {"demo_sea_state": "es"}})
    >>> values["sea_state"], values["controller"], values["rate_model"], values["seed"]
    ('es', 'pid', 'paper', 0)
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import torch
from omegaconf import DictConfig, OmegaConf

from torchrl_auv.envs.data_collection import AGENT_OBSERVATION_FEATURES
from torchrl_auv.modules import DiffusionProposer
from torchrl_auv.training.first_stage.artefacts import VALUES_FILE, ArtefactCache, check_values
from torchrl_auv.training.first_stage.build import build_first_stage
from torchrl_auv.training.schemas import ProposerConfig

__all__ = [
    "FIRST_STAGE_DEFAULTS",
    "FIRST_STAGE_VERSION",
    "FirstStage",
    "build_first_stage",
    "first_stage_frames",
    "first_stage_from_config",
    "first_stage_values",
    "proposer_from_config",
]

log = logging.getLogger(__name__)

#: the run summary's line for :func:`first_stage_frames`
FIRST_STAGE_FRAMES_FACT = "first-stage frames (offline: demonstrations and DAgger)"

#: Bumped whenever the way a first stage is built changes: older artefacts are then rebuilt.
FIRST_STAGE_VERSION = 4  # 4: task v3 (the 38-feature observation with the delivery age)

#: The ``proposer`` keys a first stage is keyed by (:func:`first_stage_values`), by section.
FIRST_STAGE_SECTIONS = {
    "demonstrations": ("demo_batches", "demo_episodes", "demo_steps", "horizon", "history"),
    "model": ("noise_model", "hidden", "cond_dim", "depth", "schedule", "num_train_steps"),
    "pretraining": (
        "pretrain_steps",
        "batch_size",
        "lr",
        "lr_schedule",
        "weight_decay",
        "ema_decay",
        "normalize_state",
        "heldout_fraction",
    ),
    "dagger": (
        "dagger_rounds",
        "dagger_batches",
        "dagger_inference_steps",
        "dagger_steps",
        "dagger_lr",
    ),
}
FIRST_STAGE_KEYS = tuple(key for keys in FIRST_STAGE_SECTIONS.values() for key in keys)
#: The acting keys, applied to a loaded proposer (they do not change its weights).
ACTING_KEYS = ("num_candidates", "num_inference_steps", "sampler", "compile")


def _schema_defaults(keys: tuple[str, ...]) -> dict:
    """The :class:`~torchrl_auv.training.ProposerConfig` defaults of ``keys`` (the one
    definition of the group's values; ``dagger_rounds``, an interpolation there, is resolved
    per sea by :func:`first_stage_values`)."""
    schema = ProposerConfig()
    return {k: getattr(schema, k) for k in keys if k != "dagger_rounds"}


#: What a config without one of :data:`FIRST_STAGE_KEYS` gets: the schema's value (the paper
#: preset's).
FIRST_STAGE_DEFAULTS = _schema_defaults(FIRST_STAGE_KEYS)
#: ... and without one of :data:`ACTING_KEYS`.
ACTING_DEFAULTS = _schema_defaults(ACTING_KEYS)


def _plain(cfg) -> dict:
    if isinstance(cfg, DictConfig):
        return OmegaConf.to_container(cfg, resolve=True)
    return dict(cfg)


#: First-stage keys that must be ints >= 1, and those that may be 0.
_COUNTS = (
    "demo_batches",
    "demo_episodes",
    "demo_steps",
    "horizon",
    "hidden",
    "cond_dim",
    "depth",
    "num_train_steps",
    "pretrain_steps",
    "batch_size",
    "dagger_batches",
    "dagger_inference_steps",
    "dagger_steps",
)
_COUNTS_OR_ZERO = ("history", "dagger_rounds")


def _check(p: Mapping) -> None:
    """Raise ``ValueError`` naming ``proposer.<key>`` for a first-stage value out of range."""
    for key in _COUNTS + _COUNTS_OR_ZERO:
        low = 0 if key in _COUNTS_OR_ZERO else 1
        value = p[key]
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            raise ValueError(f"proposer.{key} must be an int >= {low}, got {value!r}")
    for key in ("lr", "dagger_lr"):
        if not (isinstance(p[key], int | float) and p[key] > 0):
            raise ValueError(f"proposer.{key} must be a number > 0, got {p[key]!r}")
    if not 0.0 <= p["heldout_fraction"] < 1.0:
        raise ValueError(
            f"proposer.heldout_fraction must be in [0, 1), got {p['heldout_fraction']!r}"
        )


def first_stage_values(cfg: Mapping | DictConfig) -> dict:
    """What a first stage is keyed by, from a recipe config (``seed``, ``env.controller``,
    ``env.rate_model`` and the ``proposer`` group; missing keys take
    :data:`FIRST_STAGE_DEFAULTS`, a missing ``dagger_rounds`` the schema's rounds for the
    demonstrations' sea): a JSON-able dict, hashed for the artefact's folder."""
    cfg = _plain(cfg)
    env = cfg.get("env", {})
    p = {**FIRST_STAGE_DEFAULTS, **cfg.get("proposer", {})}
    sea = p.get("demo_sea_state") or env.get("sea_state", "ideal")
    if "dagger_rounds" not in p:  # the schema's rounds for the demonstrations' sea
        per_sea = p.get("dagger_rounds_per_sea") or ProposerConfig().dagger_rounds_per_sea
        if sea not in per_sea:
            raise ValueError(
                f"proposer.dagger_rounds_per_sea has no entry for the sea {sea!r} "
                f"(it has {sorted(per_sea)}): add one, or set proposer.dagger_rounds"
            )
        p["dagger_rounds"] = per_sea[sea]
    _check(p)
    return {
        "version": FIRST_STAGE_VERSION,
        "sea_state": sea,
        "controller": env.get("controller", "s_surface"),
        "rate_model": env.get("rate_model", "shannon"),
        "seed": int(cfg.get("seed", 0)),
        **{section: {k: p[k] for k in keys} for section, keys in FIRST_STAGE_SECTIONS.items()},
    }


def first_stage_frames(values: Mapping) -> int:
    """The env frames (scene-decisions) a first stage collects offline, from its
    :func:`first_stage_values`: the expert's demonstrations and the DAgger rounds,
    ``(demo_batches + dagger_rounds * dagger_batches) * demo_episodes * demo_steps`` (a budget:
    each scene counts its ``demo_steps`` decisions). Learning curves of the diffusion recipes
    start after them; a plot against SAC's frames should add them.

    >>> first_stage_frames(first_stage_values({"proposer": {
    ...     "demo_batches": 2, "demo_episodes": 48, "demo_steps": 1000,
    ...     "dagger_rounds": 1, "dagger_batches": 2}}))
    192000
    """
    demo, dagger = values["demonstrations"], values["dagger"]
    batches = demo["demo_batches"] + dagger["dagger_rounds"] * dagger["dagger_batches"]
    return int(batches * demo["demo_episodes"] * demo["demo_steps"])


@dataclass
class FirstStage:
    """A loaded first stage: the proposer, its folder (``None`` for a bare ``proposer.path``
    file), whether this call built it, and facts for a run's summary."""

    proposer: DiffusionProposer
    folder: Path | None
    built: bool
    facts: dict = field(default_factory=dict)


def _check_structure(proposer: DiffusionProposer, p: Mapping, source: Path) -> None:
    """Refuse a loaded proposer whose shape does not fit the config: its plan ``horizon``, and
    its conditioning size (the data-collection observation plus ``history`` observation-action
    pairs), naming the key."""
    horizon = p.get("horizon", FIRST_STAGE_DEFAULTS["horizon"])
    if proposer.horizon != horizon:
        raise ValueError(
            f"proposer.horizon is {horizon} but {source} plans {proposer.horizon} decisions "
            "ahead: set proposer.horizon to match, or use another proposer"
        )
    history = p.get("history", FIRST_STAGE_DEFAULTS["history"])
    obs, act = len(AGENT_OBSERVATION_FEATURES), proposer.action_dim
    expected = DiffusionProposer.conditioning_dim(obs, act, history)
    if proposer.state_dim != expected:
        raise ValueError(
            f"{source} conditions on {proposer.state_dim} features, but the data-collection "
            f"observation ({obs}) with proposer.history={history} pairs gives {expected}: "
            "set proposer.history to the proposer's, or use a proposer made for this env"
        )


def _apply_acting(proposer: DiffusionProposer, p: Mapping) -> DiffusionProposer:
    acting = {**ACTING_DEFAULTS, **{k: p[k] for k in ACTING_DEFAULTS if k in p}}
    proposer.configure_sampling(
        num_candidates=acting["num_candidates"],
        num_inference_steps=acting["num_inference_steps"],
        sampler=acting["sampler"],
    )
    proposer.compile = bool(acting["compile"])
    return proposer


def first_stage_from_config(
    cfg: Mapping | DictConfig, *, plot_loss: Callable | None = None
) -> FirstStage:
    """The recipes' first stage: ``proposer.path`` when given (a file; next to a
    ``values.json`` its values must match the config's, else it is refused naming the keys),
    else the cached artefact of :func:`first_stage_values` under ``proposer.cache_dir``, built
    if missing (``proposer.demo_workers`` collection processes). The acting keys are applied
    to the loaded proposer; one whose horizon or conditioning size does not fit the config is
    refused, naming the key."""
    plain = _plain(cfg)
    p = plain.get("proposer", {})
    values = first_stage_values(plain)
    path = p.get("path")
    if path:
        path = Path(path)
        if not path.exists():
            raise FileNotFoundError(f"proposer.path {path} does not exist")
        if (path.parent / VALUES_FILE).exists():
            check_values(path.parent, values)
        else:
            log.warning(
                "proposer.path %s has no %s beside it: its first-stage values cannot "
                "be checked against this config",
                path,
                VALUES_FILE,
            )
        proposer = DiffusionProposer.load(path)
        _check_structure(proposer, p, path)
        proposer = _apply_acting(proposer, p)
        return FirstStage(
            proposer,
            None,
            False,
            {"first stage": f"{path} (proposer.path)", FIRST_STAGE_FRAMES_FACT: "unknown"},
        )
    cache = ArtefactCache(p.get("cache_dir") or "runs/first_stage")
    name = (
        f"{values['sea_state']}-{values['controller']}-{values['rate_model']}-seed{values['seed']}"
    )
    start = time.perf_counter()
    # building draws from torch's global RNG: fork it, so that a run that builds its first
    # stage and one that reuses it continue from the same random state (the same numbers)
    with torch.random.fork_rng():
        folder, built = cache.get_or_build(
            name,
            values,
            lambda into: build_first_stage(
                into, values, workers=int(p.get("demo_workers", 1)), plot_loss=plot_loss
            ),
            resumable=True,  # a build cut short goes on from its last finished phase
        )
    seconds = time.perf_counter() - start
    proposer = _apply_acting(DiffusionProposer.load(folder / "proposer.pt"), p)
    metrics = json.loads((folder / "metrics.json").read_text())
    facts = {
        "first stage": f"{folder} ({'built' if built else 'reused'} in {seconds:.0f} s)",
        "first stage held-out denoising loss": metrics["heldout_loss"],
        "demonstration samples": metrics["samples"],
        FIRST_STAGE_FRAMES_FACT: first_stage_frames(values),
    }
    return FirstStage(proposer, folder, built, facts)


def proposer_from_config(cfg, *, plot_loss=None) -> DiffusionProposer:
    """The pretrained proposer of a recipe config: the proposer of
    :func:`first_stage_from_config` (cached artefact, or ``proposer.path``), with the config's
    acting values (``proposer.compile`` included)."""
    return first_stage_from_config(cfg, plot_loss=plot_loss).proposer
