"""SAC, the paper's RL baseline, as a recipe builds it: TorchRL's ``SACLoss`` on the agents
layout, its target updater, optimisers and logged outputs (:func:`sac_from_config`).

Examples:
    >>> from torchrl_auv.training import make_actor, make_env, make_q_critic, select_for_replay
    >>> env = make_env("ideal", seed=0, num_envs=2)
    >>> actor = make_actor(env, hidden=(32, 32))
    >>> loss, target_updater = make_sac_loss(actor, make_q_critic(env, hidden=(32, 32)), env)
    >>> sorted(loss(select_for_replay(env.rollout(3, actor))).keys())[:3]
    ['alpha', 'entropy', 'loss_actor']
"""

from __future__ import annotations

from collections.abc import Mapping

import torch
from tensordict.nn import TensorDictModule
from torchrl.modules import ProbabilisticActor
from torchrl.objectives import SACLoss, SoftUpdate

from torchrl_auv.envs import DataCollectionEnv
from torchrl_auv.envs.keys import AGENT_STABILITY_COST
from torchrl_auv.objectives import CandidateBackupSACLoss, ResidualSACLoss, SelectionRule
from torchrl_auv.training.keys import ACTION, AGENTS, Q_VALUE
from torchrl_auv.training.learner import Learner
from torchrl_auv.training.n_step import N_STEPS_KEY
from torchrl_auv.training.networks import (
    critic_layer_norm,
    make_q_critic,
    observation_action_dims,
)
from torchrl_auv.training.residual import backup_and_residual

__all__ = [
    "CRITIC_COSTS",
    "SAC_LOGGED_KEYS",
    "make_sac_loss",
    "sac_from_config",
    "sac_optimisers",
]

#: ``optim.critic_cost`` choices: what the Q critics of SAC and Diffusion+RL learn
CRITIC_COSTS = ("task", "stability")

#: The ``SACLoss`` outputs a recipe logs (``train/<key>``).
SAC_LOGGED_KEYS = ("loss_actor", "loss_qvalue", "alpha", "entropy", "residual")


def make_sac_loss(
    actor: ProbabilisticActor,
    critic: TensorDictModule,
    env: DataCollectionEnv,
    *,
    gamma: float = 0.97,
    alpha_init: float = 1.0,
    num_qvalue_nets: int = 2,
    tau: float = 0.005,
    loss_function: str = "smooth_l1",
    backup: str = "actor",
    rule: SelectionRule | None = None,
    residual_coef: float | None = None,
    critic_cost: str = "task",
) -> tuple[SACLoss, SoftUpdate]:
    """TorchRL's ``SACLoss`` on the agents layout (reward ``== -cost``) and its target updater.

    The target entropy is ``-action_dim`` per AUV; frames with n-step returns
    (:class:`~torchrl_auv.training.NStepReturns`) are discounted by ``gamma`` to their own
    number of steps; ``loss_function`` is SACLoss's Q loss
    (``smooth_l1``, SACLoss's own default, or ``l2``). ``backup="candidates"``: the Q target
    bootstraps on the candidate the selector (``rule``) executes at the next state
    (:class:`~torchrl_auv.objectives.CandidateBackupSACLoss`, a ``SACLoss``).
    ``residual_coef``: ``actor`` is a residual actor
    (:func:`~torchrl_auv.training.make_residual_actor`), pulled toward the prior with this
    weight (:class:`~torchrl_auv.objectives.ResidualSACLoss`). ``critic_cost``
    (:data:`CRITIC_COSTS`): ``"task"`` (the reward, ``-cost``) or ``"stability"``: the Q
    critics learn ``-("agents", "stability_cost")`` (the Lyapunov critic's cost: issue
    [22/26]'s ablation of the constraint).
    """
    if critic_cost not in CRITIC_COSTS:
        raise ValueError(f"critic_cost must be one of {CRITIC_COSTS}, got {critic_cost!r}")
    residual = {} if residual_coef is None else {"coef": residual_coef}
    loss = (ResidualSACLoss if residual else CandidateBackupSACLoss)(
        actor_network=actor,
        qvalue_network=critic,
        num_qvalue_nets=num_qvalue_nets,
        alpha_init=alpha_init,
        target_entropy=-float(observation_action_dims(env)[1]),
        delay_qvalue=True,
        loss_function=loss_function,
        backup=backup,
        rule=rule,
        reward_from=AGENT_STABILITY_COST if critic_cost == "stability" else None,
        **residual,
    )
    loss.set_keys(
        action=ACTION,
        state_action_value=Q_VALUE,
        reward=(AGENTS, "reward"),
        done=(AGENTS, "done"),
        terminated=(AGENTS, "terminated"),
        candidates=(AGENTS, "proposer", "first_actions"),
        anchor=(AGENTS, "proposer", "medoid"),
    )
    loss.make_value_estimator(gamma=gamma)
    # n-step frames carry their discount's exponent per AUV; one-step frames lack it (gamma)
    loss.value_estimator.set_keys(steps_to_next_obs=N_STEPS_KEY)
    return loss, SoftUpdate(loss, tau=tau)


def sac_optimisers(loss, optim: Mapping) -> dict[str, torch.optim.Optimizer]:
    """Adam for a ``SACLoss``'s actor, Q ensemble and temperature (``optim.*_lr``)."""
    return {
        "actor_optim": torch.optim.Adam(
            loss.actor_network_params.parameters(), lr=optim["actor_lr"]
        ),
        "critic_optim": torch.optim.Adam(
            loss.qvalue_network_params.parameters(), lr=optim["critic_lr"]
        ),
        "alpha_optim": torch.optim.Adam([loss.log_alpha], lr=optim["alpha_lr"]),
    }


def sac_from_config(
    cfg: Mapping,
    env: DataCollectionEnv,
    actor: ProbabilisticActor,
    rule: SelectionRule | None = None,
) -> Learner:
    """The SAC learner of a recipe config: a Q ensemble of ``cfg.network.critics`` (absent: 2,
    SAC's twin) critics of ``cfg.network.hidden`` (``cfg.network.layer_norm``, absent: off),
    :func:`make_sac_loss` with ``cfg.optim``'s gamma, initial temperature, tau and Q loss,
    ``cfg.selection.backup`` (absent: ``actor``) and the selector's ``rule``; with
    ``cfg.residual.bound > 0`` ``actor`` is a residual actor held near the prior with
    ``cfg.residual.coef`` (the backup then on the actor, which acts);
    :func:`sac_optimisers`, logging :data:`SAC_LOGGED_KEYS`; ``cfg.optim.compile`` (absent:
    ``False``) compiles the update (:class:`~torchrl_auv.training.Learner`)."""
    optim, network = cfg["optim"], cfg["network"]
    critic = make_q_critic(env, network["hidden"], layer_norm=critic_layer_norm(cfg))
    loss, target_updater = make_sac_loss(
        actor,
        critic.to(cfg["device"]),
        env,
        gamma=optim["gamma"],
        alpha_init=optim["alpha_init"],
        tau=optim["tau"],
        loss_function=optim["loss_function"],
        num_qvalue_nets=int(network.get("critics", 2)),
        rule=rule,
        critic_cost=optim.get("critic_cost", "task"),
        **backup_and_residual(cfg),
    )
    return Learner(
        loss,
        target_updater,
        sac_optimisers(loss, optim),
        SAC_LOGGED_KEYS,
        compile=bool(optim.get("compile", False)),
    )
