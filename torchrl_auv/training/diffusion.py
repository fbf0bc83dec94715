"""Factories of the diffusion recipes: the history env, the pretrained proposer (the first
stage, :mod:`~torchrl_auv.training.first_stage`), the proposer-selector policies and the
Lyapunov loss.

Keys on the ``("agents", ...)`` layout: the proposer reads ``("agents", "observation")`` and
``("agents", "history", ...)`` and writes ``("agents", "proposer", "candidates")``
``[*B, N, K, H, 3]``; the actor's own action goes to ``("agents", "actor", "action")``; the
selector writes the executed ``("agents", "action")`` and ``("agents", "selector", ...)``.

Examples:
    >>> env = make_history_env("ideal", seed=0, num_envs=2, history=3)
    >>> proposer = DiffusionProposer.for_env(env, num_inference_steps=2, horizon=4)
    >>> td = proposer_alone(proposer)(env.reset())
    >>> td["agents", "proposer", "candidates"].shape, td["agents", "action"].shape
    (torch.Size([2, 2, 5, 4, 3]), torch.Size([2, 2, 3]))
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModule, TensorDictModuleBase, TensorDictSequential
from torchrl.envs import TransformedEnv
from torchrl.modules import ProbabilisticActor

from torchrl_auv.envs import StateActionHistory
from torchrl_auv.modules import DiffusionProposer, ProposerAlone
from torchrl_auv.objectives import CandidateSelector, LyapunovActorCriticLoss
from torchrl_auv.training.factories import (
    ACTION,
    AGENTS,
    OBSERVATION,
    Q_VALUE,
    ObsActionMLP,
    _dims,
    make_env,
    make_q_critic,
)
from torchrl_auv.training.first_stage import first_stage_from_config

__all__ = [
    "ACTOR_ACTION",
    "LYAPUNOV_COSTS",
    "LYAPUNOV_RAW",
    "RankedCandidate",
    "acting_actor",
    "evaluation_policies",
    "feedback_batch",
    "lac_optimisers",
    "make_history_env",
    "make_lac_loss",
    "make_lyapunov_critic",
    "make_selection_policy",
    "proposer_alone",
    "proposer_from_config",
]

log = logging.getLogger(__name__)
ACTOR_ACTION = (AGENTS, "actor", "action")
LYAPUNOV_RAW = (AGENTS, "lyapunov_raw")


def make_history_env(sea_state: str = "ideal", *, history: int = 10, **env_kwargs):
    """:func:`~torchrl_auv.training.make_env` with :class:`~torchrl_auv.envs.StateActionHistory`
    (the last ``history`` observation-action pairs per AUV, the proposer's conditioning)."""
    env = make_env(sea_state, **env_kwargs)
    return TransformedEnv(
        env, StateActionHistory(history, observation_key=OBSERVATION, action_key=ACTION)
    )


def proposer_from_config(cfg, *, plot_loss=None) -> DiffusionProposer:
    """The pretrained proposer of a recipe config: the proposer of
    :func:`~torchrl_auv.training.first_stage_from_config` (cached artefact, or
    ``proposer.path``), with the config's acting values (``proposer.compile`` included)."""
    return first_stage_from_config(cfg, plot_loss=plot_loss).proposer


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
    which cost one evaluation each), the actor alone (``RL``, with an ``actor``) and the
    proposer alone (:func:`proposer_alone` with ``pick``, ``alone_candidates`` and
    ``alone_replan_every``)."""
    alone = proposer_alone(proposer, pick, num_candidates=alone_candidates,
                           replan_every=alone_replan_every)  # fmt: skip
    rows = {name: lambda _: policy, "proposer alone": lambda _: alone}
    if actor is not None:
        rows["RL"] = lambda _: actor
    slots = proposer.num_candidates + bool(policy[-1].include_actor_action) if ranks else 0
    for rank in range(slots):
        rows["OA" if rank == 0 else f"CA{rank}"] = lambda _, r=rank: RankedCandidate(policy, r)
    return rows


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
    return ProposerAlone(proposer, pick, action_key=ACTION, num_candidates=num_candidates,
                         replan_every=replan_every)  # fmt: skip


def feedback_batch(data: TensorDictBase) -> TensorDict:
    """The entries of a collected batch ``[B, T]`` the advisor's feedback reads, with time the
    second-last dim per AUV (``observation`` ``[B, N, T, obs]``, ``("next", "reward")``
    ``[B, N, T, 1]``), as :func:`~torchrl_auv.advisor.feedback_from_training` expects."""
    observation = data[OBSERVATION].transpose(-2, -3)
    return TensorDict(
        {
            "observation": observation,
            ("next", "reward"): data["next", AGENTS, "reward"].transpose(-2, -3),
        },
        batch_size=observation.shape[:-1],
    )


def acting_actor(actor: ProbabilisticActor, out_key=ACTOR_ACTION) -> ProbabilisticActor:
    """A second head on ``actor``'s network (shared parameters) writing ``out_key``: the
    actor's own action as one more candidate, while the loss trains ``actor`` itself."""
    dist = actor.module[-1]
    return ProbabilisticActor(actor.module[0], in_keys=dist.in_keys, out_keys=[out_key],
                              distribution_class=dist.distribution_class,
                              distribution_kwargs=dict(dist.distribution_kwargs))  # fmt: skip


