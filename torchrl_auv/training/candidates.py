"""The diffusion recipes' selection rule and what their critics' candidate backup reads.

``cfg.selection`` picks how the executed candidate is chosen and what the critics bootstrap
on (:mod:`~torchrl_auv.objectives.candidate_backup`):

- ``backup``: ``actor`` (the actor's next action, as published) or ``candidates`` (the
  candidate the selector would execute at the next state);
- ``anchor``: ``null`` (the critic's best) or ``medoid`` (the prior's consensus unless a
  candidate dominates it, :class:`~torchrl_auv.modules.SelectionRule`), with ``margin``;
- ``warmup_frames``: frames during which the anchor is executed while the critics learn its
  values (needs ``anchor: medoid``).

With ``backup: candidates`` each collected batch gets the next state's candidates
(:func:`with_next_candidates`) and the replay buffer stores them (:data:`CANDIDATE_KEYS`).

Examples:
    >>> from torchrl_auv.modules import DiffusionProposer
    >>> from torchrl_auv.training import make_history_env, proposer_alone
    >>> env = make_history_env("ideal", seed=0, num_envs=2, history=3, max_steps=4)
    >>> proposer = DiffusionProposer.for_env(env, num_inference_steps=2, horizon=4)
    >>> data = env.rollout(6, proposer_alone(proposer), break_when_any_done=False)
    >>> data = with_next_candidates(data, proposer)
    >>> data[NEXT_CANDIDATES].shape, data[NEXT_ANCHOR].shape
    (torch.Size([2, 6, 2, 5, 3]), torch.Size([2, 6, 2]))
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import torch
from tensordict import TensorDictBase

from torchrl_auv.modules import DiffusionProposer
from torchrl_auv.modules.consensus import medoid_index
from torchrl_auv.modules.selection_rule import ANCHORS, DOMINANCE, SelectionRule
from torchrl_auv.objectives.candidate_backup import BACKUPS
from torchrl_auv.training.keys import AGENTS

__all__ = [
    "CANDIDATES",
    "CANDIDATE_KEYS",
    "NEXT_ANCHOR",
    "NEXT_CANDIDATES",
    "check_selection",
    "next_state_values",
    "selection_backup",
    "selection_rule_from_config",
    "start_deviating",
    "with_next_candidates",
]

#: where the proposer writes its candidate chunks ``[*B, N, K, H, A]``
CANDIDATES = (AGENTS, "proposer", "candidates")
#: the next state's candidate first actions ``[*B, N, K, A]`` and medoid index ``[*B, N]``
NEXT_CANDIDATES = ("next", AGENTS, "proposer", "first_actions")
NEXT_ANCHOR = ("next", AGENTS, "proposer", "medoid")
#: what the replay buffer adds to :data:`~torchrl_auv.training.REPLAY_KEYS` for the backup
CANDIDATE_KEYS = (NEXT_CANDIDATES, NEXT_ANCHOR)


def check_selection(selection: Mapping) -> None:
    """A ``ValueError`` naming the first ``selection.*`` value out of its choices."""
    backup = selection.get("backup", "actor")
    if backup not in BACKUPS:
        raise ValueError(f"selection.backup must be one of {list(BACKUPS)}, got {backup!r}")
    anchor = selection.get("anchor")
    if anchor not in ANCHORS:
        raise ValueError(f"selection.anchor must be one of {list(ANCHORS)}, got {anchor!r}")
    margin = selection.get("margin", 0.0)
    if isinstance(margin, bool) or not isinstance(margin, int | float) or not margin >= 0:
        raise ValueError(f"selection.margin must be a number >= 0, got {margin!r}")
    dominance = selection.get("dominance", "interval")
    if dominance not in DOMINANCE:
        raise ValueError(f"selection.dominance must be one of {list(DOMINANCE)}, got {dominance!r}")
    warmup = selection.get("warmup_frames", 0)
    if isinstance(warmup, bool) or not isinstance(warmup, int) or warmup < 0:
        raise ValueError(f"selection.warmup_frames must be an integer >= 0, got {warmup!r}")
    if warmup and anchor is None:
        raise ValueError(
            "selection.warmup_frames > 0 executes the anchor while the critics "
            "warm up: it needs selection.anchor=medoid"
        )


def selection_rule_from_config(cfg: Mapping) -> SelectionRule:
    """The :class:`~torchrl_auv.modules.SelectionRule` of ``cfg.selection`` (checked)."""
    selection = cfg.get("selection") or {}
    check_selection(selection)
    return SelectionRule(
        anchor=selection.get("anchor"),
        margin=selection.get("margin", 0.0),
        dominance=selection.get("dominance", "interval"),
    )


def selection_backup(cfg: Mapping) -> str:
    """``cfg.selection.backup`` (``"actor"`` where the config has no selection)."""
    return (cfg.get("selection") or {}).get("backup", "actor")


def start_deviating(rule: SelectionRule, frames: int, cfg: Mapping) -> None:
    """Let ``rule`` deviate from its anchor once ``frames`` reach
    ``cfg.selection.warmup_frames`` (before: the anchor is executed and bootstrapped on)."""
    warmup = (cfg.get("selection") or {}).get("warmup_frames", 0)
    rule.deviate.fill_(frames >= warmup)


@torch.no_grad()
def next_state_values(
    data: TensorDictBase,
    current: Sequence[torch.Tensor],
    recompute: Callable[[TensorDictBase], Sequence[torch.Tensor]],
) -> list[torch.Tensor]:
    """Per-frame values ``current`` (each ``[*B, T, ...]``, time last of the batch dims) moved
    to each frame's next state: frame t's next state is frame t+1's state, so its values are
    frame t+1's; where it is not (the last frame of each row, and a frame that ended its
    episode, after which the env reset), ``recompute`` reads the stored next states (one call
    for all of them, ``data["next"]`` rows) and returns the values in the same order."""
    time = data.ndim - 1
    moved = [value.roll(-1, time) for value in current]
    own = data["next", "done"].reshape(data.batch_size).clone()
    own.select(time, -1).fill_(True)
    if own.any():
        for value, fresh in zip(moved, recompute(data["next"][own]), strict=True):
            value[own] = fresh.to(value.dtype)
    return moved


@torch.no_grad()
def with_next_candidates(data: TensorDictBase, proposer: DiffusionProposer) -> TensorDictBase:
    """``data`` (a collected batch ``[*B, T]``, time last, whose policy's proposer wrote
    :data:`CANDIDATES` at every frame) with :data:`NEXT_CANDIDATES` and :data:`NEXT_ANCHOR`
    set (:func:`next_state_values`: ``proposer`` proposes on the stored next states that are
    not the following frame's). Returns ``data``, written in place."""
    candidates = data.get(CANDIDATES, None)
    if candidates is None:
        raise ValueError(
            f"data lack the proposer's candidates {CANDIDATES!r}: collect with a "
            "policy whose proposer writes them (make_selection_policy)"
        )

    def propose(rows: TensorDictBase) -> tuple[torch.Tensor, torch.Tensor]:
        proposed = proposer(rows.select(*proposer.in_keys).copy()).get(proposer.candidates_key)
        return proposed[..., 0, :], medoid_index(proposed)

    current = (candidates[..., 0, :], medoid_index(candidates))
    next_first, next_medoid = next_state_values(data, current, propose)
    data.set(NEXT_CANDIDATES, next_first)
    data.set(NEXT_ANCHOR, next_medoid)
    return data
