"""The Lyapunov actor-critic (LAC) as a recipe builds it: the loss on the agents layout, its
target updater, optimisers and logged outputs (:func:`lac_from_config`), and the batch the LLM
advisor's training feedback reads (:func:`feedback_batch`).

Examples:
    >>> from torchrl_auv.training import make_actor, make_env, make_lyapunov_critic
    >>> env = make_env("ideal", seed=0, num_envs=2, max_steps=5)
    >>> loss = make_lac_loss(make_actor(env, (16,)), make_lyapunov_critic(env, (16,)), env,
    ...                      cost="stability", hidden=(16,))
    >>> loss.tensor_keys.cost, loss.qvalue_network is not None
    (('agents', 'stability_cost'), True)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModule
from torchrl.modules import ProbabilisticActor
from torchrl.objectives import SoftUpdate

from torchrl_auv import advisor as advisors
from torchrl_auv.envs.keys import AGENT_APPROACH, AGENT_SERVICE_START
from torchrl_auv.evaluation import LyapunovCertificate
from torchrl_auv.modules import LyapunovFilter
from torchrl_auv.objectives import LyapunovActorCriticLoss, ResidualLACLoss, SelectionRule
from torchrl_auv.training.keys import ACTION, AGENTS, LYAPUNOV_RAW, OBSERVATION, Q_VALUE
from torchrl_auv.training.learner import Learner
from torchrl_auv.training.networks import (
    critic_layer_norm,
    make_lyapunov_critic,
    make_q_critic,
    observation_action_dims,
)
from torchrl_auv.training.residual import backup_and_residual

__all__ = [
    "LAC_LOGGED_KEYS",
    "LEG_KEYS",
    "LYAPUNOV_COSTS",
    "AdvisorLoop",
    "advisor_from_config",
    "feedback_batch",
    "filter_mode",
    "lac_from_config",
    "lac_optimisers",
    "leg_keys",
    "lyapunov_certificate",
    "lyapunov_critic_from_config",
    "lyapunov_filter",
    "make_lac_loss",
]

#: The loss outputs a recipe logs (``train/<key>``; the task critic's with ``cost="stability"``).
LAC_LOGGED_KEYS = (
    "loss_actor",
    "loss_lyapunov",
    "lambda",
    "beta",
    "violation_rate",
    "delta_l",
    "loss_qvalue",
    "qvalue",
    "residual",
    "leg_fraction",
)


#: The approach-leg flags a replay buffer stores for ``lyapunov.legs`` or ``lyapunov.filter``
LEG_KEYS = (("next", *AGENT_APPROACH), ("next", *AGENT_SERVICE_START))


def leg_keys(cfg: Mapping) -> tuple:
    """:data:`LEG_KEYS` where the loss reads them (``cfg.lyapunov.legs`` or ``filter``), else
    nothing (:func:`~torchrl_auv.training.select_for_replay`'s ``extra_keys``)."""
    lyapunov = cfg.get("lyapunov", None) or {}
    return LEG_KEYS if lyapunov.get("legs", False) or filter_mode(cfg) else ()


def filter_mode(cfg: Mapping) -> str | None:
    """``cfg.lyapunov.filter`` as the loss's and the filter's mode: ``None`` for ``off`` (or
    absent), else ``rank`` or ``veto`` (:data:`~torchrl_auv.modules.FILTER_MODES`)."""
    mode = (cfg.get("lyapunov", None) or {}).get("filter", "off")
    return None if mode in ("off", None) else mode


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
    layer_norm: bool = False,
    backup: str = "actor",
    rule: SelectionRule | None = None,
    residual_coef: float | None = None,
    legs: bool = False,
    multiplier: str = "dual",
    lambda_init: float = 1.0,
    pid_gains: Sequence[float] = (1.0, 0.01, 0.0),
    constraint: str = "mean",
    filter_candidates: str | None = None,
    lyapunov_gamma: float | None = None,
    violation_budget: float | None = None,
) -> LyapunovActorCriticLoss:
    """:class:`~torchrl_auv.objectives.LyapunovActorCriticLoss` on the agents layout
    (``loss_function``: the critics' TD loss, ``l2`` or ``smooth_l1``).

    ``cost`` (:data:`LYAPUNOV_COSTS`): ``"task"`` (the paper): the Lyapunov critic learns
    ``("agents", "cost")`` and the actor minimises it through L alone; ``"stability"``: the
    Lyapunov critic learns ``("agents", "stability_cost")`` (0 in service) and carries the
    constraint, while a task Q critic (:func:`~torchrl_auv.training.make_q_critic` with
    ``hidden`` and ``layer_norm``) learns ``("agents", "cost")`` and gives the actor the task.
    The loss (the task critic and the dual variables too) is on the actor's device.
    ``backup`` and ``rule``: what both critics bootstrap on (the loss's arguments of those
    names). ``residual_coef``: ``actor`` is a residual actor
    (:func:`~torchrl_auv.training.make_residual_actor`), pulled toward the prior with this
    weight (:class:`~torchrl_auv.objectives.ResidualLACLoss`; ``backup`` should be
    ``"actor"``: the actor acts). ``legs``: the Lyapunov critic and the decrease condition
    per approach leg, absorbing at service start (the env's ``("agents", "approach" |
    "service_start")``; the loss's docstring). ``multiplier``, ``lambda_init``,
    ``pid_gains``, ``constraint``, ``filter_candidates``, ``violation_budget``: the loss's
    arguments of those names; ``lyapunov_gamma``: the Lyapunov critic's discount (``None``:
    ``gamma``; :meth:`~torchrl_auv.objectives.LyapunovActorCriticLoss.make_value_estimator`)."""
    if cost not in LYAPUNOV_COSTS:
        raise ValueError(f"cost must be one of {LYAPUNOV_COSTS}, got {cost!r}")
    qvalue = make_q_critic(env, hidden, layer_norm) if cost == "stability" else None
    residual = {} if residual_coef is None else {"coef": residual_coef}
    loss = (ResidualLACLoss if residual else LyapunovActorCriticLoss)(
        actor,
        critic,
        form=form,
        stability_weight=stability_weight,
        lambda_max=lambda_max,
        target_entropy=-float(observation_action_dims(env)[1]),
        loss_function=loss_function,
        qvalue_network=qvalue,
        backup=backup,
        rule=rule,
        multiplier=multiplier,
        lambda_init=lambda_init,
        pid_gains=tuple(pid_gains),
        constraint=constraint,
        filter_candidates=filter_candidates,
        violation_budget=violation_budget,
        **residual,
    )
    lyapunov_cost = (AGENTS, "stability_cost") if cost == "stability" else (AGENTS, "cost")
    loss.set_keys(
        action=ACTION,
        reward=(AGENTS, "reward"),
        cost=lyapunov_cost,
        task_cost=(AGENTS, "cost"),
        done=(AGENTS, "done"),
        terminated=(AGENTS, "terminated"),
        value=LYAPUNOV_RAW,
        qvalue=Q_VALUE,
        observation=OBSERVATION,
        candidates=(AGENTS, "proposer", "first_actions"),
        anchor=(AGENTS, "proposer", "medoid"),
    )
    if legs:  # else the loss's defaults, which no env key has: one leg, nothing absorbing
        loss.set_keys(approach=AGENT_APPROACH, equilibrium=AGENT_SERVICE_START)
    loss.make_value_estimator(gamma=gamma, lyapunov_gamma=lyapunov_gamma)
    return loss.to(next(actor.parameters()).device)