def make_selection_policy(
    proposer: DiffusionProposer,
    critic: TensorDictModuleBase,
    *,
    mode: str,
    critic_out_key,
    actor: ProbabilisticActor | None = None,
    loss: LyapunovActorCriticLoss | None = None,
) -> TensorDictSequential:
    """Proposer, then (with ``actor``) the actor's own action, then the selector: argmax Q
    (``mode="q"``) or argmin L (``"lyapunov"``) over the K candidates' first actions (and the
    actor's); writes the executed ``("agents", "action")``. With ``loss`` (mode
    ``"lyapunov"``) the selector reads the loss's Lyapunov spec, which the loss owns
    (:meth:`~torchrl_auv.objectives.LyapunovActorCriticLoss.share_spec`): an advisor's or a
    checkpoint's new spec reaches the selector, and with its weights the workers."""
    if loss is not None and mode != "lyapunov":
        raise ValueError(
            f"loss (the owner of the Lyapunov spec) needs mode='lyapunov', got {mode!r}"
        )
    selector = CandidateSelector(
        critic, mode=mode, include_actor_action=actor is not None,
        candidates_key=(AGENTS, "proposer", "candidates"), observation_key=OBSERVATION,
        action_key=ACTION, actor_action_key=ACTOR_ACTION, critic_action_key=ACTION,
        critic_out_key=critic_out_key,
    )  # fmt: skip
    if loss is not None:
        loss.share_spec(selector)
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


def make_lyapunov_critic(env, hidden: Sequence[int] = (256, 256)) -> TensorDictModule:
    """Per-AUV Lyapunov critic's raw output z(o, a) (shared weights) at
    ``("agents", "lyapunov_raw")``; the form (e.g. softplus) is applied by the loss and the
    selector."""
    obs_dim, act_dim = _dims(env)
    return TensorDictModule(ObsActionMLP(obs_dim + act_dim, hidden), in_keys=[OBSERVATION, ACTION],
                            out_keys=[LYAPUNOV_RAW])  # fmt: skip


def lac_optimisers(loss: LyapunovActorCriticLoss, optim) -> dict[str, torch.optim.Optimizer]:
    """Adam for the actor, the critics (Lyapunov, and the task Q critic when the loss has one)
    and the dual variables (lambda, beta)."""
    critics = list(loss.lyapunov_network_params.parameters())
    if loss.qvalue_network is not None:
        critics += list(loss.qvalue_network_params.parameters())
    return {
        "actor_optim": torch.optim.Adam(loss.actor_network_params.parameters(), lr=optim.actor_lr),
        "critic_optim": torch.optim.Adam(critics, lr=optim.critic_lr),
        "dual_optim": torch.optim.Adam([loss.log_lambda, loss.log_beta], lr=optim.dual_lr),
    }  # fmt: skip


#: ``lyapunov.cost`` choices: which cost the Lyapunov critic learns (the loss's docstring)
LYAPUNOV_COSTS = ("task", "stability")


def make_lac_loss(
    actor: ProbabilisticActor,
    critic: TensorDictModule,
    env,
    *,
    gamma: float = 0.97,
    form: str = "softplus",
    stability_weight: float = 0.1,
    lambda_max: float = 1.0,
    loss_function: str = "l2",
    cost: str = "task",
    hidden: Sequence[int] = (256, 256),
) -> LyapunovActorCriticLoss:
    """:class:`~torchrl_auv.objectives.LyapunovActorCriticLoss` on the agents layout
    (``loss_function``: the critics' TD loss, ``l2`` or ``smooth_l1``).

    ``cost`` (:data:`LYAPUNOV_COSTS`): ``"task"`` (the paper): the Lyapunov critic learns
    ``("agents", "cost")`` and the actor minimises it through L alone; ``"stability"``: the
    Lyapunov critic learns ``("agents", "stability_cost")`` (0 in service) and carries the
    constraint, while a task Q critic (:func:`~torchrl_auv.training.make_q_critic` with
    ``hidden``) learns ``("agents", "cost")`` and gives the actor the task."""
    if cost not in LYAPUNOV_COSTS:
        raise ValueError(f"cost must be one of {LYAPUNOV_COSTS}, got {cost!r}")
    qvalue = make_q_critic(env, hidden) if cost == "stability" else None
    loss = LyapunovActorCriticLoss(
        actor, critic, form=form, stability_weight=stability_weight, lambda_max=lambda_max,
        target_entropy=-float(_dims(env)[1]), loss_function=loss_function,
        qvalue_network=qvalue,
    )  # fmt: skip
    lyapunov_cost = (AGENTS, "stability_cost") if cost == "stability" else (AGENTS, "cost")
    loss.set_keys(action=ACTION, reward=(AGENTS, "reward"), cost=lyapunov_cost,
                  task_cost=(AGENTS, "cost"), done=(AGENTS, "done"),
                  terminated=(AGENTS, "terminated"), value=LYAPUNOV_RAW, qvalue=Q_VALUE,
                  observation=OBSERVATION)  # fmt: skip
    loss.make_value_estimator(gamma=gamma)
    return loss
