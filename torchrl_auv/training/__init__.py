"""What the training recipes share and users import: factories, checkpoints, evaluation.

``recipes/<name>/train.py`` are short scripts composed from these pieces; copy one and swap a
factory to build your own pipeline.
"""

from __future__ import annotations

from torchrl_auv.training.checkpointing import ProgressState, make_checkpoint, resume_latest
from torchrl_auv.training.config import COLLECTOR_BACKENDS, check_choices
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
    make_collector,
    make_env,
    make_logger,
    make_q_critic,
    make_replay_buffer,
    make_sac_loss,
    select_for_replay,
)
from torchrl_auv.training.summary import write_eval, write_summary

__all__ = [
    "COLLECTOR_BACKENDS",
    "POLICIES",
    "REPLAY_KEYS",
    "ProgressState",
    "bytes_per_frame",
    "check_choices",
    "episode_stats",
    "evaluate",
    "exit_policy",
    "make_actor",
    "make_checkpoint",
    "make_collector",
    "make_env",
    "make_logger",
    "make_policy",
    "make_q_critic",
    "make_replay_buffer",
    "make_sac_loss",
    "reference_policies",
    "resume_latest",
    "select_for_replay",
    "write_eval",
    "write_summary",
]
