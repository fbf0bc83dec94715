"""The diffusion recipes' acting: the proposer's K candidates, optionally the actor's own
action, and a critic's selection among them; the rows their evaluation shows.

Keys on the ``("agents", ...)`` layout: the proposer reads ``("agents", "observation")`` and
``("agents", "history", ...)`` and writes ``("agents", "proposer", "candidates")``
``[*B, N, K, H, 3]``; the actor's own action goes to ``("agents", "actor", "action")``; the
selector writes the executed ``("agents", "action")`` and ``("agents", "selector", ...)``.

Examples:
    >>> from torchrl_auv.modules import DiffusionProposer
    >>> from torchrl_auv.training import make_history_env
    >>> env = make_history_env("ideal", seed=0, num_envs=2, history=3)
    >>> proposer = DiffusionProposer.for_env(env, num_inference_steps=2, horizon=4)
    >>> td = proposer_alone(proposer)(env.reset())
    >>> td["agents", "proposer", "candidates"].shape, td["agents", "action"].shape
    (torch.Size([2, 2, 5, 4, 3]), torch.Size([2, 2, 3]))
"""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase, TensorDictSequential
from torchrl.modules import ProbabilisticActor

from torchrl_auv.evaluation import SameRowAs, reference_policies
from torchrl_auv.modules import DiffusionProposer, LyapunovFilter, ProposerAlone
from torchrl_auv.objectives import CandidateSelector, LyapunovActorCriticLoss, SelectionRule
from torchrl_auv.training.keys import ACTION, ACTOR_ACTION, AGENTS, OBSERVATION
from torchrl_auv.training.residual import residual_bound

__all__ = [
    "RankedCandidate",
    "acting_actor",
    "evaluation_policies",
    "evaluation_policies_from_config",
    "make_selection_policy",
    "proposer_alone",
]


def acting_actor(actor: ProbabilisticActor, out_key=ACTOR_ACTION) -> ProbabilisticActor:
    """A second head on ``actor``'s network (shared parameters) writing ``out_key``: the
    actor's own action as one more candidate, while the loss trains ``actor`` itself."""
    dist = actor.module[-1]
    return ProbabilisticActor(
        actor.module[0],
        in_keys=dist.in_keys,
        out_keys=[out_key],
        distribution_class=dist.distribution_class,
        distribution_kwargs=dict(dist.distribution_kwargs),
    )


def make_selection_policy(
    proposer: DiffusionProposer,
    critic: TensorDictModuleBase,
    *,
    mode: str,
    critic_out_key,
    actor: ProbabilisticActor | None = None,
    loss: LyapunovActorCriticLoss | None = None,
    rule: SelectionRule | None = None,
    constraint: LyapunovFilter | None = None,
) -> TensorDictSequential:
    """Proposer, then (with ``actor``) the actor's own action, then the selector: argmax Q
    (``mode="q"``) or argmin L (``"lyapunov"``) over the K candidates' first actions (and the
    actor's); writes the executed ``("agents", "action")``. With ``loss`` (mode
    ``"lyapunov"``) the selector reads the loss's Lyapunov spec, which the loss owns
    (:meth:`~torchrl_auv.objectives.LyapunovActorCriticLoss.share_spec`): an advisor's or a
    checkpoint's new spec reaches the selector, and with its weights the workers. ``rule``:
    which scored candidate is executed (default: the best; the learner's candidate backup
    should share it, :func:`~torchrl_auv.training.selection_rule_from_config`).
    ``constraint``: a :class:`~torchrl_auv.modules.LyapunovFilter` (e.g.
    :func:`~torchrl_auv.training.lyapunov_filter`; the loss's spec shared with it): only the
    candidates that keep the decrease condition may be executed, ranked by ``critic`` (e.g.
    LAC's task critic, ``mode="cost"``)."""
    if loss is not None and mode != "lyapunov" and constraint is None:
        raise ValueError(
            f"loss (the owner of the Lyapunov spec) needs mode='lyapunov' or a constraint, "
            f"got mode {mode!r} and no constraint"
        )
    selector = CandidateSelector(
        critic,
        mode=mode,
        include_actor_action=actor is not None,
        candidates_key=(AGENTS, "proposer", "candidates"),
        observation_key=OBSERVATION,
        action_key=ACTION,
        actor_action_key=ACTOR_ACTION,
        critic_action_key=ACTION,
        critic_out_key=critic_out_key,
        rule=rule,
        constraint=constraint,
    )
    if loss is not None:
        for reader in (selector if mode == "lyapunov" else None, constraint):
            if reader is not None:
                loss.share_spec(reader)
    parts = [proposer] + ([acting_actor(actor)] if actor is not None else []) + [selector]
    return TensorDictSequential(*parts)