def lyapunov_certificate(loss: LyapunovActorCriticLoss, critic: TensorDictModule):
    """The :class:`~torchrl_auv.evaluation.LyapunovCertificate` of a LAC run: ``critic`` (the
    Lyapunov critic the selector ranks with, writing ``LYAPUNOV_RAW``) read with the loss's
    spec in force and checked against the cost it learns; ``Run.evaluate(...,
    certificate=...)`` writes ``lyapunov_certificate.json``."""
    return LyapunovCertificate(
        critic, loss.spec, raw_key=LYAPUNOV_RAW, cost_key=loss.tensor_keys.cost
    )


def lyapunov_filter(
    loss: LyapunovActorCriticLoss, critic: TensorDictModule, mode: str = "rank"
) -> LyapunovFilter:
    """The :class:`~torchrl_auv.modules.LyapunovFilter` of a LAC run on the agents layout:
    ``critic`` (the Lyapunov critic), the history's last pair, the cost the critic learns and
    the env's approach-leg flags, ``mode`` (``rank`` or ``veto``); the loss's spec shared with
    it (an advisor's new spec reaches it)."""
    screen = LyapunovFilter(
        critic,
        mode=mode,
        raw_key=LYAPUNOV_RAW,
        observation_key=OBSERVATION,
        action_key=ACTION,
        history_key=(AGENTS, "history"),
        cost_key=loss.tensor_keys.cost,
        on_leg_key=AGENT_APPROACH,
        equilibrium_key=AGENT_SERVICE_START,
    )
    return loss.share_spec(screen)


