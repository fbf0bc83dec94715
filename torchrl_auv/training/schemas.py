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

====================  ==============  =====================================
group                 name            schema
====================  ==============  =====================================
``proposer``          ``diffusion``   :class:`ProposerConfig`
``selection``         ``default``     :class:`SelectionConfig`
``residual``          ``default``     :class:`ResidualConfig`
``replay_buffer``     ``default``     :class:`ReplayBufferConfig`
``env``               ``default``     :class:`EnvConfig`
``env``               ``history``     :class:`HistoryEnvConfig`
``collector``         ``default``     :class:`CollectorConfig`
``optim``             ``sac``         :class:`SACOptimConfig`
``optim``             ``lac``         :class:`LACOptimConfig`
``network``           ``default``     :class:`NetworkConfig`
``network``           ``ensemble``    :class:`EnsembleNetworkConfig`
``lyapunov``          ``default``     :class:`LyapunovConfig`
``advisor``           ``default``     :class:`AdvisorConfig`
``finetune``          ``default``     :class:`FinetuneConfig`
``demonstrations``    ``default``     :class:`DemonstrationsConfig`
``logger``            ``default``     :class:`LoggerConfig`
``checkpoint``        ``default``     :class:`CheckpointConfig`
``checkpoint``        ``learner``     :class:`LearnerCheckpointConfig`
``eval``              ``default``     :class:`EvalConfig`
====================  ==============  =====================================

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
from omegaconf import MISSING

