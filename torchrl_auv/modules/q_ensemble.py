r"""``QEnsembleCritic``: the Q critic that filters candidates, trained by TorchRL's SAC or TD3.

The paper's "Diffusion+RL" (§III-B, eq. 15) scores the proposer's candidates with a learned
:math:`Q(s, a)`. We do not rewrite Q-learning: TorchRL's ``SACLoss`` or ``TD3Loss`` trains the
critic (clipped double Q, target networks found by ``SoftUpdate``). One catch makes this adapter
necessary: those losses copy the critic into an ensemble of ``num_qvalue_nets`` parameter sets
(``loss.qvalue_network_params``), so the module the user passed in keeps its *initial*
weights. ``QEnsembleCritic.from_loss(loss)`` reads the loss's live ensemble (no copy: it follows
training) and reduces it, by default to the minimum, the same pessimistic estimate SAC and TD3
bootstrap from.

Examples:
    >>> import torch
    >>> from tensordict import TensorDict
    >>> from torchrl.modules import MLP, ValueOperator
    >>> from torchrl.objectives import TD3Loss
    >>> from torchrl.data import Bounded
    >>> from tensordict.nn import TensorDictModule
    >>> actor = TensorDictModule(MLP(in_features=3, out_features=1, num_cells=[8]),
    ...                          in_keys=["observation"], out_keys=["action"])
    >>> q = ValueOperator(MLP(in_features=4, out_features=1, num_cells=[8]),
    ...                   in_keys=["observation", "action"])
    >>> loss = TD3Loss(actor, q, action_spec=Bounded(-1.0, 1.0, shape=(1,)))
    >>> critic = QEnsembleCritic.from_loss(loss)
    >>> td = TensorDict({"observation": torch.zeros(4, 3), "action": torch.zeros(4, 1)}, [4])
    >>> critic(td)["state_action_value"].shape
    torch.Size([4, 1])
"""

from __future__ import annotations

import torch
from tensordict import TensorDictBase, TensorDictParams
from tensordict.nn import TensorDictModuleBase

__all__ = ["Q_REDUCTIONS", "QEnsembleCritic"]

Q_REDUCTIONS = ("min", "mean")


class QEnsembleCritic(TensorDictModuleBase):
    """An ensemble of Q networks sharing one architecture, reduced to one value.

    Args:
        qvalue_network: the (TensorDict) module that computes one Q value.
        params: the ensemble's parameters, stacked on dim 0 (``[n, ...]``), e.g. a TorchRL
            loss's ``qvalue_network_params``; kept by reference.
        reduce: ``"min"`` (default, pessimistic, as SAC/TD3 targets) or ``"mean"``.
        out_key: the network's output key (``state_action_value`` for ``ValueOperator``).

    Reads the network's ``in_keys``; writes ``out_key`` ``[*B, 1]``; no gradient.
    """

    def __init__(
        self,
        qvalue_network: TensorDictModuleBase,
        params: TensorDictParams,
        *,
        reduce: str = "min",
        out_key="state_action_value",
    ) -> None:
        super().__init__()
        if reduce not in Q_REDUCTIONS:
            raise ValueError(f"reduce must be one of {Q_REDUCTIONS}, got {reduce!r}")
        if params.batch_size.numel() == 0 or len(params.batch_size) != 1:
            raise ValueError(
                f"params must be stacked on one leading ensemble dim, got batch size "
                f"{tuple(params.batch_size)}"
            )
        self.qvalue_network = qvalue_network
        self.params = params
        self.reduce = reduce
        self.in_keys = list(qvalue_network.in_keys)
        self.out_keys = [out_key]

    @classmethod
    def from_loss(cls, loss, *, reduce: str = "min") -> QEnsembleCritic:
        """The live Q ensemble of a TorchRL ``SACLoss`` / ``TD3Loss`` (or any loss with
        ``qvalue_network`` and ``qvalue_network_params``)."""
        network = getattr(loss, "qvalue_network", None)
        params = getattr(loss, "qvalue_network_params", None)
        if network is None or params is None:
            raise ValueError(
                f"loss must own qvalue_network and qvalue_network_params (TorchRL SACLoss, "
                f"TD3Loss), got {type(loss).__name__}"
            )
        return cls(network, params, reduce=reduce, out_key=network.out_keys[0])

    @property
    def num_nets(self) -> int:
        return int(self.params.batch_size[0])

    def members(self, tensordict: TensorDictBase) -> torch.Tensor:
        """Every member's value ``[n, *B, 1]`` (no gradient; ``tensordict`` is not written):
        the ensemble's spread, e.g. for :class:`~torchrl_auv.modules.SelectionRule`."""
        values = []
        with torch.no_grad():
            for i in range(self.num_nets):
                with self.params[i].to_module(self.qvalue_network):
                    out = self.qvalue_network(tensordict.select(*self.in_keys).copy())
                values.append(out.get(self.out_keys[0]))
        return torch.stack(values)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        stacked = self.members(tensordict)
        value = stacked.min(0).values if self.reduce == "min" else stacked.mean(0)
        tensordict.set(self.out_keys[0], value)
        return tensordict