class RankedCandidate(TensorDictModuleBase):
    """Executes the candidate of a fixed rank of the selector's ranking (rank 0 is the
    selector's own choice, "OA"; rank r >= 1 is "CA r" of the paper's Fig. 8/9)."""

    def __init__(self, policy: TensorDictSequential, rank: int) -> None:
        super().__init__()
        self.policy, self.rank = policy, rank
        self.in_keys, self.out_keys = policy.in_keys, [ACTION]

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        self.policy(tensordict)
        first = tensordict[AGENTS, "proposer", "first_actions"]
        if ACTOR_ACTION in tensordict.keys(True, True):
            first = torch.cat([first, tensordict[ACTOR_ACTION].unsqueeze(-2)], -2)
        index = tensordict[AGENTS, "selector", "ranking"][..., self.rank]
        pick = index[..., None, None].expand(*index.shape, 1, first.shape[-1])
        return tensordict.set(ACTION, torch.gather(first, -2, pick).squeeze(-2))


def proposer_alone(
    proposer: DiffusionProposer,
    pick: str = "medoid",
    *,
    num_candidates: int | None = None,
    replan_every: int = 1,
) -> ProposerAlone:
    """The proposer acting alone on the agents layout
    (:class:`~torchrl_auv.modules.ProposerAlone`: the ``pick`` candidate, ``"medoid"`` or
    ``"first"``, of ``num_candidates`` draws, its actions executed for ``replan_every``
    decisions before the next plan; the env's ``step_count`` restarts the plan)."""
    return ProposerAlone(
        proposer, pick, action_key=ACTION, num_candidates=num_candidates, replan_every=replan_every
    )


def evaluation_policies(
    name: str,
    policy,
    actor,
    proposer: DiffusionProposer,
    *,
    pick: str = "medoid",
    alone_candidates: int | None = None,
    alone_replan_every: int = 1,
    ranks: bool = True,
) -> dict:
    """The diffusion recipes' evaluation rows: the framework (``name``), each rank of its
    selector's ranking executed on its own (``OA`` = rank 0, ``CA1`` ... over the K candidates
    and, when the selector scores it, the actor's own action; ``ranks=False``: none of these,
    which cost one evaluation each; ``OA`` is the framework's own row when the actor's action
    does not compete: :class:`~torchrl_auv.evaluation.SameRowAs`), the actor alone
    (``RL``, with an ``actor``) and the proposer alone (:func:`proposer_alone` with ``pick``,
    ``alone_candidates`` and ``alone_replan_every``)."""
    alone = proposer_alone(
        proposer, pick, num_candidates=alone_candidates, replan_every=alone_replan_every
    )
    rows = {name: policy, "proposer alone": alone}
    if actor is not None:
        rows["RL"] = actor
    with_actor = ranks and bool(policy[-1].include_actor_action)
    for rank in range(proposer.num_candidates + with_actor if ranks else 0):
        rows["OA" if rank == 0 else f"CA{rank}"] = RankedCandidate(policy, rank)
    if ranks and not with_actor:  # rank 0 is what the framework executes: the same row
        rows["OA"] = SameRowAs(name)
    return rows


def evaluation_policies_from_config(
    cfg, name: str, policy, actor, proposer: DiffusionProposer
) -> dict:
    """:func:`evaluation_policies` with the config's proposer-alone values
    (``proposer.alone_pick``, ``alone_candidates``, ``alone_replan_every``) and ``eval.ranks``,
    followed by the reference rows (the scripted expert, random actions). A residual actor's
    policy (``cfg.residual.bound > 0``) has no ranks."""
    p = cfg["proposer"]
    rows = evaluation_policies(
        name,
        policy,
        actor,
        proposer,
        pick=p["alone_pick"],
        alone_candidates=p["alone_candidates"],
        alone_replan_every=p["alone_replan_every"],
        ranks=cfg["eval"]["ranks"] and not residual_bound(cfg),
    )
    return {**rows, **reference_policies()}
