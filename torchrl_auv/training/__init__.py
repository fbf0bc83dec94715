"""What the training recipes share and users import: factories, checkpoints, evaluation.

``recipes/<name>/train.py`` are short scripts composed from these pieces; copy one and swap a
factory to build your own pipeline.
"""

from __future__ import annotations

from torchrl_auv.training.artefacts import ArtefactCache, values_key
from torchrl_auv.training.checkpointing import (
    ProgressState,
    SpecState,
    make_checkpoint,
    resume_latest,
)
from torchrl_auv.training.collectors import (
    COLLECTOR_BACKENDS,
    check_ray_address,
    check_ray_backend,
    make_collector,
)
from torchrl_auv.training.config import check_choices, check_config
from torchrl_auv.training.evaluation import (
    POLICIES,
    episode_stats,
    evaluate,
    exit_policy,
    make_policy,
    reference_policies,
)
from torchrl_auv.training.factories import (
    REPLAY_KEYS,
    bytes_per_frame,
    make_actor,
    make_env,
    make_logger,
    make_q_critic,
    make_replay_buffer,
    make_sac_loss,
    select_for_replay,
)
from torchrl_auv.training.first_stage import (
    FIRST_STAGE_VERSION,
    FirstStage,
    build_first_stage,
    first_stage_from_config,
    first_stage_values,
)
from torchrl_auv.training.run import (
    RunTracker,
    batch_metrics,
    buffer_from_config,
    close_logger,
    collector_from_config,
    env_from_config,
    finish_run,
    gradient_step,
    held_out_env,
    log_metrics,
    logger_from_config,
    prepare_resume,
    progress_postfix,
    sac_optimisers,
    start_run,
)
from torchrl_auv.training.seeding import configure_threads, seed_everything
from torchrl_auv.training.summary import write_eval, write_summary

__all__ = [
    "COLLECTOR_BACKENDS",
    "FIRST_STAGE_VERSION",
    "POLICIES",
    "REPLAY_KEYS",
    "ArtefactCache",
    "FirstStage",
    "ProgressState",
    "RunTracker",
    "SpecState",
    "batch_metrics",
    "buffer_from_config",
    "build_first_stage",
    "bytes_per_frame",
    "check_choices",
    "check_config",
    "check_ray_address",
    "check_ray_backend",
    "close_logger",
    "collector_from_config",
    "configure_threads",
    "env_from_config",
    "episode_stats",
    "evaluate",
    "exit_policy",
    "finish_run",
    "first_stage_from_config",
    "first_stage_values",
    "gradient_step",
    "held_out_env",
    "log_metrics",
    "logger_from_config",
    "make_actor",
    "make_checkpoint",
    "make_collector",
    "make_env",
    "make_logger",
    "make_policy",
    "make_q_critic",
    "make_replay_buffer",
    "make_sac_loss",
    "prepare_resume",
    "progress_postfix",
    "reference_policies",
    "resume_latest",
    "sac_optimisers",
    "seed_everything",
    "select_for_replay",
    "start_run",
    "values_key",
    "write_eval",
    "write_summary",
]
