r"""``CandidateSelector``: pick one of the proposer's candidates with a critic ("filtering").

Paper §III-B: the diffusion proposer's K candidate chunks are scored by a critic on their first
action, :math:`Q(s, a_k)` ("Diffusion+RL", eq. 15: argmax) or the Lyapunov value
:math:`L(s, a_k)` ("Diffusion+RL (LAC)": argmin, the optimal action OA); the chosen first action
is executed. At one state, argmin :math:`L(s, a_k)` is also argmin :math:`\Delta L` in the
paper's form :math:`L(s, a_k) - L(s, a) + \alpha c` (the other terms do not depend on the
candidate), so one Lyapunov mode serves both. Optionally the actor's own action joins as one
more candidate. Exploration: a softmax over the scores with a temperature, or epsilon-greedy.
The ranking (best first) is kept so that OA, CA1 ... CA4 of the paper's Fig. 8/9 are
recoverable. A :class:`~torchrl_auv.modules.SelectionRule` anchored on the medoid makes the
choice a safe improvement on the prior: the prior's consensus candidate unless a candidate
beats it by more than the critic ensemble's disagreement.
"""

from __future__ import annotations

import torch
from tensordict import NestedKey, TensorDict, TensorDictBase, unravel_key
from tensordict.nn import TensorDictModuleBase

from torchrl_auv.modules.consensus import medoid_index
from torchrl_auv.modules.lyapunov_filter import INFEASIBLE_SCORE, LyapunovFilter, filtered_choice
from torchrl_auv.modules.lyapunov_forms import LyapunovSpec, LyapunovSpecState, lyapunov_value
from torchrl_auv.modules.selection_rule import SelectionRule

__all__ = ["INFEASIBLE_SCORE", "SELECTION_MODES", "CandidateSelector"]

SELECTION_MODES = ("q", "lyapunov", "cost")


