r"""Critics that evaluate the policy that acts: a TD backup over the next state's candidates.

In the diffusion frameworks the executed action is a :class:`~torchrl_auv.objectives.
CandidateSelector`'s choice among the proposer's K candidates, not the actor's sample. A critic
bootstrapped on the actor's next action learns :math:`Q(s, a) \approx c + \gamma V^{actor}(s')`,
the value of a controller that never acts, and the selection ranks candidates by it. With the
next state's candidates :math:`a'_1 \dots a'_K` stored beside each transition, the backup
follows the executed policy instead (``backup="candidates"``):

.. math::

    y = r + \gamma (1 - d)\, \underline Q'(s', a'_{k^*}),\qquad
    k^* = \mathrm{rule}(\underline Q'(s', a'_\cdot), \overline Q'(s', a'_\cdot),
    \mathrm{anchor}(s')),

with :math:`\underline Q', \overline Q'` the minimum and maximum over the target Q ensemble and
``rule`` the :class:`~torchrl_auv.modules.SelectionRule` the selector acts with (argmax: the
expected-max-Q backup of EMaQ, Ghasemipour et al. 2021; anchored: the medoid unless a candidate
dominates it). The proposer is the behaviour prior, so the candidates stand for the policy's
support; no actor sample and no entropy term enter the target.

:class:`CandidateBackupSACLoss` is TorchRL's ``SACLoss`` with that target (its actor and
temperature losses unchanged); :class:`~torchrl_auv.objectives.LyapunovActorCriticLoss` takes
the same ``backup`` argument.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import torch
from tensordict import NestedKey, TensorDict, TensorDictBase
from torchrl.objectives import SACLoss

from torchrl_auv.modules.selection_rule import SelectionRule

__all__ = ["BACKUPS", "CandidateBackupSACLoss", "per_candidate"]

#: ``backup`` values: bootstrap on the actor's next action, or on the executed candidate
BACKUPS = ("actor", "candidates")


def check_backup(backup: str) -> None:
    if backup not in BACKUPS:
        raise ValueError(f"backup must be one of {BACKUPS}, got {backup!r}")


def per_candidate(td: TensorDictBase, keys: Iterable[NestedKey], k: int) -> TensorDict:
    """``td``'s entries under ``keys`` (each ``[..., d]``) repeated for ``k`` candidates as
    ``[..., k, d]`` (a view), batch size ``[]``: the inputs of a critic scoring candidates
    ``[..., k, A]`` (the candidate dim just before the feature dim, as the proposer writes it).

    >>> td = TensorDict({"observation": torch.zeros(4, 2, 3)}, [4])
    >>> per_candidate(td, ["observation"], 5)["observation"].shape
    torch.Size([4, 2, 5, 3])
    """
    out = {}
    for key in keys:
        value = td.get(key, None)
        if value is None:
            raise ValueError(f"the critic reads {key!r}, which is missing from the next state")
        out[key] = value.unsqueeze(-2).expand(*value.shape[:-1], k, value.shape[-1])
    return TensorDict(out, batch_size=[])


def next_candidates(
    next_td: TensorDictBase, candidates_key: NestedKey, anchor_key: NestedKey, rule: SelectionRule
) -> tuple[torch.Tensor, torch.Tensor | None]:
    """The next state's candidate first actions ``[..., K, A]`` and, for an anchored ``rule``,
    the anchor's index ``[...]``; a ``ValueError`` naming the key the data lack."""
    candidates = next_td.get(candidates_key, None)
    if candidates is None:
        raise ValueError(
            f"backup='candidates' reads the next state's candidates from "
            f"('next', {candidates_key!r}), which the data lack: store them "
            "(torchrl_auv.training.with_next_candidates)"
        )
    anchor = None
    if rule.anchored:
        anchor = next_td.get(anchor_key, None)
        if anchor is None:
            raise ValueError(
                f"an anchored rule reads the next state's anchor from "
                f"('next', {anchor_key!r}), which the data lack"
            )
    return candidates, anchor


