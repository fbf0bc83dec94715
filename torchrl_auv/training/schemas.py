"""Typed schemas of the recipes' config groups, registered with Hydra's ConfigStore.

A recipe config names a schema in its defaults list and sets only what its preset changes::

    defaults:
      - /proposer@proposer: diffusion   # ProposerConfig, the paper preset's values
      - _self_
    proposer:
      compile: true

Hydra then checks every value's type when the config is composed (``proposer.hidden=abc`` is
refused naming ``proposer.hidden``), refuses a key the schema lacks (a typo), and each recipe
shares one definition instead of a copy of the group. Ranges are checked where a builder reads
the group (e.g. :func:`~torchrl_auv.training.first_stage_values`).

==================  ==============  =====================================================
group               name            schema
==================  ==============  =====================================================
``proposer``        ``diffusion``   :class:`ProposerConfig`
``selection``       ``default``     :class:`SelectionConfig`
``residual``        ``default``     :class:`ResidualConfig`
``replay_buffer``   ``default``     :class:`ReplayBufferConfig`
==================  ==============  =====================================================

Examples:
    >>> from omegaconf import OmegaConf
    >>> cfg = OmegaConf.structured(ProposerConfig)
    >>> cfg.num_candidates, cfg.history
    (5, 10)
    >>> cfg.hidden = "wide"
    Traceback (most recent call last):
    ...
    omegaconf.errors.ValidationError: Value 'wide' of type 'str' could not be converted to Integer
        full_key: hidden
        object_type=ProposerConfig
"""

from __future__ import annotations

from dataclasses import dataclass, field

from hydra.core.config_store import ConfigStore

__all__ = [
    "SCHEMAS",
    "ProposerConfig",
    "ReplayBufferConfig",
    "ResidualConfig",
    "SelectionConfig",
    "register_schemas",
]


def _dagger_rounds_per_sea() -> dict[str, int]:
    # in a current, behaviour cloning alone drifts out of the area (es, ves); in still water it
    # does not, and a DAgger round cut the SSN to ~55 % of the expert's (recipes/README.md)
    return {"ideal": 0, "es": 1, "ves": 1}


@dataclass
class ProposerConfig:
    """The ``proposer`` group of the diffusion recipes: the first stage that pretrains the
    diffusion proposer (the scripted expert's demonstrations, pretraining, DAgger rounds; the
    values its cached artefact is keyed by) and how the loaded proposer acts. The values are the
    paper preset's; where they depart from the paper's Table I the reason is in
    ``recipes/README.md``.
    """

    # where the proposer comes from
    path: str | None = None  # a proposer.pt to reuse (its values.json must match); None: cached
    cache_dir: str = "${run_root}/first_stage"  # one artefact per set of first-stage values
    # acting: applied to the loaded proposer, not part of the first stage's key
    num_candidates: int = 5  # K candidate chunks per AUV and decision
    num_inference_steps: int = 50  # denoising steps per sample
    sampler: str = "ddpm"  # ddpm (the paper) | ddim (deterministic, better with few steps)
    compile: bool = False  # torch.compile of the denoising step
    alone_pick: str = "medoid"  # the proposer alone executes this candidate: medoid | first
    alone_candidates: int | None = 10  # ... of this many draws (None: num_candidates)
    alone_replan_every: int = 1  # decisions per plan (1: re-plan every decision)
    # first stage: the scripted expert's demonstrations
    demo_sea_state: str = "${env.sea_state}"
    demo_batches: int = 2  # batches of demo_episodes scenes
    demo_episodes: int = 48  # scenes per batch (one env batch; one batch per worker)
    demo_steps: int = 1000  # decisions per scene
    demo_workers: int = 2  # collection processes (the data do not depend on it)
    horizon: int = 8  # decisions per proposed chunk
    history: int = 10  # state-action pairs conditioned on (Table I: L = 10)
    # first stage: noise model and pretraining
    noise_model: str = "mlp"  # mlp | unet
    hidden: int = 256  # Table I: 256
    cond_dim: int = 128  # width of the state encoder
    depth: int = 3
    schedule: str = "linear"  # Table I: linear 1e-4 -> 0.02 over T = 1000
    num_train_steps: int = 1000
    pretrain_steps: int = 10000
    batch_size: int = 256  # Table I: 32
    lr: float = 1.0e-3  # Table I: 1e-4; annealed by lr_schedule
    lr_schedule: str = "cosine"  # constant | cosine (to 0 over pretrain_steps)
    weight_decay: float = 0.0
    ema_decay: float | None = None  # e.g. 0.999: sample from an EMA of the weights
    normalize_state: bool = True  # standardise the conditioning state on the demonstrations
    heldout_fraction: float = 0.1  # of the scenes, kept out for the held-out loss curve
    # first stage: DAgger (the proposer acts alone on new scenes, the expert labels them)
    dagger_rounds: int = "${.dagger_rounds_per_sea.${.demo_sea_state}}"  # type: ignore[assignment]
    dagger_rounds_per_sea: dict[str, int] = field(default_factory=_dagger_rounds_per_sea)
    dagger_batches: int = 2  # batches of demo_episodes scenes per round
    dagger_inference_steps: int = 10  # DDIM steps of the acting proposer while collecting
    dagger_steps: int = 4000  # training steps on demonstrations + DAgger samples per round
    dagger_lr: float = 3.0e-4  # fine-tuning from the pretrained weights (cosine to 0)


@dataclass
class SelectionConfig:
    """The ``selection`` group of Diffusion+RL and Diffusion+RL (LAC): which of the proposer's
    K candidates is executed, and what the critics bootstrap on
    (:func:`~torchrl_auv.training.selection_rule_from_config`,
    :func:`~torchrl_auv.training.selection_backup`; ``recipes/README.md``, "The RL stage that
    acts")."""

    include_actor: bool = False  # the actor's own action competes with the K candidates
    backup: str = "candidates"  # candidates (the candidate executed at s') | actor (published)
    anchor: str | None = "medoid"  # medoid: the prior's choice unless beaten | None: the best
    margin: float = 0.0  # ... by more than the ensemble's disagreement plus this (critic units)
    warmup_frames: int = 5000  # frames executing the anchor while the critics learn its values


@dataclass
class ResidualConfig:
    """The ``residual`` group of the same recipes: with ``bound > 0`` the executed learner is a
    residual actor on the proposer alone's action instead of the selection
    (:mod:`~torchrl_auv.training.residual`)."""

    bound: float = 0.0  # > 0: the residual's bound (action units); 0: the selection acts
    coef: float = 1.0  # weight of the pull toward the prior: coef x (residual / bound)^2


@dataclass
class ReplayBufferConfig:
    """The ``replay_buffer`` group of the RL recipes
    (:func:`~torchrl_auv.training.buffer_from_config`)."""

    size: int = 1_000_000  # transitions kept
    batch_size: int = 64  # transitions per gradient step (Table I)
    storage: str = "memory"  # memory | memmap (under run_dir/replay)


#: ``(group, name, schema)`` of every registered schema
SCHEMAS = (
    ("proposer", "diffusion", ProposerConfig),
    ("selection", "default", SelectionConfig),
    ("residual", "default", ResidualConfig),
    ("replay_buffer", "default", ReplayBufferConfig),
)


def register_schemas() -> None:
    """Store every schema of :data:`SCHEMAS` in Hydra's ConfigStore (idempotent): what a recipe
    config's defaults list names, e.g. ``- /proposer@proposer: diffusion``."""
    store = ConfigStore.instance()
    for group, name, schema in SCHEMAS:
        store.store(group=group, name=name, node=schema)
