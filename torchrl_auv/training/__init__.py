"""What the training recipes share and users import: one file per thing a recipe builds, and
two subpackages, the first stage and the run's lifecycle.

==========================  ========================================================================
module                      builds
==========================  ========================================================================
``env``                     the run's envs from ``cfg.env``: training scenes, worker factories,
                            held-out evaluation scenes (``env.history``: the proposer's history)
``networks``                per-AUV actor, Q critic, Lyapunov critic (weights shared by the AUVs)
``sac``                     SAC's learner: ``SACLoss``, target updater, optimisers, logged keys
``lac``                     LAC's learner: ``LyapunovActorCriticLoss``, target updater, optimisers
``learner``                 :class:`Learner`, what one gradient step touches
``first_stage/``            the pretrained proposer (cached artefact per first-stage values):
                            config, build, artefact cache
``selection``               the proposer + selector policy, ranked candidates, the evaluation rows
``candidates``              the selection rule of ``cfg.selection``, the next state's candidates the
                            critics' candidate backup reads
``residual``                the executed learner: a bounded residual actor on the prior's choice
``proposer_finetuning``     the proposer fine-tuned on its own candidates, weighted by the critic
``replay``                  the replay buffer and what it stores of a frame
``n_step``                  n-step returns for the Q critics (TorchRL's ``MultiStepTransform``)
``demonstration_replay``    SAC's expert demonstrations, half of each batch (RLPD)
``collectors``              TorchRL collectors: local, worker processes, Ray
``run/``                    :class:`Run` and what it owns: folder and its lock, logger, checkpoints,
                            counters (:class:`Progress`), the loop's bookkeeping, summary, video
(re-exported)               held-out evaluation (:mod:`torchrl_auv.evaluation`, its own layer)
==========================  ========================================================================

``recipes/<name>/train.py`` are short scripts composed from these pieces (the loop written
out, as in TorchRL's sota-implementations); copy one and swap a piece to build your own.

This layer needs the ``recipes`` extra (hydra-core, tqdm; ``pip install
'torchrl-auv[recipes]'``): importing it without says so.
"""

from __future__ import annotations

from torchrl_auv.evaluation import (
    POLICIES,
    SameRowAs,
    episode_stats,
    evaluate,
    exit_policy,
    expert_policy,
    make_policy,
    random_policy,
    reference_policies,
)
from torchrl_auv.training._extra import RECIPES_PACKAGES  # first: names the extra if missing
from torchrl_auv.training.candidates import (
    CANDIDATE_KEYS,
    CANDIDATES,
    NEXT_ANCHOR,
    NEXT_CANDIDATES,
    check_selection,
    next_state_values,
    selection_backup,
    selection_rule_from_config,
    start_deviating,
    with_next_candidates,
)
from torchrl_auv.training.collectors import (
    COLLECTOR_BACKENDS,
    check_ray_address,
    check_ray_backend,
    collector_from_config,
    make_collector,
)
from torchrl_auv.training.config import check_choices, check_config, check_endpoint
from torchrl_auv.training.demonstration_replay import (
    DEMONSTRATION_SEED_OFFSET,
    collect_demonstrations,
    demonstration_frames,
    sampler_from_config,
    symmetric_sampler,
)
from torchrl_auv.training.env import (
    env_factory,
    env_from_config,
    env_history,
    held_out_env,
    make_env,
    make_history_env,
)
from torchrl_auv.training.first_stage import (
    FIRST_STAGE_VERSION,
    ArtefactCache,
    FirstStage,
    build_first_stage,
    first_stage_frames,
    first_stage_from_config,
    first_stage_values,
    proposer_from_config,
    values_key,
)
from torchrl_auv.training.keys import (
    ACTION,
    ACTOR_ACTION,
    AGENTS,
    LYAPUNOV_RAW,
    OBSERVATION,
    Q_VALUE,
)
from torchrl_auv.training.lac import (
    LAC_LOGGED_KEYS,
    LEG_KEYS,
    LYAPUNOV_COSTS,
    AdvisorLoop,
    advisor_from_config,
    feedback_batch,
    filter_mode,
    lac_from_config,
    lac_optimisers,
    leg_keys,
    lyapunov_certificate,
    lyapunov_critic_from_config,
    lyapunov_filter,
    make_lac_loss,
)
from torchrl_auv.training.learner import Learner, gradient_step
from torchrl_auv.training.n_step import (
    N_STEP_KEYS,
    N_STEPS_KEY,
    NStepReturns,
    n_step_from_config,
)
from torchrl_auv.training.networks import (
    LYAPUNOV_INPUTS,
    ObsActionMLP,
    critic_layer_norm,
    make_actor,
    make_lyapunov_critic,
    make_q_critic,
    observation_action_dims,
)
from torchrl_auv.training.proposer_finetuning import (
    ProposerFineTuning,
    candidate_weights,
    check_finetune,
    demonstration_samples,
    finetuning_from_config,
)
from torchrl_auv.training.replay import (
    REPLAY_KEYS,
    buffer_from_config,
    bytes_per_frame,
    make_replay_buffer,
    select_for_replay,
)
from torchrl_auv.training.residual import (
    NEXT_PRIOR_ACTION,
    PRIOR_ACTION,
    RESIDUAL_KEYS,
    backup_and_residual,
    check_residual,
    make_residual_actor,
    next_state_keys,
    residual_bound,
    residual_policy,
    with_next_prior,
)
from torchrl_auv.training.run import (
    EPISODE_METRICS,
    Progress,
    ProgressState,
    Run,
    RunFolderInUse,
    RunTracker,
    VerifiedRotation,
    batch_metrics,
    checkpoint_problems,
    close_logger,
    configure_threads,
    episode_frames,
    log_metrics,
    logger_from_config,
    make_checkpoint,
    make_logger,
    peak_rss_mb,
    progress_postfix,
    resume_latest,
    seed_everything,
    truncate_curve,
    write_episode_video,
    write_eval,
    write_summary,
)
from torchrl_auv.training.sac import (
    CRITIC_COSTS,
    SAC_LOGGED_KEYS,
    make_sac_loss,
    sac_from_config,
    sac_optimisers,
)
from torchrl_auv.training.schemas import (
    SCHEMAS,
    AdvisorConfig,
    CheckpointConfig,
    CollectorConfig,
    DemonstrationsConfig,
    EnsembleNetworkConfig,
    EnvConfig,
    EvalConfig,
    FinetuneConfig,
    HistoryEnvConfig,
    LACOptimConfig,
    LearnerCheckpointConfig,
    LoggerConfig,
    LyapunovConfig,
    NetworkConfig,
    ProposerConfig,
    ReplayBufferConfig,
    ResidualConfig,
    SACOptimConfig,
    SelectionConfig,
    register_schemas,
)
from torchrl_auv.training.selection import (
    RankedCandidate,
    acting_actor,
    evaluation_policies,
    evaluation_policies_from_config,
    make_selection_policy,
    proposer_alone,
)

