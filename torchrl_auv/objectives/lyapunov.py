r"""``LyapunovActorCriticLoss``: the Lyapunov actor-critic (LAC) with Lagrangian dual updates.

Paper §III-B (eqs. 20-28) after Han et al. (2020). With cost :math:`c \ge 0` (the ``cost`` key
when present, else :math:`-r`), a Lyapunov critic :math:`L(s, a) = \mathrm{form}(z(s, a)) \ge 0`
(:mod:`~torchrl_auv.modules.lyapunov_forms`), the actor :math:`\pi`, the Lagrange multiplier
:math:`\lambda \in [0, \lambda_{max}]` and the entropy temperature :math:`\beta`:

.. math::

    \mathcal L_{L} &= \mathbb E\big[(L(s, a) - c - \gamma (1 - d)\,
        L_{target}(s', a'))^2\big],\ a' \sim \pi(s') \\
    \Delta L &= L(s', a') - L(s, a) + \alpha c \quad (\text{mode "lac"}) \\
    \Delta L &= L(s, \tilde a) - L(s, a) + \alpha c,\ \tilde a \sim \pi(s)
        \quad (\text{mode "paper"}) \\
    \mathcal L_{\pi} &= \bar\lambda\,\mathbb E[\Delta L] + \bar\beta\,\mathbb E[\log\pi] \\
    \mathcal L_\lambda &= -\log\lambda\ \mathbb E[\Delta L]^{\perp} \\
    \mathcal L_\beta &= -\log\beta\ \mathbb E[\log\pi + \bar{\mathcal H}]^{\perp}

(bars and :math:`\perp`: no gradient). Each term sends gradient only to its own parameters:
:math:`\mathcal L_L` to the critic, :math:`\mathcal L_\pi` to the actor (through the sampled
actions; the critic is detached), :math:`\mathcal L_\lambda` to :math:`\log\lambda`,
:math:`\mathcal L_\beta` to :math:`\log\beta`. Summing them under one optimiser is correct.

**Why "lac" is the default.** With :math:`\gamma \to 1` the true cost-to-go satisfies
:math:`V(s') - V(s) = -c`, so the next-state condition :math:`L(s', \pi(s')) - L(s, a) + \alpha c
\le 0` is feasible for :math:`\alpha < 1` and is the one LAC's stability proof uses. The paper's
eq. 25 as printed compares two actions at the same state (an advantage-like quantity that says
nothing about the decrease along trajectories); it is available as ``mode="paper"``.

**Which cost the critic learns.** For a critic equal to the true discounted cost-to-go,
:math:`L(s, a) = c + \gamma L(s', a')`, so along the policy's transitions

.. math::

    \Delta L = L(s', a') - L(s, a) + \alpha c = (1 - \gamma)\, L(s', a') - (1 - \alpha)\, c .

If the cost is roughly stationary (:math:`c' \approx c`, :math:`L \approx c / (1 - \gamma)`),
:math:`\Delta L \approx \alpha c > 0` for every :math:`\alpha > 0`: the decrease condition of
Han et al. cannot hold for a cost that does not vanish. It is built for stabilisation, a cost
that is zero where the system should be and falls along the trajectories that reach it (e.g.
:math:`c_k = c_0 - k\delta` until arrival gives :math:`\Delta L < 0` once
:math:`(1 - \gamma) L(s') < (1 - \alpha) c`). The data-collection task cost carries the data
still waiting in the nodes, which never vanishes (46-59 % of the expert's cost), so with the
task cost the constraint is infeasible; :func:`torchrl_auv.iout.stability_cost` (distance and
regress toward the target, collisions, violations: 0 in service) can satisfy it.

**Legs and an absorbing equilibrium** (the ``approach`` and ``equilibrium`` keys; absent
from the data, every transition counts and none is absorbing). Even the stability cost does
not vanish for good in the data-collection task: after each service the AUV takes a new
target and the distance jumps. What can decrease is the cost-to-go of one *approach leg*
(:mod:`torchrl_auv.iout.legs`), from taking a target to starting service at it. The critic
learns that leg's cost-to-go: its TD target ends at service start,

.. math::

    L(s, a) \leftarrow c + \gamma_L\,(1 - d)\,(1 - e)\, L_{target}(s', a'),

with :math:`e = 1` where the transition starts service (the equilibrium: :math:`L = 0`
there), and the critic's loss and the decrease condition are means over the approach
transitions only (``approach``: not in service, the same target kept). For the leg's true
cost-to-go, :math:`\Delta L = L(s', a') - L(s, a) + \alpha c = (1 - \gamma) L(s', a') -
(1 - \alpha) c` inside the leg and :math:`-L(s, a) + \alpha c = -(1 - \alpha) c` on the last
transition. With :math:`\gamma = 1` every transition of a leg that ends satisfies the
condition (:math:`c > 0` outside service); with :math:`\gamma < 1` every transition where
:math:`(1 - \gamma) L(s') < (1 - \alpha) c`: for an approach at speed :math:`v` with a cost
:math:`w\,d / D` proportional to the distance :math:`d` left (``iout.stability_cost``),
:math:`L \approx w d^2 / (2 D v \Delta t)` and the condition holds for
:math:`d < 2 (1 - \alpha) v \Delta t / (1 - \gamma)` (270 m at 1.5 m a decision,
:math:`\alpha = 0.1`, :math:`\gamma = 0.99`: all of the area's 283 m diagonal but its last
13 m). A policy that stalls, circles or regresses (the regress term) violates it: that is
what the condition is for. The bound scales with the approach speed: an AUV held back by a
current to :math:`v \Delta t = 0.2` m a decision keeps it for :math:`d < 36` m only. The
Lyapunov critic's discount :math:`\gamma_L` (``make_value_estimator(lyapunov_gamma=...)``;
default the task's :math:`\gamma`) need not be the task's: a leg ends at service start, so
:math:`\gamma_L` near 1 is well posed, and at :math:`\gamma_L = 0.999` the bound is ten times
wider (360 m at 0.2 m a decision).

**The constraint and the multiplier.** ``constraint="mean"`` charges the actor
:math:`\lambda\,\mathbb E[\Delta L]` (as published: one transition's violation can be paid
by another's decrease); ``"hinge"`` charges :math:`\lambda\,\mathbb E[\max(0, \Delta L)]`,
each violating sample on its own. ``multiplier="dual"`` moves :math:`\log\lambda` by
gradient ascent on :math:`\mathbb E[\Delta L]` (published; its pace is the optimiser's step
size, not the constraint's); ``"pid"`` sets :math:`\lambda` from a PID controller on the
batch's :math:`e = \mathbb E[\Delta L]` (Stooke, Achiam and Abbeel 2020; with
``violation_budget`` :math:`b`, :math:`e = P(\Delta L > 0) - b`, the batch's violation rate
over the budget: the mean can be negative while a tenth of the transitions violate): :math:`I
\leftarrow \max(0, I + e)`, :math:`\lambda = \mathrm{clip}(k_p e + k_i I + k_d \max(0, e -
e_{prev}), 0, \lambda_{max})`, updated by every forward call in training mode (the module's
``train()``), so a persistent violation raises :math:`\lambda` however small, and a
satisfied condition lowers it; ``"fixed"`` keeps ``lambda_init`` (0: the constraint off).
Only the ``"dual"`` multiplier has a gradient (``loss_lambda`` is a constant otherwise).

**Two critics** (``qvalue_network``, paper Algorithm 1 initialises both :math:`Q_\psi` and
:math:`L_\xi`). Without it, the actor optimises the task through :math:`L` alone (LAC: the
critic learns the ``cost`` key, the task cost). With it, :math:`L` learns the ``cost`` key
(set it to the stability cost) and carries only the constraint, while a Q critic learns the
``task_cost`` key by the same TD(0) rule and the actor minimises the task:

.. math::

    \mathcal L_{Q} &= \mathbb E\big[(Q(s, a) - c^{task} - \gamma (1 - d)\,
        Q_{target}(s', a'))^2\big] \\
    \mathcal L_{\pi} &= \mathbb E[Q(s, \tilde a)] + \bar\lambda\,\mathbb E[\Delta L]
        + \bar\beta\,\mathbb E[\log\pi],\ \tilde a \sim \pi(s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from tensordict import NestedKey, TensorDict, TensorDictBase, TensorDictParams, unravel_key
from tensordict.nn import TensorDictModule
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.objectives.common import LossModule
from torchrl.objectives.utils import ValueEstimators

from torchrl_auv.modules.lyapunov_filter import FILTER_MODES, filtered_choice
from torchrl_auv.modules.lyapunov_forms import (
    FORMS,
    LyapunovSpec,
    LyapunovSpecState,
    lyapunov_value,
)
from torchrl_auv.modules.selection_rule import SelectionRule
from torchrl_auv.objectives.candidate_backup import check_backup, next_candidates, per_candidate

__all__ = ["CONSTRAINTS", "LOSS_FUNCTIONS", "MODES", "MULTIPLIERS", "LyapunovActorCriticLoss"]

MODES = ("lac", "paper")
#: How the actor's loss weighs the decrease condition: ``mean`` (LAC as published:
#: :math:`\lambda\,\mathbb E[\Delta L]`, a violation can be paid by a decrease elsewhere) or
#: ``hinge`` (:math:`\lambda\,\mathbb E[\max(0, \Delta L)]`, per sample: only violations count).
CONSTRAINTS = ("mean", "hinge")
#: How the multiplier moves: ``dual`` (gradient ascent on :math:`\log\lambda`, Adam, as
#: published), ``pid`` (a PID controller on the batch's :math:`\mathbb E[\Delta L]`, Stooke,
#: Achiam and Abbeel, ICML 2020) or ``fixed`` (:math:`\lambda` = ``lambda_init`` throughout; 0
#: switches the constraint off: the ablation).
MULTIPLIERS = ("dual", "pid", "fixed")
#: The critic's TD loss: ``l2`` (:math:`\tfrac12 e^2`) or ``smooth_l1`` (Huber, threshold 1: the
#: same :math:`\tfrac12 e^2` for :math:`|e| < 1`, :math:`|e| - \tfrac12` beyond, so one large
#: target, such as a termination cost, weighs linearly, not quadratically).
LOSS_FUNCTIONS = ("l2", "smooth_l1")


def _read_out(out: TensorDictBase, key: NestedKey, name: str, network: str, module) -> torch.Tensor:
    """``out[key]``, or a ``ValueError`` naming the loss's key and the critic's out keys."""
    value = out.get(key, None)
    if value is None:
        raise ValueError(
            f"the loss reads the {network}'s output from its {name!r} key {key!r}, "
            f"but the critic writes {list(module.out_keys)}: make them agree with "
            f"loss.set_keys({name}=...) or the critic's out_keys"
        )
    return value


class LyapunovActorCriticLoss(LossModule):
    """Lyapunov actor-critic loss with Lagrangian dual updates (module docstring).

    Args:
        actor_network: a TorchRL ``ProbabilisticActor`` (e.g. with ``TanhNormal``); its
            parameters stay shared with the module passed in (a collector running it acts
            with the trained policy).
        lyapunov_network: a ``ValueOperator``-like module reading observation and action and
            writing the raw critic output (``state_action_value`` for TorchRL's
            ``ValueOperator``); the loss applies the form.
        form: a Lyapunov form name (:data:`~torchrl_auv.modules.FORMS`), or pass ``spec``.
        stability_weight: :math:`\\alpha > 0`.
        mode: ``"lac"`` (default) or ``"paper"``.
        loss_function: the critic's TD loss, one of :data:`LOSS_FUNCTIONS` (default ``l2``).
        lambda_init, lambda_max: initial and largest Lagrange multiplier (> 0); ``log_lambda``
            itself is held at or below ``log(lambda_max)`` (no windup past the cap).
        beta_init: initial entropy temperature (> 0).
        target_entropy: ``"auto"`` (minus the action dimension) or a number.
        action_spec: optional, for the ``"auto"`` target entropy.
        spec: a full :class:`~torchrl_auv.modules.LyapunovSpec` (overrides ``form`` and
            ``stability_weight``).
        qvalue_network: optional task critic (a ``ValueOperator``-like module reading
            observation and action, writing the ``qvalue`` key): trained on ``task_cost``, it
            gives the actor the task objective while the Lyapunov critic, trained on ``cost``,
            gives the constraint (module docstring, "Two critics"). ``None``: LAC as published.
        backup: the next action both critics' targets bootstrap on: ``"actor"`` (LAC as
            published: :math:`a' \\sim \\pi(s')`) or ``"candidates"``: the candidate the
            selector would execute at :math:`s'` (argmin :math:`L_{target}(s', a'_k)` under
            ``rule``; :mod:`~torchrl_auv.objectives.candidate_backup`), read from the
            ``candidates`` and ``anchor`` keys under ``"next"``. The actor's own loss is
            unchanged.
        rule: the selector's :class:`~torchrl_auv.modules.SelectionRule` (by reference;
            default argmin).
        constraint: :data:`CONSTRAINTS` (module docstring; default ``"mean"``, published).
        multiplier: :data:`MULTIPLIERS` (default ``"dual"``, published); ``lambda_init`` may be
            0 for ``"pid"`` and ``"fixed"``.
        pid_gains: ``(kp, ki, kd)`` >= 0 of the ``"pid"`` multiplier (per unit of
            :math:`\\Delta L`; default ``(1, 0.01, 0)``).
        violation_budget: ``None`` (the PID's error is :math:`\\mathbb E[\\Delta L]`), or the
            fraction in [0, 1) of approach transitions allowed to violate the condition: the
            ``"pid"`` multiplier's error is then the batch's violation rate minus it (a chance
            constraint, what :class:`~torchrl_auv.evaluation.LyapunovCertificate` measures).
        filter_candidates: ``None``, or the ``mode`` of the selector's
            :class:`~torchrl_auv.modules.LyapunovFilter` (:data:`~torchrl_auv.modules.FILTER_MODES`;
            ranking by the task critic; needs ``qvalue_network`` and ``backup="candidates"``,
            ``"veto"`` an anchored ``rule``): the backup follows that selector, at :math:`s'`
            the task critic's choice among the candidates that keep the decrease condition of
            the transition (``"veto"``: the anchor where it does), else the least :math:`L`.

    Keys (``set_keys``): ``action``, ``reward``, ``cost`` (the Lyapunov critic's cost; ``-reward``
    when the default ``"cost"`` is absent; a key set with ``set_keys`` must be in the data),
    ``task_cost`` (the Q critic's; likewise), ``done``, ``terminated``, ``candidates`` and
    ``anchor`` (``backup="candidates"``: the next state's candidate first actions
    ``[*B, K, A]`` and anchor index ``[*B]``), ``approach`` and ``equilibrium`` (under
    ``"next"``, bool like the cost: the approach legs; module docstring), ``value`` (the Lyapunov
    critic's out key), ``qvalue`` (the Q critic's out key; a critic that does not write its key
    is a ``ValueError`` naming both), ``observation`` (read by a prior), ``log_prob``.

    Output: ``loss_actor``, ``loss_lyapunov``, ``loss_lambda``, ``loss_beta`` and detached
    ``lambda``, ``beta``, ``delta_l`` (mean), ``violation_rate`` (fraction of
    :math:`\\Delta L > 0`), ``lyapunov_value`` (mean; these three over the approach
    transitions), ``leg_fraction`` (their share), ``negative_cost_fraction``; with a
    ``qvalue_network`` also ``loss_qvalue`` and ``qvalue`` (mean).

    Examples:
        >>> from tensordict.nn import NormalParamExtractor
        >>> from torchrl.modules import MLP, ProbabilisticActor, TanhNormal, ValueOperator
        >>> net = torch.nn.Sequential(MLP(3, 2, num_cells=[16]), NormalParamExtractor())
        >>> actor = ProbabilisticActor(TensorDictModule(net, ["observation"], ["loc", "scale"]),
        ...     in_keys=["loc", "scale"], distribution_class=TanhNormal)
        >>> critic = ValueOperator(MLP(4, 1, num_cells=[16]), ["observation", "action"])
        >>> q = ValueOperator(MLP(4, 1, num_cells=[16]), ["observation", "action"],
        ...                   out_keys=["task_value"])
        >>> loss = LyapunovActorCriticLoss(actor, critic, qvalue_network=q)
        >>> loss.set_keys(cost="stability_cost", task_cost="cost", qvalue="task_value")
        >>> td = TensorDict({"observation": torch.randn(4, 3), "action": torch.rand(4, 1),
        ...     "next": {"observation": torch.randn(4, 3), "cost": torch.rand(4, 1),
        ...              "stability_cost": torch.rand(4, 1), "reward": torch.zeros(4, 1),
        ...              "terminated": torch.zeros(4, 1, dtype=torch.bool)}}, [4])
        >>> sorted(k for k in loss(td).keys() if k.startswith("loss_"))
        ['loss_actor', 'loss_beta', 'loss_lambda', 'loss_lyapunov', 'loss_qvalue']
    """

    @dataclass
    class _AcceptedKeys:
        """Keys read by the loss (see the class docstring)."""

        action: NestedKey = "action"
        reward: NestedKey = "reward"
        cost: NestedKey = "cost"
        task_cost: NestedKey = "cost"
        done: NestedKey = "done"
        terminated: NestedKey = "terminated"
        value: NestedKey = "state_action_value"
        qvalue: NestedKey = "state_action_value"
        observation: NestedKey = "observation"
        log_prob: NestedKey = "action_log_prob"
        candidates: NestedKey = ("proposer", "first_actions")
        anchor: NestedKey = ("proposer", "medoid")
        approach: NestedKey = "approach"
        equilibrium: NestedKey = "service_start"

    default_keys = _AcceptedKeys
    default_value_estimator = ValueEstimators.TD0

    actor_network: TensorDictModule
    actor_network_params: TensorDictParams
    target_actor_network_params: TensorDictParams | None
    lyapunov_network: TensorDictModule
    lyapunov_network_params: TensorDictParams
    target_lyapunov_network_params: TensorDictParams
    qvalue_network: TensorDictModule | None
    qvalue_network_params: TensorDictParams | None
    target_qvalue_network_params: TensorDictParams | None

    def __init__(
        self,
        actor_network: TensorDictModule,
        lyapunov_network: TensorDictModule,
        *,
        form: str = "softplus",
        stability_weight: float = 0.1,
        mode: str = "lac",
        lambda_init: float = 1.0,
        lambda_max: float = 1.0,
        beta_init: float = 1.0,
        target_entropy: str | float = "auto",
        action_spec=None,
        spec: LyapunovSpec | None = None,
        loss_function: str = "l2",
        qvalue_network: TensorDictModule | None = None,
        backup: str = "actor",
        rule: SelectionRule | None = None,
        constraint: str = "mean",
        multiplier: str = "dual",
        pid_gains: tuple[float, float, float] = (1.0, 0.01, 0.0),
        filter_candidates: str | None = None,
        violation_budget: float | None = None,
    ) -> None:
        check_backup(backup)
        if filter_candidates not in (None, *FILTER_MODES):
            raise ValueError(
                f"filter_candidates must be None or one of {FILTER_MODES}, "
                f"got {filter_candidates!r}"
            )
        if filter_candidates and (qvalue_network is None or backup != "candidates"):
            raise ValueError(
                f"filter_candidates={filter_candidates!r} bootstraps on the task critic's choice "
                "among the candidates that keep the decrease condition: it needs a "
                f"qvalue_network and backup='candidates', got qvalue_network={qvalue_network!r}, "
                f"backup={backup!r}"
            )
        if filter_candidates == "veto" and not (rule is not None and rule.anchored):
            raise ValueError("filter_candidates='veto' keeps the anchor: it needs an anchored rule")
        if constraint not in CONSTRAINTS:
            raise ValueError(f"constraint must be one of {CONSTRAINTS}, got {constraint!r}")
        if multiplier not in MULTIPLIERS:
            raise ValueError(f"multiplier must be one of {MULTIPLIERS}, got {multiplier!r}")
        if violation_budget is not None and not 0 <= violation_budget < 1:
            raise ValueError(f"violation_budget must be None or in [0, 1), got {violation_budget}")
        if violation_budget is not None and multiplier != "pid":
            raise ValueError(
                f"violation_budget sets the PID multiplier's error: it needs multiplier='pid', "
                f"got {multiplier!r}"
            )
        if len(pid_gains) != 3 or any(not gain >= 0 for gain in pid_gains):
            raise ValueError(f"pid_gains must be three numbers >= 0 (kp, ki, kd), got {pid_gains}")
        if loss_function not in LOSS_FUNCTIONS:
            raise ValueError(
                f"loss_function must be one of {LOSS_FUNCTIONS}, got {loss_function!r}"
            )
        if form not in FORMS:
            raise ValueError(f"form must be one of {sorted(FORMS)}, got {form!r}")
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        if not stability_weight > 0:
            raise ValueError(f"stability_weight must be > 0, got {stability_weight}")
        for name, value in (
            ("lambda_init", lambda_init),
            ("lambda_max", lambda_max),
            ("beta_init", beta_init),
        ):
            if not value > 0 and not (name == "lambda_init" and multiplier != "dual"):
                raise ValueError(f"{name} must be > 0, got {value}")
        if not lambda_init >= 0:
            raise ValueError(f"lambda_init must be >= 0, got {lambda_init}")
        if lambda_init > lambda_max:
            raise ValueError(f"lambda_init must be <= lambda_max, got {lambda_init}")
        if target_entropy != "auto" and not isinstance(target_entropy, int | float):
            raise ValueError(f"target_entropy must be 'auto' or a number, got {target_entropy!r}")
        super().__init__()
        self.convert_to_functional(actor_network, "actor_network")
        self.convert_to_functional(lyapunov_network, "lyapunov_network", create_target_params=True)
        if qvalue_network is not None:
            self.convert_to_functional(qvalue_network, "qvalue_network", create_target_params=True)
        else:
            self.qvalue_network = None
        # the one spec object; the selectors share it (share_spec); in the state dict
        self.spec_state = LyapunovSpecState(
            spec if spec is not None else LyapunovSpec(form=form, alpha=stability_weight)
        )
        self.mode, self.loss_function = mode, loss_function
        self.lambda_max = float(lambda_max)
        self.constraint, self.multiplier = constraint, multiplier
        self.filter_candidates = filter_candidates
        self.pid_gains = tuple(float(gain) for gain in pid_gains)
        self.violation_budget = None if violation_budget is None else float(violation_budget)
        # the dual's parameter (multiplier "dual"); kept for the others so that optimisers
        # and state dicts have one shape
        self.log_lambda = torch.nn.Parameter(torch.tensor(max(float(lambda_init), 1e-8)).log())
        # the PID's and the fixed multiplier's value, integral and last error (state dict)
        self.register_buffer("lambda_value", torch.tensor(float(lambda_init)))
        self.register_buffer("pid_integral", torch.tensor(0.0))
        self.register_buffer("pid_error", torch.tensor(0.0))
        self.log_beta = torch.nn.Parameter(torch.tensor(float(beta_init)).log())
        self._target_entropy = target_entropy
        self._action_spec = action_spec
        self.gamma = 0.99
        self._lyapunov_gamma: float | None = None  # None: the task's gamma
        self.backup = backup
        # by reference, not a submodule: the selector owns the rule and its deviate switch
        self.__dict__["rule"] = rule if rule is not None else SelectionRule()

    # -- configuration ---------------------------------------------------------------------
    @property
    def spec(self) -> LyapunovSpec:
        """The Lyapunov form, prior and stability weight in force: :attr:`spec_state`'s (a
        :class:`~torchrl_auv.modules.LyapunovSpecState`, in this loss's state dict, so a
        checkpoint of the loss restores it). Assigning it (or :meth:`set_lyapunov_spec`)
        sets it for every module given to :meth:`share_spec` too: they hold the same object."""
        return self.spec_state.spec

    @spec.setter
    def spec(self, value: LyapunovSpec) -> None:
        self.spec_state.spec = value

    def set_lyapunov_spec(self, spec: LyapunovSpec) -> None:
        """Switch the form, prior and stability weight; parameters, dual variables and any
        optimiser state are untouched (the critic's raw output is reinterpreted). Modules
        sharing the spec (:meth:`share_spec`) switch with it."""
        self.spec = spec

    def share_spec(self, reader):
        """Make ``reader`` (e.g. a :class:`~torchrl_auv.modules.CandidateSelector` ranking
        with this loss's critic) hold this loss's :attr:`spec_state`: the same object, so an
        advisor's or a checkpoint's spec is the reader's too. Returns ``reader``.

        Examples:
            >>> from torchrl_auv.objectives import CandidateSelector
            >>> from torchrl_auv.training import make_actor, make_env, make_lyapunov_critic
            >>> env = make_env("ideal", seed=0, num_envs=1, max_steps=2)
            >>> critic = make_lyapunov_critic(env, (8,))
            >>> loss = LyapunovActorCriticLoss(make_actor(env, (8,)), critic)
            >>> selector = loss.share_spec(CandidateSelector(critic, mode="lyapunov"))
            >>> loss.set_lyapunov_spec(LyapunovSpec(form="squared", alpha=0.25))
            >>> selector.spec.form, selector.spec.alpha, selector.spec_state is loss.spec_state
            ('squared', 0.25, True)
        """
        if not isinstance(getattr(reader, "spec_state", None), LyapunovSpecState):
            raise ValueError(
                f"reader must hold a LyapunovSpecState as spec_state, got {type(reader).__name__}"
            )
        reader.spec_state = self.spec_state
        return reader

    def make_value_estimator(self, value_type: ValueEstimators = None, **hyperparams):
        """Set the discounts: ``make_value_estimator(ValueEstimators.TD0, gamma=0.995)``.

        ``gamma``: the task critic's discount, and the Lyapunov critic's unless
        ``lyapunov_gamma`` is given (:attr:`lyapunov_gamma`; ``None`` goes back to ``gamma``).
        The targets are one-step (TD(0)) targets; other estimators are refused.

        Examples:
            >>> from torchrl_auv.training import make_actor, make_env, make_lyapunov_critic
            >>> env = make_env("ideal", seed=0, num_envs=1)
            >>> actor, critic = make_actor(env, (8,)), make_lyapunov_critic(env, (8,))
            >>> loss = LyapunovActorCriticLoss(actor, critic)
            >>> loss = loss.make_value_estimator(gamma=0.99, lyapunov_gamma=0.999)
            >>> loss.gamma, loss.lyapunov_gamma
            (0.99, 0.999)
        """
        if value_type not in (None, ValueEstimators.TD0):
            raise ValueError(f"value_type must be ValueEstimators.TD0, got {value_type}")
        gamma = hyperparams.pop("gamma", self.gamma)
        lyapunov_gamma = hyperparams.pop("lyapunov_gamma", self._lyapunov_gamma)
        if hyperparams:
            raise ValueError(f"unknown value estimator arguments {sorted(hyperparams)}")
        for name, value in (("gamma", gamma), ("lyapunov_gamma", lyapunov_gamma)):
            if value is not None and not 0 < value <= 1:
                raise ValueError(f"{name} must be in (0, 1], got {value}")
        self.gamma = float(gamma)
        self._lyapunov_gamma = None if lyapunov_gamma is None else float(lyapunov_gamma)
        return self

    @property
    def lyapunov_gamma(self) -> float:
        r"""The Lyapunov critic's discount (:meth:`make_value_estimator`; default ``gamma``).
        A leg's cost-to-go keeps the decrease condition where :math:`(1 - \gamma_L) L(s')
        < (1 - \alpha) c` (module docstring): a discount nearer 1 widens that region."""
        return self.gamma if self._lyapunov_gamma is None else self._lyapunov_gamma

    def _forward_value_estimator_keys(self, **kwargs) -> None:
        pass

    @property
    def lambda_(self) -> torch.Tensor:
        """The Lagrange multiplier in ``[0, lambda_max]``: ``exp(log_lambda)`` (multiplier
        ``dual``), the PID's output (``pid``) or ``lambda_init`` (``fixed``)."""
        if self.multiplier == "dual":
            return self.log_lambda.exp().clamp(0.0, self.lambda_max)
        return self.lambda_value

    @torch.no_grad()
    def _pid_step(self, error: torch.Tensor) -> None:
        r"""One PID update on the batch's constraint error :math:`e = \mathbb E[\Delta L]`
        (Stooke et al. 2020, Alg. 2): :math:`I \leftarrow \max(0, I + e)`,
        :math:`\lambda = \mathrm{clip}(k_p e + k_i I + k_d \max(0, e - e_{prev}), 0,
        \lambda_{max})`. The integral answers a persistent violation, however small; the
        proportional term a violation now; the derivative a rising one."""
        kp, ki, kd = self.pid_gains
        self.pid_integral.copy_((self.pid_integral + error).clamp_min(0.0))
        rise = (error - self.pid_error).clamp_min(0.0)
        value = kp * error + ki * self.pid_integral + kd * rise
        self.lambda_value.copy_(value.clamp(0.0, self.lambda_max))
        self.pid_error.copy_(error)

    def _clamp_log_lambda(self) -> None:
        """Put ``log_lambda`` itself back at ``log(lambda_max)`` when a dual step pushed it
        past (no windup: once the condition holds, the very next dual step lowers lambda;
        TorchRL's ``SACLoss`` clamps ``log_alpha`` in place the same way)."""
        with torch.no_grad():
            self.log_lambda.clamp_(max=math.log(self.lambda_max))

    @property
    def beta(self) -> torch.Tensor:
        return self.log_beta.exp()

    @property
    def in_keys(self) -> list[NestedKey]:
        keys = [*self.actor_network.in_keys, self.tensor_keys.action]
        keys += [("next", k) for k in self.actor_network.in_keys]
        keys += [("next", self.tensor_keys.reward), ("next", self.tensor_keys.terminated)]
        if self.backup == "candidates":
            keys.append(unravel_key(("next", self.tensor_keys.candidates)))
            if self.rule.anchored:
                keys.append(unravel_key(("next", self.tensor_keys.anchor)))
        return list(dict.fromkeys(keys))

    @property
    def out_keys(self) -> list[str]:
        losses = ["loss_actor", "loss_lyapunov", "loss_lambda", "loss_beta"]
        task = ["loss_qvalue", "qvalue"] if self.qvalue_network is not None else []
        return [
            *losses,
            "lambda",
            "beta",
            "delta_l",
            "violation_rate",
            "lyapunov_value",
            "leg_fraction",
            "negative_cost_fraction",
            *task,
        ]

    # -- pieces ----------------------------------------------------------------------------
    def _sample(self, td: TensorDictBase, params) -> tuple[torch.Tensor, torch.Tensor]:
        """Reparameterised action and its log-probability from the actor with ``params``."""
        with set_exploration_type(ExplorationType.RANDOM), params.to_module(self.actor_network):
            dist = self.actor_network.get_dist(td)
            action = dist.rsample()
            log_prob = dist.log_prob(action)
        if log_prob.dim() == action.dim():  # per-dimension log-probs: sum them
            log_prob = log_prob.sum(-1)
        return action, log_prob

    def _lyapunov(self, td: TensorDictBase, action: torch.Tensor, params) -> torch.Tensor:
        """``L(s, action)`` ``[*B, 1]`` with the critic's ``params``."""
        td = td.select(*self.lyapunov_network.in_keys, strict=False).copy()
        td.set(self.tensor_keys.action, action)
        with params.to_module(self.lyapunov_network):
            raw = _read_out(
                self.lyapunov_network(td),
                self.tensor_keys.value,
                "value",
                "lyapunov_network",
                self.lyapunov_network,
            )
        spec = self.spec_state.last_set  # no tensor read: the update may be compiled
        observation = td.get(self.tensor_keys.observation, None) if spec.prior else None
        return lyapunov_value(raw, spec, observation)

    def _qvalue(self, td: TensorDictBase, action: torch.Tensor, params) -> torch.Tensor:
        """The task critic's ``Q(s, action)`` ``[*B, 1]`` with ``params``."""
        td = td.select(*self.qvalue_network.in_keys, strict=False).copy()
        td.set(self.tensor_keys.action, action)
        with params.to_module(self.qvalue_network):
            return _read_out(
                self.qvalue_network(td),
                self.tensor_keys.qvalue,
                "qvalue",
                "qvalue_network",
                self.qvalue_network,
            )

    def _executed_next(
        self, next_td: TensorDictBase, bound: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """The candidate the selector executes at the next state and its target value
        :math:`L_{target}(s', a')` ``[*B, 1]``: argmin of :math:`L_{target}(s', a'_k)` under
        ``rule``; with ``filter_candidates``, the ``rule``'s choice by the target task critic
        (least :math:`Q_{target}(s', a'_k)`) among the candidates with :math:`L_{target}(s',
        a'_k) \\le` ``bound`` (``[*B, 1]``; ``inf`` where the filter does not apply), and the
        least :math:`L_{target}` where none is (:class:`~torchrl_auv.modules.LyapunovFilter`'s
        rule, with the transition's own :math:`L_{target}(s, a) - \alpha c` as the bound)."""
        candidates, anchor = next_candidates(
            next_td, self.tensor_keys.candidates, self.tensor_keys.anchor, self.rule
        )
        action_key = self.tensor_keys.action
        inputs = {*self.lyapunov_network.in_keys, self.tensor_keys.observation} - {action_key}
        if self.qvalue_network is not None:
            inputs |= set(self.qvalue_network.in_keys) - {action_key}
        td = per_candidate(
            next_td, [k for k in inputs if next_td.get(k, None) is not None], candidates.shape[-2]
        )
        values = self._lyapunov(td, candidates, self.target_lyapunov_network_params)[..., 0]
        if bound is None:
            index = self.rule.choose(-values, -values, anchor)  # [..., K] -> [...]
        else:
            q = self._qvalue(td, candidates, self.target_qvalue_network_params)[..., 0]
            index, _ = filtered_choice(  # the selector's rule (least task cost among the
                self.rule, -q, anchor, values <= bound, values, self.filter_candidates
            )  # candidates that keep the condition, else the least L)
        pick = index[..., None, None].expand(*index.shape, 1, candidates.shape[-1])
        next_action = candidates.gather(-2, pick).squeeze(-2)
        return next_action, values.gather(-1, index.unsqueeze(-1))

    def _cost(self, next_td: TensorDictBase, name: str = "cost") -> torch.Tensor:
        """The cost under the ``name`` key (``cost`` or ``task_cost``); when the data lack it,
        ``-reward`` if the key is the default, else a ``ValueError`` (a key set with
        ``set_keys`` that the data do not have is a typo, not a request for ``-reward``)."""
        key = getattr(self.tensor_keys, name)
        cost = next_td.get(key, None)
        if cost is not None:
            return cost
        if key != getattr(self.default_keys(), name):
            have = sorted(str(k) for k in next_td.keys(True, True))
            raise ValueError(
                f"the {name} key {key!r} (set with set_keys) is not in the data's "
                f"'next' entry, which has {have}"
            )
        reward = next_td.get(self.tensor_keys.reward, None)
        if reward is None:
            raise ValueError(
                f"neither the {name} key {key!r} nor the reward key "
                f"{self.tensor_keys.reward!r} is in the data's 'next' entry"
            )
        return -reward

    def _td_loss(
        self, value: torch.Tensor, target: torch.Tensor, weight: torch.Tensor | None = None
    ) -> torch.Tensor:
        """The critics' TD loss (``loss_function``), averaged over the samples of weight 1
        (``weight``: the approach mask, default all)."""
        if self.loss_function == "l2":
            errors = 0.5 * (value - target).square()
        else:
            errors = torch.nn.functional.smooth_l1_loss(value, target, reduction="none")
        if weight is None:
            return errors.mean()
        return (errors * weight).sum() / weight.sum().clamp_min(1.0)

    def _legs(
        self, next_td: TensorDictBase, cost: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """``(on_leg, at_equilibrium)`` as float masks shaped like ``cost``: the transitions
        the Lyapunov critic and the decrease condition are about (the ``approach`` key; all
        when the data have none) and those that reach the absorbing equilibrium (the
        ``equilibrium`` key, where :math:`L(s') = 0`; none when absent). A key set with
        ``set_keys`` that the data lack is a ``ValueError``, not a request for the default."""
        masks = []
        for name, default in (("approach", 1.0), ("equilibrium", 0.0)):
            key = getattr(self.tensor_keys, name)
            flag = next_td.get(key, None)
            if flag is None and key != getattr(self.default_keys(), name):
                have = sorted(str(k) for k in next_td.keys(True, True))
                raise ValueError(
                    f"the {name} key {key!r} (set with set_keys) is not in the data's 'next' "
                    f"entry, which has {have}: store it (training.LEG_KEYS)"
                )
            masks.append(
                torch.full_like(cost, default)
                if flag is None
                else flag.to(cost.dtype).expand_as(cost)
            )
        return masks[0], masks[1]

    def forward(self, tensordict: TensorDictBase) -> TensorDict:
        self._clamp_log_lambda()
        td = tensordict.copy()  # never modify the caller's data
        next_td = td.get("next", None)
        if next_td is None:
            raise ValueError("the input must hold a 'next' entry (a transition)")
        for key in self.lyapunov_network.in_keys:
            if key != self.tensor_keys.action and td.get(key, None) is None:
                raise ValueError(f"key {key!r} read by the lyapunov_network is missing")
        cost = self._cost(next_td)
        terminated = next_td.get(self.tensor_keys.terminated, None)
        if terminated is None:
            raise ValueError(f"key ('next', {self.tensor_keys.terminated!r}) is missing")
        on_leg, at_equilibrium = self._legs(next_td, cost)
        action = td.get(self.tensor_keys.action)
        actor_params = self.actor_network_params
        critic_params = self.lyapunov_network_params
        frozen_critic = critic_params.detach()

        # critic: L(s, a) towards c + gamma (1 - terminated) (1 - equilibrium) L_target(s', a')
        continues = 1 - terminated.to(cost.dtype)
        leg_continues = continues * (1 - at_equilibrium)
        with torch.no_grad():
            if self.backup == "candidates":
                bound = None
                if self.filter_candidates:  # the filter applies on a leg that goes on
                    own = self._lyapunov(td, action, self.target_lyapunov_network_params)
                    alpha = self.spec_state.last_set.alpha
                    applies = (on_leg * leg_continues) > 0
                    bound = torch.where(applies, own - alpha * cost, torch.inf)
                next_action, next_value = self._executed_next(next_td, bound)
            else:
                next_action, _ = self._sample(next_td, actor_params.detach())
                next_value = self._lyapunov(
                    next_td, next_action, self.target_lyapunov_network_params
                )
            target = cost + self.lyapunov_gamma * leg_continues * next_value
        value = self._lyapunov(td, action, critic_params)
        loss_lyapunov = self._td_loss(value, target, on_leg)

        # actor: lambda * DeltaL + beta * log pi, gradient through the sampled actions only
        new_action, log_prob = self._sample(td, actor_params)
        if self.mode == "lac":
            policy_next, _ = self._sample(next_td, actor_params)
            after = self._lyapunov(next_td, policy_next, frozen_critic)
        else:
            after = self._lyapunov(td, new_action, frozen_critic)
        # L is 0 at an absorbing state (an episode's end, a leg's equilibrium)
        if self.mode == "lac":
            after = leg_continues * after
        delta = after - value.detach() + self.spec_state.last_set.alpha * cost
        legs = on_leg.sum().clamp_min(1.0)

        def over_legs(x: torch.Tensor) -> torch.Tensor:  # the mean over approach transitions
            return (x * on_leg).sum() / legs

        mean_delta = over_legs(delta)
        violation_rate = over_legs((delta.detach() > 0).to(delta.dtype))
        if self.multiplier == "pid" and self.training:
            if self.violation_budget is None:
                self._pid_step(mean_delta.detach())
            else:  # the chance constraint P(Delta L > 0) <= budget
                self._pid_step(violation_rate - self.violation_budget)
        owed = mean_delta if self.constraint == "mean" else over_legs(delta.clamp_min(0))
        loss_actor = self.lambda_.detach() * owed + self.beta.detach() * log_prob.mean()
        task = {}
        if self.qvalue_network is not None:  # the task: a Q critic on task_cost
            task_cost = self._cost(next_td, "task_cost")
            with torch.no_grad():
                next_q = self._qvalue(next_td, next_action, self.target_qvalue_network_params)
                q_target = task_cost + self.gamma * continues * next_q
            q = self._qvalue(td, action, self.qvalue_network_params)
            policy_q = self._qvalue(td, new_action, self.qvalue_network_params.detach())
            loss_actor = loss_actor + policy_q.mean()
            task = {"loss_qvalue": self._td_loss(q, q_target), "qvalue": q.detach().mean()}

        # duals (the multiplier's only with multiplier "dual")
        if self.multiplier == "dual":
            loss_lambda = -self.log_lambda * mean_delta.detach()
        else:
            loss_lambda = (self.log_lambda * 0.0).detach()
        target_entropy = self._target_entropy_value(new_action)
        loss_beta = -self.log_beta * (log_prob + target_entropy).detach().mean()
        return TensorDict(
            {
                "loss_actor": loss_actor,
                "loss_lyapunov": loss_lyapunov,
                "loss_lambda": loss_lambda,
                "loss_beta": loss_beta,
                "lambda": self.lambda_.detach(),
                "beta": self.beta.detach(),
                "delta_l": mean_delta.detach(),
                "violation_rate": violation_rate,
                "lyapunov_value": over_legs(value.detach()),
                "leg_fraction": on_leg.mean(),
                "negative_cost_fraction": (cost < 0).float().mean(),
                **task,
            },
            batch_size=[],
        )

    def _target_entropy_value(self, action: torch.Tensor) -> float:
        if self._target_entropy != "auto":
            return float(self._target_entropy)
        if self._action_spec is not None:
            return -float(self._action_spec.shape[-1])
        return -float(action.shape[-1])