def lac_optimisers(
    loss: LyapunovActorCriticLoss, optim: Mapping
) -> dict[str, torch.optim.Optimizer]:
    """Adam for the actor, the critics (Lyapunov, and the task Q critic when the loss has one)
    and the dual variables (lambda, beta)."""
    critics = list(loss.lyapunov_network_params.parameters())
    if loss.qvalue_network is not None:
        critics += list(loss.qvalue_network_params.parameters())
    return {
        "actor_optim": torch.optim.Adam(
            loss.actor_network_params.parameters(), lr=optim["actor_lr"]
        ),
        "critic_optim": torch.optim.Adam(critics, lr=optim["critic_lr"]),
        "dual_optim": torch.optim.Adam([loss.log_lambda, loss.log_beta], lr=optim["dual_lr"]),
    }


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


def lyapunov_critic_from_config(cfg: Mapping, env) -> TensorDictModule:
    """The Lyapunov critic of a recipe config: :func:`make_lyapunov_critic` with
    ``cfg.network.hidden``, ``network.layer_norm`` and ``lyapunov.inputs`` (absent:
    ``all``), on ``cfg.device``."""
    return make_lyapunov_critic(
        env,
        cfg["network"]["hidden"],
        layer_norm=critic_layer_norm(cfg),
        inputs=(cfg.get("lyapunov", None) or {}).get("inputs", "all"),
    ).to(cfg["device"])


def lac_from_config(
    cfg: Mapping,
    env,
    actor: ProbabilisticActor,
    critic: TensorDictModule,
    rule: SelectionRule | None = None,
) -> Learner:
    """The LAC learner of a recipe config: :func:`make_lac_loss` with ``cfg.optim`` (gamma,
    lambda_max, the critics' loss function), ``cfg.lyapunov``'s form, stability weight (before
    an advisor's first consultation) and cost; a ``SoftUpdate`` of ``cfg.optim.tau`` (made
    before the loss's first forward, as TorchRL requires); :func:`lac_optimisers`; logging
    :data:`LAC_LOGGED_KEYS`; ``cfg.optim.compile`` (absent: ``False``) compiles the update
    (:class:`~torchrl_auv.training.Learner`). ``critic`` is the Lyapunov critic the selector
    ranks with too (the task critic takes ``cfg.network.layer_norm``, absent: off);
    ``cfg.selection.backup`` (absent: ``actor``) with the selector's ``rule`` is what the
    critics bootstrap on; with ``cfg.residual.bound > 0`` ``actor`` is a residual actor held
    near the prior with ``cfg.residual.coef`` (the backup then on the actor, which acts)."""
    optim, lyapunov = cfg["optim"], cfg["lyapunov"]
    loss = make_lac_loss(
        actor,
        critic,
        env,
        gamma=optim["gamma"],
        form=lyapunov["form"],
        stability_weight=lyapunov["stability_weight"],
        lambda_max=optim["lambda_max"],
        loss_function=optim["loss_function"],
        cost=lyapunov["cost"],
        legs=bool(lyapunov.get("legs", False)),
        multiplier=optim.get("multiplier", "dual"),
        lambda_init=optim.get("lambda_init", 1.0),
        pid_gains=optim.get("pid_gains", (1.0, 0.01, 0.0)),
        constraint=optim.get("constraint", "mean"),
        violation_budget=optim.get("violation_budget", None),
        filter_candidates=filter_mode(cfg),
        lyapunov_gamma=lyapunov.get("gamma", None),
        hidden=cfg["network"]["hidden"],
        layer_norm=critic_layer_norm(cfg),
        rule=rule,
        **backup_and_residual(cfg),
    )
    target_updater = SoftUpdate(loss, tau=optim["tau"])
    return Learner(
        loss,
        target_updater,
        lac_optimisers(loss, optim),
        LAC_LOGGED_KEYS,
        compile=bool(optim.get("compile", False)),
    )


