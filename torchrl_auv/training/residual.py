"""The diffusion recipe's executed learner: a bounded residual actor on the prior's choice.

With ``cfg.residual.bound = b > 0`` the proposer alone picks its action (the medoid of
``proposer.alone_candidates`` draws, :func:`~torchrl_auv.training.proposer_alone`) and writes
it to :data:`PRIOR_ACTION`; the residual actor (:func:`make_residual_actor`) reads the AUV's
observation and that action and samples the executed action within ``b`` of it. The actor is
the policy that acts, so SAC trains it and its critics as they are
(:class:`~torchrl_auv.objectives.ResidualSACLoss`, which adds a pull toward the prior of
weight ``cfg.residual.coef``); the replay buffer stores the prior's action of each state and
of its next state (:data:`RESIDUAL_KEYS`, :func:`with_next_prior`). The candidate selection
(``cfg.selection``) is not used.

Examples:
    >>> from torchrl_auv.modules import DiffusionProposer
    >>> from torchrl_auv.training import make_history_env
    >>> env = make_history_env("ideal", seed=0, num_envs=2, history=3, max_steps=4)
    >>> proposer = DiffusionProposer.for_env(env, num_inference_steps=2, horizon=4)
    >>> policy = residual_policy(proposer, make_residual_actor(env, (16,), bound=0.2))
    >>> data = with_next_prior(env.rollout(6, policy, break_when_any_done=False), policy[0])
    >>> data["next", "agents", "prior", "action"].shape
    torch.Size([2, 6, 2, 3])
    >>> bool(((data["agents", "action"] - data["agents", "prior", "action"]).abs() <= 0.2).all())
    True
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import torch
from tensordict import TensorDictBase
from tensordict.nn import (
    NormalParamExtractor,
    TensorDictModule,
    TensorDictModuleBase,
    TensorDictSequential,
)
from torch import nn
from torchrl.modules import MLP, ProbabilisticActor, TanhNormal

from torchrl_auv.envs import DataCollectionEnv
from torchrl_auv.modules import DiffusionProposer, ProposerAlone
from torchrl_auv.objectives import CandidateSelector, LyapunovActorCriticLoss
from torchrl_auv.training.candidates import CANDIDATE_KEYS, next_state_values, selection_backup
from torchrl_auv.training.keys import ACTION, AGENTS, LYAPUNOV_RAW, OBSERVATION
from torchrl_auv.training.networks import observation_action_dims

__all__ = [
    "NEXT_PRIOR_ACTION",
    "PRIOR_ACTION",
    "RESIDUAL_KEYS",
    "backup_and_residual",
    "check_residual",
    "make_residual_actor",
    "next_state_keys",
    "residual_bound",
    "residual_policy",
    "with_next_prior",
]

#: the prior's choice (the proposer alone's action) ``[*B, N, A]``
PRIOR_ACTION = (AGENTS, "prior", "action")
NEXT_PRIOR_ACTION = ("next", *PRIOR_ACTION)
#: what the replay buffer adds to :data:`~torchrl_auv.training.REPLAY_KEYS` for the actor
RESIDUAL_KEYS = (PRIOR_ACTION, NEXT_PRIOR_ACTION)
_LOW, _HIGH = (AGENTS, "prior", "low"), (AGENTS, "prior", "high")
#: the executed action as a selector's one candidate ``[*B, N, 1, A]`` (its selector writes
#: under ``("agents", "selector")``)
_EXECUTED = (AGENTS, "executed", "candidates")


class _ObsPriorMLP(nn.Module):
    """loc and scale of the residual from the observation and the prior's action; loc's
    output layer starts at zero (a zero residual: the deterministic action is the prior's)."""

    def __init__(self, obs_dim: int, act_dim: int, hidden: Sequence[int]) -> None:
        super().__init__()
        mlp = MLP(
            in_features=obs_dim + act_dim,
            out_features=2 * act_dim,
            num_cells=list(hidden),
            activation_class=nn.ReLU,
        )
        last = [m for m in mlp.modules() if isinstance(m, nn.Linear)][-1]
        with torch.no_grad():  # loc starts at 0: the untrained actor's action is the prior's
            last.weight[:act_dim].zero_()
            last.bias[:act_dim].zero_()
        self.net = nn.Sequential(mlp, NormalParamExtractor())

    def forward(self, obs: torch.Tensor, prior: torch.Tensor) -> tuple[torch.Tensor, ...]:
        return self.net(torch.cat([obs, prior], -1))


class _Bounds(nn.Module):
    """``[prior - bound, prior + bound]``: the support of the executed action."""

    def __init__(self, bound: float) -> None:
        super().__init__()
        self.bound = bound

    def forward(self, prior: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return prior - self.bound, prior + self.bound


class _OneCandidate(nn.Module):
    """An action ``[..., A]`` as a set of one candidate ``[..., 1, A]`` (picklable, for
    collector worker processes)."""

    def forward(self, action: torch.Tensor) -> torch.Tensor:
        return action.unsqueeze(-2)


def make_residual_actor(
    env: DataCollectionEnv, hidden: Sequence[int] = (256, 256), *, bound: float
) -> ProbabilisticActor:
    """Per-AUV residual actor (shared weights): a ``TanhNormal`` on ``[a0 - bound, a0 + bound]``
    with ``a0`` the prior's action (:data:`PRIOR_ACTION`); its deterministic action is
    ``a0 + bound * tanh(loc)``, and ``loc`` starts at 0: untrained, it executes the prior's
    action (a safe start; SAC's exploration samples around it). ``bound`` is in action units
    (actions lie in [-1, 1]; the env clips what leaves them). Reads
    ``("agents", "observation")`` and :data:`PRIOR_ACTION`, writes ``("agents", "action")``."""
    if isinstance(bound, bool) or not isinstance(bound, int | float) or not 0 < bound <= 2:
        raise ValueError(f"bound must be a number in (0, 2] (action units), got {bound!r}")
    obs_dim, act_dim = observation_action_dims(env)
    body = TensorDictModule(
        _ObsPriorMLP(obs_dim, act_dim, hidden),
        in_keys=[OBSERVATION, PRIOR_ACTION],
        out_keys=[(AGENTS, "loc"), (AGENTS, "scale")],
    )
    bounds = TensorDictModule(_Bounds(float(bound)), in_keys=[PRIOR_ACTION], out_keys=[_LOW, _HIGH])
    return ProbabilisticActor(
        TensorDictSequential(body, bounds),
        in_keys={"loc": (AGENTS, "loc"), "scale": (AGENTS, "scale"), "low": _LOW, "high": _HIGH},
        out_keys=[ACTION],
        distribution_class=TanhNormal,
        return_log_prob=False,
    )


def residual_policy(
    proposer: DiffusionProposer,
    actor: ProbabilisticActor,
    *,
    pick: str = "medoid",
    num_candidates: int | None = None,
    lyapunov: tuple[TensorDictModuleBase, LyapunovActorCriticLoss] | None = None,
) -> TensorDictSequential:
    """The proposer alone (``pick`` of ``num_candidates`` draws, re-planned every decision)
    writing :data:`PRIOR_ACTION`, then the residual ``actor`` writing the executed action
    (``policy[0]`` is the prior). With ``lyapunov = (critic, loss)`` (the LAC recipe) a
    :class:`~torchrl_auv.modules.CandidateSelector` in mode ``"lyapunov"`` then scores the
    executed action, its one candidate, with ``critic`` under ``loss``'s Lyapunov spec: it
    writes ``("agents", "selector", "scores")`` (``-L``) and ``"index"`` (0), what the
    Lyapunov trace reads (:func:`~torchrl_auv.report.write_lyapunov_trace`)."""
    prior = ProposerAlone(proposer, pick, action_key=PRIOR_ACTION, num_candidates=num_candidates)
    if lyapunov is None:
        return TensorDictSequential(prior, actor)
    critic, loss = lyapunov
    as_candidate = TensorDictModule(_OneCandidate(), in_keys=[ACTION], out_keys=[_EXECUTED])
    scorer = CandidateSelector(
        critic,
        mode="lyapunov",
        candidates_key=_EXECUTED,
        observation_key=OBSERVATION,
        action_key=ACTION,
        critic_action_key=ACTION,
        critic_out_key=LYAPUNOV_RAW,
    )
    loss.share_spec(scorer)
    return TensorDictSequential(prior, actor, as_candidate, scorer)


@torch.no_grad()
def with_next_prior(data: TensorDictBase, prior: ProposerAlone) -> TensorDictBase:
    """``data`` (a collected batch ``[*B, T]``, time last, whose policy's ``prior`` wrote
    :data:`PRIOR_ACTION` at every frame) with :data:`NEXT_PRIOR_ACTION` set
    (:func:`~torchrl_auv.training.next_state_values`: ``prior`` acts on the stored next
    states that are not the following frame's). Returns ``data``, written in place."""
    current = data.get(PRIOR_ACTION, None)
    if current is None:
        raise ValueError(
            f"data lack the prior's action {PRIOR_ACTION!r}: collect with residual_policy"
        )

    def act(rows: TensorDictBase) -> tuple[torch.Tensor]:
        return (prior(rows.select(*prior.in_keys).copy()).get(PRIOR_ACTION),)

    (moved,) = next_state_values(data, (current,), act)
    return data.set(NEXT_PRIOR_ACTION, moved)


def check_residual(residual: Mapping, alone_replan_every: int | None = 1) -> None:
    """A ``ValueError`` naming the first ``residual.*`` value out of range: ``bound`` a number
    in [0, 2] (0: off), ``coef`` a number >= 0; a residual on a prior that re-plans every
    decision only (``proposer.alone_replan_every`` 1)."""
    bound, coef = residual.get("bound", 0.0), residual.get("coef", 1.0)
    if isinstance(bound, bool) or not isinstance(bound, int | float) or not 0 <= bound <= 2:
        raise ValueError(f"residual.bound must be a number in [0, 2] (0: off), got {bound!r}")
    if isinstance(coef, bool) or not isinstance(coef, int | float) or not coef >= 0:
        raise ValueError(f"residual.coef must be a number >= 0, got {coef!r}")
    if bound and alone_replan_every not in (None, 1):
        raise ValueError(
            "residual.bound > 0 acts on the proposer alone re-planned every decision: it "
            f"needs proposer.alone_replan_every=1, got {alone_replan_every!r}"
        )


def residual_bound(cfg: Mapping) -> float:
    """``cfg.residual.bound`` (absent: 0, no residual actor)."""
    return float((cfg.get("residual") or {}).get("bound", 0.0))


def backup_and_residual(cfg: Mapping) -> dict:
    """The loss arguments of a recipe config's critic target and actor: with a residual actor
    (``cfg.residual.bound > 0``) ``backup="actor"`` (the actor acts) and ``residual_coef`` =
    ``cfg.residual.coef``; else ``cfg.selection.backup`` and no residual.

    >>> backup_and_residual({"residual": {"bound": 0.2, "coef": 3}})
    {'backup': 'actor', 'residual_coef': 3.0}
    >>> backup_and_residual({"selection": {"backup": "candidates"}})
    {'backup': 'candidates', 'residual_coef': None}
    """
    if residual_bound(cfg) > 0:
        return {"backup": "actor", "residual_coef": float(cfg["residual"].get("coef", 1.0))}
    return {"backup": selection_backup(cfg), "residual_coef": None}


def next_state_keys(cfg: Mapping) -> tuple:
    """What the diffusion recipes' replay buffer stores of each frame's next state beyond
    :data:`~torchrl_auv.training.REPLAY_KEYS`: the prior's action for a residual actor
    (:data:`RESIDUAL_KEYS`), the candidates for the critics' candidate backup
    (:data:`~torchrl_auv.training.CANDIDATE_KEYS`), else nothing."""
    if residual_bound(cfg) > 0:
        return RESIDUAL_KEYS
    return CANDIDATE_KEYS if selection_backup(cfg) == "candidates" else ()