class CandidateSelector(TensorDictModuleBase):
    """Score candidates with a critic and write the chosen action.

    Key contract: reads ``candidates_key`` ``[*B, K, H, A]`` (or ``[*B, K, A]``),
    ``observation_key`` ``[*B, d]`` and, with ``include_actor_action``, ``actor_action_key``
    ``[*B, A]``; writes ``action_key`` ``[*B, A]`` (the chosen first action) and under
    ``("selector", ...)`` next to the candidates: ``index`` ``[*B]`` (int64; ``K`` is the
    actor's action), ``scores`` ``[*B, K(+1)]`` (higher is better: :math:`Q` or :math:`-L`) and
    ``ranking`` ``[*B, K(+1)]`` (candidate indices, best first: OA, CA1, ...); with an
    anchored ``rule`` also ``anchor`` ``[*B]`` (the medoid's index among the K candidates).
    The executed ``index`` is ``ranking[..., 0]`` unless the rule keeps the anchor.

    Args:
        critic: a module reading the observation and ``critic_action_key`` and writing
            ``critic_out_key`` (TorchRL's ``ValueOperator``: ``state_action_value``, but
            ``state_value`` when its action key is nested, e.g. ``("agents", "action")``). A
            critic that does not write ``critic_out_key`` raises a ``KeyError`` naming the key
            and the keys the critic wrote.
        mode: ``"q"`` (argmax Q), ``"lyapunov"`` (argmin L, the raw output through ``spec``)
            or ``"cost"`` (argmin of a critic of a cost, e.g. LAC's task critic).
        spec: the Lyapunov form (mode ``"lyapunov"``; default softplus).
        exploration: ``None``, ``"softmax"`` (sample from softmax(scores / temperature)) or
            ``"epsilon"`` (a uniformly random candidate with probability ``epsilon``).
        temperature, epsilon: exploration parameters.
        include_actor_action: score the actor's action as one more candidate.
        generator: source of exploration draws.
        rule: which scored candidate is executed
            (:class:`~torchrl_auv.modules.SelectionRule`; default: the best). With a critic
            that has ``members`` (:class:`~torchrl_auv.modules.QEnsembleCritic`, mode
            ``"q"``) the rule compares the reduced score with the members' maximum.
        constraint: a :class:`~torchrl_auv.modules.LyapunovFilter`: where it applies, only
            the candidates that keep the decrease condition may be executed (the others
            score :data:`INFEASIBLE_SCORE` before the rule), and where none does, the one of
            least :math:`L` (where the rule may leave its anchor,
            :attr:`~torchrl_auv.modules.SelectionRule.may_leave_anchor`: during a warm-up the
            anchored rule's anchor acts); writes ``("selector", "feasible")`` and ``("selector",
            "lyapunov")`` (each candidate's :math:`L(s, a_k)`) ``[*B, K]``.

    Examples:
        >>> from torchrl.modules import MLP, ValueOperator
        >>> critic = ValueOperator(MLP(in_features=5, out_features=1, num_cells=[8]),
        ...                        in_keys=["observation", "action"])
        >>> selector = CandidateSelector(critic, mode="q")
        >>> td = TensorDict({"observation": torch.zeros(2, 3),
        ...                  ("proposer", "candidates"): torch.rand(2, 5, 8, 2)}, batch_size=[2])
        >>> selector(td)["action"].shape, td["selector", "ranking"].shape
        (torch.Size([2, 2]), torch.Size([2, 5]))
    """

    def __init__(
        self,
        critic: TensorDictModuleBase,
        *,
        mode: str = "q",
        spec: LyapunovSpec | None = None,
        exploration: str | None = None,
        temperature: float = 1.0,
        epsilon: float = 0.1,
        include_actor_action: bool = False,
        candidates_key: NestedKey = ("proposer", "candidates"),
        observation_key: NestedKey = "observation",
        action_key: NestedKey = "action",
        actor_action_key: NestedKey = ("actor", "action"),
        critic_action_key: NestedKey = "action",
        critic_out_key: NestedKey = "state_action_value",
        generator: torch.Generator | None = None,
        rule: SelectionRule | None = None,
        constraint: LyapunovFilter | None = None,
    ) -> None:
        super().__init__()
        if mode not in SELECTION_MODES:
            raise ValueError(f"mode must be one of {SELECTION_MODES}, got {mode!r}")
        if exploration not in (None, "softmax", "epsilon"):
            raise ValueError(
                f"exploration must be None, 'softmax' or 'epsilon', got {exploration!r}"
            )
        if not temperature > 0:
            raise ValueError(f"temperature must be > 0, got {temperature}")
        if not 0 <= epsilon <= 1:
            raise ValueError(f"epsilon must be in [0, 1], got {epsilon}")
        self.critic = critic
        # the spec as a buffer module (shared with the loss that owns it, share_spec): it
        # travels with the weights TorchRL's collectors copy to worker processes and Ray actors
        self.spec_state = LyapunovSpecState(spec)
        self.mode = mode
        self.exploration, self.temperature, self.epsilon = exploration, temperature, epsilon
        self.include_actor_action = include_actor_action
        self.generator = generator
        self.rule = rule if rule is not None else SelectionRule()
        if constraint is not None and constraint.mode == "veto" and not self.rule.anchored:
            raise ValueError(
                "a LyapunovFilter in mode 'veto' keeps the rule's anchor where it is feasible: "
                "it needs an anchored rule (SelectionRule(anchor='medoid'))"
            )
        self.constraint = constraint
        self.candidates_key = unravel_key(candidates_key)
        self.observation_key = unravel_key(observation_key)
        self.action_key = unravel_key(action_key)
        self.actor_action_key = unravel_key(actor_action_key)
        self.critic_action_key = unravel_key(critic_action_key)
        self.critic_out_key = unravel_key(critic_out_key)
        prefix = self.candidates_key[:-2] if isinstance(self.candidates_key, tuple) else ()
        self.selector_key = (*prefix, "selector")
        self.in_keys = [self.candidates_key, self.observation_key]
        if include_actor_action:
            self.in_keys.append(self.actor_action_key)
        self.out_keys = [self.action_key] + [
            (*self.selector_key, k) for k in ("index", "scores", "ranking")
        ]
        if self.rule.anchored:
            self.out_keys.append((*self.selector_key, "anchor"))
        if constraint is not None:
            self.out_keys += [(*self.selector_key, "feasible"), (*self.selector_key, "lyapunov")]

    @property
    def spec(self) -> LyapunovSpec:
        """The Lyapunov form (mode ``"lyapunov"``): :attr:`spec_state`'s, a
        :class:`~torchrl_auv.modules.LyapunovSpecState` (the loss's own when shared with
        :meth:`~torchrl_auv.objectives.LyapunovActorCriticLoss.share_spec`). A copy whose
        weights were loaded, or synced by a collector, follows them.

        Examples:
            >>> from torchrl.modules import MLP, ValueOperator
            >>> critic = ValueOperator(MLP(in_features=3, out_features=1, num_cells=[4]),
            ...                        in_keys=["observation", "action"])
            >>> a, b = CandidateSelector(critic, mode="lyapunov"), CandidateSelector(critic)
            >>> a.spec = LyapunovSpec(form="squared", alpha=0.25)
            >>> _ = b.load_state_dict(a.state_dict())
            >>> b.spec.form, b.spec.alpha
            ('squared', 0.25)
        """
        return self.spec_state.spec

    @spec.setter
    def spec(self, value: LyapunovSpec) -> None:
        self.spec_state.spec = value

    def scores(self, observation: torch.Tensor, actions: torch.Tensor) -> torch.Tensor:
        """Scores ``[*B, K]`` (higher is better) of first actions ``[*B, K, A]``."""
        return self.score_bounds(observation, actions)[0]

    def score_bounds(
        self, observation: torch.Tensor, actions: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """The scores ``[*B, K]`` (:meth:`scores`) and an optimistic bound on them: the
        maximum over the critic's members where it has them (``mode="q"``), else the scores."""
        return self.member_scores(observation, actions)[:2]

    def member_scores(
        self, observation: torch.Tensor, actions: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """:meth:`score_bounds` and each member's scores ``[n, *B, K]`` (``n`` = 1 for a
        critic without members, or the Lyapunov critic)."""
        k = actions.shape[-2]
        obs = observation.unsqueeze(-2).expand(*observation.shape[:-1], k, observation.shape[-1])
        td = TensorDict(
            {self.observation_key: obs, self.critic_action_key: actions},
            batch_size=actions.shape[:-1],
        )
        members = getattr(self.critic, "members", None)
        if self.mode == "q" and members is not None:
            values = members(td)[..., 0]  # [n, *B, K]
            reduced = values.min(0).values if self.critic.reduce == "min" else values.mean(0)
            return reduced, values.max(0).values, values
        with torch.no_grad():
            out = self.critic(td)
        raw = out.get(self.critic_out_key, None)
        if raw is None:
            raise self._missing_critic_output(out)
        if self.mode in ("q", "cost"):
            score = raw[..., 0] if self.mode == "q" else -raw[..., 0]
            return score, score, score.unsqueeze(0)
        spec = self.spec
        score = -lyapunov_value(raw, spec, obs if spec.prior else None)[..., 0]
        return score, score, score.unsqueeze(0)

    def _missing_critic_output(self, out: TensorDictBase) -> KeyError:
        """The error for a critic that did not write ``critic_out_key``: names what it wrote."""
        inputs = {self.observation_key, self.critic_action_key}
        written = sorted(
            (k for k in out.keys(include_nested=True, leaves_only=True) if k not in inputs), key=str
        )
        declared = getattr(self.critic, "out_keys", None)
        return KeyError(
            f"CandidateSelector: the critic did not write critic_out_key "
            f"{self.critic_out_key!r}; the keys it wrote are {written}"
            + (f" (its out_keys: {list(declared)})" if declared is not None else "")
            + ". Pass the critic's output key as critic_out_key=... (TorchRL's ValueOperator "
            "names its output 'state_value', not 'state_action_value', when its action key is "
            "nested, e.g. ('agents', 'action'))"
        )

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        candidates = tensordict.get(self.candidates_key, None)
        if candidates is None:
            raise ValueError(f"candidates_key {self.candidates_key!r} is missing from the input")
        observation = tensordict.get(self.observation_key)
        chunked = candidates.dim() >= observation.dim() + 2  # [*B, K, H, A], else [*B, K, A]
        first = candidates[..., 0, :] if chunked else candidates
        if self.include_actor_action:
            own = tensordict.get(self.actor_action_key, None)
            if own is None:
                raise ValueError(f"actor_action_key {self.actor_action_key!r} is missing")
            first = torch.cat([first, own.unsqueeze(-2)], -2)
        scores, upper, members = self.member_scores(observation, first)
        anchor = None
        if self.rule.anchored:
            anchor = medoid_index(candidates if chunked else candidates.unsqueeze(-2))
        if self.constraint is not None:  # feasible already holds where the filter is off
            feasible, values, _ = self.constraint(tensordict, first)
            index, scores = filtered_choice(
                self.rule,
                scores,
                anchor,
                feasible,
                values,
                self.constraint.mode,
                upper=upper,
                members=members,
            )
            tensordict.set((*self.selector_key, "feasible"), feasible)
            tensordict.set((*self.selector_key, "lyapunov"), values)
            ranking = scores.argsort(-1, descending=True)
        else:
            ranking = scores.argsort(-1, descending=True)
            index = ranking[..., 0]
            if self.rule.anchored:
                index = self.rule.choose(scores, upper, anchor, members=members)
        if self.rule.anchored:
            tensordict.set((*self.selector_key, "anchor"), anchor)
        # draws on the generator's device (a CPU generator for a selector on a GPU)
        draw_on = scores.device if self.generator is None else self.generator.device
        if self.exploration == "softmax":
            probs = torch.softmax(scores / self.temperature, -1)
            flat = probs.reshape(-1, probs.shape[-1]).to(draw_on)
            index = torch.multinomial(flat, 1, generator=self.generator).reshape(index.shape)
            index = index.to(scores.device)
        elif self.exploration == "epsilon":
            shape, n = index.shape, scores.shape[-1]
            explore = torch.rand(shape, generator=self.generator, device=draw_on) < self.epsilon
            random = torch.randint(0, n, shape, generator=self.generator, device=draw_on)
            index = torch.where(explore.to(scores.device), random.to(scores.device), index)
        chosen = torch.gather(
            first, -2, index[..., None, None].expand(*index.shape, 1, first.shape[-1])
        )
        tensordict.set(self.action_key, chosen.squeeze(-2))
        tensordict.set((*self.selector_key, "index"), index)
        tensordict.set((*self.selector_key, "scores"), scores)
        tensordict.set((*self.selector_key, "ranking"), ranking)
        return tensordict