__all__ = [
    "SCHEMAS",
    "AdvisorConfig",
    "CheckpointConfig",
    "CollectorConfig",
    "DemonstrationsConfig",
    "EnsembleNetworkConfig",
    "EnvConfig",
    "EvalConfig",
    "FinetuneConfig",
    "HistoryEnvConfig",
    "LACOptimConfig",
    "LearnerCheckpointConfig",
    "LoggerConfig",
    "LyapunovConfig",
    "NetworkConfig",
    "ProposerConfig",
    "ReplayBufferConfig",
    "ResidualConfig",
    "SACOptimConfig",
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
    dominance: str = "interval"  # interval: min over members > the anchor's max | paired:
    #   every member's advantage over the anchor > margin (SelectionRule)
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


@dataclass
class EnvConfig:
    """The ``env`` group: the training scenes (:func:`~torchrl_auv.training.env_from_config`)."""

    sea_state: str = "ves"  # ideal | es | ves
    controller: str = "s_surface"  # s_surface | pid | smc (the low-level controller)
    rate_model: str = "shannon"  # the acoustic link's rate model
    num_envs: int = 8  # scenes per batch (the proposer and the physics batch across them)
    max_steps: int = 1000  # decisions per episode
    compile_physics: bool = True  # torch.compile of the decision (minutes once per shape)


@dataclass
class HistoryEnvConfig(EnvConfig):
    """``env`` of the diffusion recipes: the proposer's state-action history too."""

    history: int = "${proposer.history}"  # type: ignore[assignment]


@dataclass
class CollectorConfig:
    """The ``collector`` group (:func:`~torchrl_auv.training.collector_from_config`)."""

    total_frames: int = 300_000  # scene-decisions (300 episodes x 1000 decisions)
    frames_per_batch: int = 1000
    init_random_frames: int = 0  # uniform random actions first (recipes with a learner)
    num_workers: int = 1  # > 1: a MultiSyncCollector of this many worker processes
    backend: str = "local"  # local | ray (num_workers remote collectors on a Ray cluster)
    ray_address: str | None = None  # ray: "auto", "host:port", "ray://host:port"; None: local


@dataclass
class SACOptimConfig:
    """The ``optim`` group of the SAC learners (SAC, Diffusion+RL;
    :func:`~torchrl_auv.training.sac_from_config`)."""

    actor_lr: float = 1.0e-4
    critic_lr: float = 1.0e-3
    alpha_lr: float = 3.0e-4  # TorchRL sota SAC's (the paper gives none)
    alpha_init: float = 1.0
    updates_per_batch: int = 250
    gamma: float = 0.99  # Table I: 0.97 (recipes/README.md)
    n_steps: int = 1  # > 1: n-step returns for the Q critics (torchrl_auv.training.NStepReturns)
    critic_cost: str = "task"  # task (the reward) | stability (-stability_cost: [22]'s ablation)
    tau: float = 0.005
    loss_function: str = "smooth_l1"  # the Q loss: smooth_l1 (Huber) | l2
    compile: bool = False  # torch.compile of the update


@dataclass
class LACOptimConfig:
    """The ``optim`` group of the LAC learner (Diffusion+RL (LAC);
    :func:`~torchrl_auv.training.lac_from_config`)."""

    actor_lr: float = 1.0e-4
    critic_lr: float = 1.0e-3
    dual_lr: float = 1.0e-4  # the Lagrange multiplier's
    updates_per_batch: int = 250
    gamma: float = 0.99  # Table I: 0.97 (recipes/README.md)
    tau: float = 0.005
    loss_function: str = "smooth_l1"  # the critics' TD loss: smooth_l1 (Huber) | l2 (the paper)
    compile: bool = False  # torch.compile of the update
    lambda_max: float = 1.0  # the multiplier's cap
    multiplier: str = "dual"  # dual (Adam on log lambda, published) | pid | fixed (lambda_init)
    lambda_init: float = 1.0  # the multiplier's start (fixed: its value; 0 = no constraint)
    pid_gains: list[float] = field(default_factory=lambda: [1.0, 0.01, 0.0])  # kp, ki, kd
    constraint: str = "mean"  # mean: lambda E[dL] (published) | hinge: lambda E[max(0, dL)]
    violation_budget: float | None = None  # pid: error = violation rate - budget (null: E[dL])


@dataclass
class NetworkConfig:
    """The ``network`` group: per-AUV actor and critics (:mod:`~torchrl_auv.training.networks`)."""

    hidden: list[int] = field(default_factory=lambda: [256, 256])
    layer_norm: bool = False  # a LayerNorm in each hidden layer of the critics (RLPD's)


@dataclass
class EnsembleNetworkConfig(NetworkConfig):
    """``network`` of the learners with a Q ensemble (SAC, Diffusion+RL)."""

    critics: int = 2  # Q networks (SAC's twin: 2); the target takes their min


@dataclass
class LyapunovConfig:
    """The ``lyapunov`` group of Diffusion+RL (LAC): the spec before the advisor's first
    consultation (throughout with ``advisor.backend=fixed``) and what the critic learns."""

    form: str = "softplus"  # softplus | squared | log
    stability_weight: float = 0.1  # alpha of the decrease condition
    cost: str = "stability"  # stability (0 in service) | task (the paper's; never vanishes)
    legs: bool = False  # per approach leg: TD ends at service start (L = 0), the loss and the
    #   condition on approach transitions only (needs cost=stability; LyapunovActorCriticLoss)
    filter: str = "off"  # off | rank: the task critic's choice among the candidates that keep
    #   the decrease condition, else the least L | veto: the medoid where it keeps it, else as
    #   rank (LyapunovFilter; needs cost=stability, the candidate backup, the selection)
    inputs: str = "all"  # all | task: the critic reads the task's features only, not the
    #   vehicle's (velocities, rates: waves shake them each decision; make_lyapunov_critic)
    gamma: float | None = None  # the Lyapunov critic's discount (null: optim.gamma); legs end at
    #   service start, so near 1 is well posed and widens where the condition can hold


@dataclass
class AdvisorConfig:
    """The ``advisor`` group of Diffusion+RL (LAC): who picks the Lyapunov spec during training
    (:mod:`torchrl_auv.advisor`)."""

    backend: str = "rules"  # rules | fixed | openai (any OpenAI-compatible endpoint)
    base_url: str = "http://127.0.0.1:8080/v1"
    model: str = "smollm2"
    api_key_env: str = "OPENAI_API_KEY"  # the key is read from this variable, never stored
    cooldown: int = 20_000  # frames between consultations after the start
    window: int = 5  # collected batches the feedback summarises
    task: str = MISSING  # the task's text the advisor reads
    forms: list[str] = field(default_factory=lambda: ["log", "softplus", "squared"])  # rules:
    #   the forms it may pick (drop log where L reaches tens: RuleBasedAdvisor's docstring)
    position_indices: list[int] = field(default_factory=lambda: [0, 1, 2])  # target offset
    velocity_indices: list[int] = field(default_factory=lambda: [23, 24, 25])  # u, v, w


@dataclass
class FinetuneConfig:
    """The ``finetune`` group of Diffusion+RL: the proposer fine-tuned on its own candidates,
    weighted by their Q (:mod:`~torchrl_auv.training.proposer_finetuning`; off by default)."""

    steps: int = 0  # > 0: denoising steps after each batch's updates (needs residual.bound 0)
    batch_size: int = 256  # candidate chunks per step
    lr: float = 1.0e-4
    temperature: float = 1.0  # of the softmax over a state's K candidates (the batch's spread)
    start_frames: int = 5000  # frames before the first step
    demo_fraction: float = 0.0  # share of each step's chunks from the first stage's samples
    demo_samples: int = 50_000  # ... drawn once from its demonstrations and DAgger rounds


@dataclass
class DemonstrationsConfig:
    """The ``demonstrations`` group of SAC: the scripted expert's frames in a buffer of their
    own, half of every batch (RLPD; :mod:`~torchrl_auv.training.demonstration_replay`)."""

    frames: int = 0  # > 0: the expert's scene-decisions; 0: plain SAC


@dataclass
class LoggerConfig:
    """The ``logger`` group: a TorchRL logger (:func:`~torchrl_auv.training.logger_from_config`)."""

    backend: str = "wandb"  # wandb | csv | tensorboard, or empty for none
    offline: bool = True  # wandb: offline (no network, no account)
    project: str = "torchrl-auv"
    exp_name: str = MISSING  # the recipe's name
    group: str | None = None  # wandb group (a sweep sets it to its name)


@dataclass
class CheckpointConfig:
    """The ``checkpoint`` group (:func:`~torchrl_auv.training.make_checkpoint`)."""

    every_frames: int = 20_000
    keep_last: int = 2


@dataclass
class LearnerCheckpointConfig(CheckpointConfig):
    """``checkpoint`` of the recipes with a replay buffer."""

    replay_buffer: bool = False  # also save the buffer (large)


@dataclass
class EvalConfig:
    """The ``eval`` group: the final held-out evaluation and the learning curve
    (:meth:`~torchrl_auv.training.Run.evaluate`)."""

    sea_states: list[str] = field(default_factory=lambda: ["ideal", "es", "ves"])
    seed: int = 100_000  # held out: training scenes use seed, seed + 1, ...
    num_envs: int = 4  # held-out scenes per sea
    steps: int = 1000  # decisions per episode
    workers: int = 2  # rows evaluated side by side in this many processes (the same numbers)
    every_frames: int | None = 25_000  # the curve: at frame 0 and every this many (None: off)
    curve_envs: int = 2  # ... on this many held-out scenes of the training sea
    curve_steps: int = 1000  # ... of this many decisions
    curve_background: bool = True  # the curve's points in a worker process (the same numbers)
    video_steps: int = 0  # > 0: eval_episode.mp4 of this many decisions
    ranks: bool = True  # recipes with a selection: each rank executed alone too (Table II)


#: ``(group, name, schema)`` of every registered schema
SCHEMAS = (
    ("proposer", "diffusion", ProposerConfig),
    ("selection", "default", SelectionConfig),
    ("residual", "default", ResidualConfig),
    ("replay_buffer", "default", ReplayBufferConfig),
    ("env", "default", EnvConfig),
    ("env", "history", HistoryEnvConfig),
    ("collector", "default", CollectorConfig),
    ("optim", "sac", SACOptimConfig),
    ("optim", "lac", LACOptimConfig),
    ("network", "default", NetworkConfig),
    ("network", "ensemble", EnsembleNetworkConfig),
    ("lyapunov", "default", LyapunovConfig),
    ("advisor", "default", AdvisorConfig),
    ("finetune", "default", FinetuneConfig),
    ("demonstrations", "default", DemonstrationsConfig),
    ("logger", "default", LoggerConfig),
    ("checkpoint", "default", CheckpointConfig),
    ("checkpoint", "learner", LearnerCheckpointConfig),
    ("eval", "default", EvalConfig),
)


def register_schemas() -> None:
    """Store every schema of :data:`SCHEMAS` in Hydra's ConfigStore (idempotent): what a recipe
    config's defaults list names, e.g. ``- /proposer@proposer: diffusion``."""
    store = ConfigStore.instance()
    for group, name, schema in SCHEMAS:
        store.store(group=group, name=name, node=schema)