def advisor_from_config(cfg: Mapping):
    """The advisor of ``cfg.advisor.backend``: ``rules`` (offline default; ``advisor.forms``,
    absent: all, the forms its rules may pick), ``fixed`` (the form
    and weight stay as configured: the alpha and form studies) or ``openai`` (any
    OpenAI-compatible endpoint at ``base_url``, the key read from ``api_key_env``)."""
    a = cfg["advisor"]
    if a["backend"] == "rules":  # advisor.forms (absent: all): the forms it may pick
        return advisors.RuleBasedAdvisor(forms=tuple(a.get("forms", None) or advisors.FORM_ORDER))
    if a["backend"] == "fixed":
        return advisors.FixedAdvisor()
    if a["backend"] == "openai":
        return advisors.OpenAICompatibleAdvisor(
            a["base_url"], a["model"], api_key_env=a["api_key_env"]
        )
    raise ValueError(f"advisor.backend must be 'rules', 'fixed' or 'openai', got {a['backend']!r}")


class AdvisorLoop:
    """The LLM outer loop of a LAC run: after each batch, the training feedback over the last
    ``cfg.advisor.window`` batches goes to the :class:`~torchrl_auv.advisor.AdvisorTrigger`,
    which consults the advisor at the start and when the feedback crosses a threshold (after
    ``cfg.advisor.cooldown`` frames) and applies its Lyapunov spec to the loss, the spec's
    owner: the selector follows. Decisions go to ``run_dir/advisor.jsonl`` and the logger.

    Checkpoint :meth:`checkpoint_modules` with the run: the spec in force and the trigger's
    cooldown resume with it.
    """

    def __init__(
        self, cfg: Mapping, run_dir: str | Path, logger, loss: LyapunovActorCriticLoss
    ) -> None:
        a = cfg["advisor"]
        self.cfg, self.loss = a, loss
        self.trigger = advisors.AdvisorTrigger(
            advisor_from_config(cfg),
            a["task"],
            log_path=Path(run_dir) / "advisor.jsonl",
            cooldown=a["cooldown"],
            logger=logger,
        )
        self.window: list = []
        self.outputs: list = []

    def checkpoint_modules(self) -> dict[str, object]:
        """The trigger (the spec in force is in the loss's state dict, the learner's)."""
        return {"advisor": self.trigger}

    def step(self, frames: int, data: TensorDictBase, out: TensorDictBase) -> dict[str, float]:
        """After a batch ``data`` whose last update returned ``out``; returns
        ``train/form_index`` (the form in force, :data:`~torchrl_auv.advisor.FORM_ORDER`)."""
        window = self.cfg["window"]
        self.window = [*self.window, feedback_batch(data)][-window:]
        self.outputs = [*self.outputs, out][-window:]  # Learner.step's output: detached
        feedback = advisors.feedback_from_training(
            self.window,
            self.outputs,
            position_indices=self.cfg["position_indices"],
            velocity_indices=self.cfg["velocity_indices"],
        )
        self.trigger.step(frames, feedback, self.loss)
        return {"train/form_index": advisors.FORM_ORDER.index(self.loss.spec.form)}