__all__ = [
    "ACTION",
    "ACTOR_ACTION",
    "AGENTS",
    "CANDIDATES",
    "CANDIDATE_KEYS",
    "COLLECTOR_BACKENDS",
    "CRITIC_COSTS",
    "DEMONSTRATION_SEED_OFFSET",
    "EPISODE_METRICS",
    "FIRST_STAGE_VERSION",
    "LAC_LOGGED_KEYS",
    "LEG_KEYS",
    "LYAPUNOV_COSTS",
    "LYAPUNOV_INPUTS",
    "LYAPUNOV_RAW",
    "NEXT_ANCHOR",
    "NEXT_CANDIDATES",
    "NEXT_PRIOR_ACTION",
    "N_STEPS_KEY",
    "N_STEP_KEYS",
    "OBSERVATION",
    "POLICIES",
    "PRIOR_ACTION",
    "Q_VALUE",
    "RECIPES_PACKAGES",
    "REPLAY_KEYS",
    "RESIDUAL_KEYS",
    "SAC_LOGGED_KEYS",
    "SCHEMAS",
    "AdvisorConfig",
    "AdvisorLoop",
    "ArtefactCache",
    "CheckpointConfig",
    "CollectorConfig",
    "DemonstrationsConfig",
    "EnsembleNetworkConfig",
    "EnvConfig",
    "EvalConfig",
    "FinetuneConfig",
    "FirstStage",
    "HistoryEnvConfig",
    "LACOptimConfig",
    "Learner",
    "LearnerCheckpointConfig",
    "LoggerConfig",
    "LyapunovConfig",
    "NStepReturns",
    "NetworkConfig",
    "ObsActionMLP",
    "Progress",
    "ProgressState",
    "ProposerConfig",
    "ProposerFineTuning",
    "RankedCandidate",
    "ReplayBufferConfig",
    "ResidualConfig",
    "Run",
    "RunFolderInUse",
    "RunTracker",
    "SACOptimConfig",
    "SameRowAs",
    "SelectionConfig",
    "VerifiedRotation",
    "acting_actor",
    "advisor_from_config",
    "backup_and_residual",
    "batch_metrics",
    "buffer_from_config",
    "build_first_stage",
    "bytes_per_frame",
    "candidate_weights",
    "check_choices",
    "check_config",
    "check_endpoint",
    "check_finetune",
    "check_ray_address",
    "check_ray_backend",
    "check_residual",
    "check_selection",
    "checkpoint_problems",
    "close_logger",
    "collect_demonstrations",
    "collector_from_config",
    "configure_threads",
    "critic_layer_norm",
    "demonstration_frames",
    "demonstration_samples",
    "env_factory",
    "env_from_config",
    "env_history",
    "episode_frames",
    "episode_stats",
    "evaluate",
    "evaluation_policies",
    "evaluation_policies_from_config",
    "exit_policy",
    "expert_policy",
    "feedback_batch",
    "filter_mode",
    "finetuning_from_config",
    "first_stage_frames",
    "first_stage_from_config",
    "first_stage_values",
    "gradient_step",
    "held_out_env",
    "lac_from_config",
    "lac_optimisers",
    "leg_keys",
    "log_metrics",
    "logger_from_config",
    "lyapunov_certificate",
    "lyapunov_critic_from_config",
    "lyapunov_filter",
    "make_actor",
    "make_checkpoint",
    "make_collector",
    "make_env",
    "make_history_env",
    "make_lac_loss",
    "make_logger",
    "make_lyapunov_critic",
    "make_policy",
    "make_q_critic",
    "make_replay_buffer",
    "make_residual_actor",
    "make_sac_loss",
    "make_selection_policy",
    "n_step_from_config",
    "next_state_keys",
    "next_state_values",
    "observation_action_dims",
    "peak_rss_mb",
    "progress_postfix",
    "proposer_alone",
    "proposer_from_config",
    "random_policy",
    "reference_policies",
    "register_schemas",
    "residual_bound",
    "residual_policy",
    "resume_latest",
    "sac_from_config",
    "sac_optimisers",
    "sampler_from_config",
    "seed_everything",
    "select_for_replay",
    "selection_backup",
    "selection_rule_from_config",
    "start_deviating",
    "symmetric_sampler",
    "truncate_curve",
    "values_key",
    "with_next_candidates",
    "with_next_prior",
    "write_episode_video",
    "write_eval",
    "write_summary",
]

register_schemas()  # the recipes' configs name the typed group schemas
