r"""SAC and LAC for a residual actor on the prior's choice, held near it.

A residual actor (:func:`~torchrl_auv.training.make_residual_actor`) samples the executed
action from a ``TanhNormal`` on :math:`[a_0 - b, a_0 + b]`, with :math:`a_0` the prior's
choice (the proposer alone's action) and :math:`b` the residual bound: its deterministic action
is :math:`a_0 + b \tanh(\mu)`, the prior's own where :math:`\mu = 0`. It is the policy that
acts, so TorchRL's ``SACLoss`` (:class:`ResidualSACLoss`) or the Lyapunov actor-critic
(:class:`ResidualLACLoss`) trains it and its critics unchanged (the critics bootstrap on its
next action, which is what is executed). :class:`ResidualPenalty` adds a pull toward the prior,

.. math::

    \mathcal L_{res} = c\, \mathbb E\big[\lVert (\bar a - m) / h \rVert^2 / A\big],

with :math:`\bar a` the actor's deterministic action, :math:`m` and :math:`h` the centre and
half-width of its bounds (the prior's action and :math:`b`), :math:`A` the action's size: a
residual in units of its bound, zero at the prior, at most :math:`c` (``coef``, in the
critic's units: a residual at its bound must buy that much Q).

Examples:
    >>> from tensordict import TensorDict
    >>> from tensordict.nn import NormalParamExtractor, TensorDictModule, TensorDictSequential
    >>> from torchrl.modules import MLP, ProbabilisticActor, TanhNormal, ValueOperator
    >>> net = torch.nn.Sequential(MLP(4, 2, num_cells=[8]), NormalParamExtractor())
    >>> body = TensorDictModule(lambda o, p: net(torch.cat([o, p], -1)),
    ...                         ["observation", "prior"], ["loc", "scale"])
    >>> bounds = TensorDictModule(lambda p: (p - 0.2, p + 0.2), ["prior"], ["low", "high"])
    >>> actor = ProbabilisticActor(TensorDictSequential(body, bounds),
    ...     in_keys=["loc", "scale", "low", "high"], distribution_class=TanhNormal)
    >>> q = ValueOperator(MLP(4, 1, num_cells=[8]), ["observation", "action"])
    >>> loss = ResidualSACLoss(actor, q, coef=1.0, target_entropy=-1.0)
    >>> td = TensorDict({"observation": torch.randn(6, 3), "prior": torch.zeros(6, 1),
    ...     "action": torch.zeros(6, 1), "next": {"observation": torch.randn(6, 3),
    ...     "prior": torch.zeros(6, 1), "reward": torch.zeros(6, 1),
    ...     "done": torch.zeros(6, 1, dtype=torch.bool),
    ...     "terminated": torch.zeros(6, 1, dtype=torch.bool)}}, [6])
    >>> out = loss(td)
    >>> 0 <= out["loss_residual"].item() <= 1.0, out["residual"].shape
    (True, torch.Size([]))
"""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from torchrl.envs.utils import ExplorationType, set_exploration_type

from torchrl_auv.objectives.candidate_backup import CandidateBackupSACLoss
from torchrl_auv.objectives.lyapunov import LyapunovActorCriticLoss

__all__ = ["ResidualLACLoss", "ResidualPenalty", "ResidualSACLoss", "residual_offset"]


def residual_offset(dist) -> torch.Tensor:
    """The deterministic action's offset from the centre of a bounded distribution's support,
    in half-widths (``[..., A]``, in [-1, 1]): for a residual actor, the residual in units of
    its bound. ``dist`` has ``low``, ``high`` and ``deterministic_sample`` (TorchRL's
    ``TanhNormal``)."""
    centre, half = (dist.high + dist.low) / 2, (dist.high - dist.low) / 2
    return (dist.deterministic_sample - centre) / half


class ResidualPenalty:
    """Mixin for a TorchRL ``LossModule`` with an ``actor_network`` (a bounded residual actor):
    its ``forward`` adds ``loss_residual`` (module docstring) and the logged ``residual`` (the
    mean absolute offset, in bounds) to the loss's own outputs.

    Args:
        *args: the loss's positional arguments.
        coef: the weight ``c >= 0`` of the pull toward the prior (0: none).
        **kwargs: the loss's keyword arguments.
    """

    def __init__(self, *args, coef: float = 1.0, **kwargs) -> None:
        if isinstance(coef, bool) or not isinstance(coef, int | float) or not coef >= 0:
            raise ValueError(f"coef must be a number >= 0, got {coef!r}")
        super().__init__(*args, **kwargs)
        self.coef = float(coef)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        out = super().forward(tensordict)
        actor = self.actor_network
        with (
            set_exploration_type(ExplorationType.DETERMINISTIC),
            self.actor_network_params.to_module(actor),
        ):
            dist = actor.get_dist(tensordict.select(*actor.in_keys))
        offset = residual_offset(dist)
        out.set("loss_residual", self.coef * offset.pow(2).mean())
        out.set("residual", offset.detach().abs().mean())
        return out


class ResidualSACLoss(ResidualPenalty, CandidateBackupSACLoss):
    """TorchRL's ``SACLoss`` (through :class:`CandidateBackupSACLoss`, ``backup="actor"`` by
    default: the residual actor acts) with :class:`ResidualPenalty`'s pull toward the prior
    (``coef``)."""


class ResidualLACLoss(ResidualPenalty, LyapunovActorCriticLoss):
    """:class:`~torchrl_auv.objectives.LyapunovActorCriticLoss` (``backup="actor"``: the
    residual actor acts, so the Lyapunov critic and its constraint are on the executed action)
    with :class:`ResidualPenalty`'s pull toward the prior (``coef``)."""