class CandidateBackupSACLoss(SACLoss):
    """TorchRL's ``SACLoss`` (v2: twin Q, no value network) whose Q target bootstraps on the
    executed candidate of the next state (module docstring) when ``backup="candidates"``;
    ``backup="actor"`` is ``SACLoss`` itself.

    Args:
        *args: ``SACLoss``'s positional arguments.
        **kwargs: ``SACLoss``'s keyword arguments.
        backup: one of :data:`BACKUPS`.
        rule: the :class:`~torchrl_auv.modules.SelectionRule` the selector acts with
            (kept by reference: its ``deviate`` switch reaches the target; default argmax).
        reward_from: ``None`` (the ``reward`` key, SACLoss's) or a cost key under ``"next"``
            whose negative is the reward the Q critics learn (e.g. a stability cost: the
            critics then rank by it, the actor maximises it).

    Keys (``set_keys``, read under ``"next"``): SACLoss's, plus ``candidates`` (first actions
    ``[*B, K, A]``, default ``("proposer", "first_actions")``) and ``anchor`` (``[*B]``,
    default ``("proposer", "medoid")``; an anchored rule only).

    Examples:
        >>> from tensordict.nn import NormalParamExtractor, TensorDictModule
        >>> from torchrl.modules import MLP, ProbabilisticActor, TanhNormal, ValueOperator
        >>> net = torch.nn.Sequential(MLP(3, 2, num_cells=[8]), NormalParamExtractor())
        >>> actor = ProbabilisticActor(TensorDictModule(net, ["observation"], ["loc", "scale"]),
        ...     in_keys=["loc", "scale"], distribution_class=TanhNormal)
        >>> q = ValueOperator(MLP(4, 1, num_cells=[8]), ["observation", "action"])
        >>> loss = CandidateBackupSACLoss(actor, q, backup="candidates", target_entropy=-1.0)
        >>> td = TensorDict({"observation": torch.randn(6, 3), "action": torch.rand(6, 1),
        ...     "next": {"observation": torch.randn(6, 3), "reward": torch.zeros(6, 1),
        ...              "done": torch.zeros(6, 1, dtype=torch.bool),
        ...              "terminated": torch.zeros(6, 1, dtype=torch.bool),
        ...              ("proposer", "first_actions"): torch.rand(6, 5, 1)}}, [6])
        >>> loss(td)["loss_qvalue"].shape
        torch.Size([])
    """

    @dataclass
    class _AcceptedKeys(SACLoss._AcceptedKeys):
        """SACLoss's keys and the next state's candidates and anchor."""

        candidates: NestedKey = ("proposer", "first_actions")
        anchor: NestedKey = ("proposer", "medoid")

    default_keys = _AcceptedKeys

    def __init__(
        self,
        *args,
        backup: str = "actor",
        rule: SelectionRule | None = None,
        reward_from: NestedKey | None = None,
        **kwargs,
    ) -> None:
        check_backup(backup)
        super().__init__(*args, **kwargs)
        self.backup = backup
        self.reward_from = reward_from
        # by reference, not a submodule: the selector owns the rule and its deviate switch
        self.__dict__["rule"] = rule if rule is not None else SelectionRule()

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        if self.reward_from is not None:  # the critics learn -cost of that key
            cost = tensordict.get(("next", self.reward_from), None)
            if cost is None:
                raise ValueError(
                    f"reward_from {self.reward_from!r} is not in the data's 'next' entry"
                )
            tensordict = tensordict.clone(False)
            tensordict.set(("next", self.tensor_keys.reward), -cost)
        return super().forward(tensordict)

    def _compute_target_v2(self, tensordict: TensorDictBase) -> torch.Tensor:
        if self.backup == "actor":
            return super()._compute_target_v2(tensordict)
        tensordict = tensordict.clone(False)
        with torch.no_grad():
            next_td = tensordict.get("next")
            candidates, anchor = next_candidates(
                next_td, self.tensor_keys.candidates, self.tensor_keys.anchor, self.rule
            )
            action_key = self.tensor_keys.action
            inputs = [key for key in self.qvalue_network.in_keys if key != action_key]
            td = per_candidate(next_td, inputs, candidates.shape[-2])
            td.set(action_key, candidates)
            values = self._vmap_qnetworkN0(td, self.target_qvalue_network_params)
            members = values.get(self.tensor_keys.state_action_value)[..., 0]  # [n, ..., K]
            lower, upper = members.min(0).values, members.max(0).values
            index = self.rule.choose(lower, upper, anchor, members=members)
            next_value = lower.gather(-1, index.unsqueeze(-1))  # [..., 1]
            tensordict.set(("next", self.value_estimator.tensor_keys.value), next_value)
            return self.value_estimator.value_estimate(tensordict).squeeze(-1)
