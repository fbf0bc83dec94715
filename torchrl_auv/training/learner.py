"""What a recipe's update step needs, in one object: the loss, its target updater, its
optimisers and the loss outputs it logs (:func:`~torchrl_auv.training.sac_from_config`,
:func:`~torchrl_auv.training.lac_from_config` build one).

Examples:
    >>> import torch
    >>> from tensordict import TensorDict
    >>> from tensordict.nn import TensorDictModule
    >>> class Square(torch.nn.Module):  # a stand-in for a TorchRL LossModule
    ...     def __init__(self):
    ...         super().__init__()
    ...         self.net = TensorDictModule(torch.nn.Linear(2, 1), ["x"], ["y"])
    ...     def forward(self, td):
    ...         return TensorDict({"loss_y": self.net(td)["y"].pow(2).mean()}, [])
    >>> class NoTargets:
    ...     def step(self): pass
    >>> loss = Square()
    >>> learner = Learner(loss, NoTargets(), {"optim": torch.optim.SGD(loss.parameters(), 0.1)},
    ...                   logged_keys=("loss_y",))
    >>> out = learner.step(TensorDict({"x": torch.ones(4, 2)}, [4]))
    >>> list(learner.metrics(out))
    ['train/loss_y']
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import torch
from tensordict import TensorDictBase

__all__ = ["Learner", "gradient_step"]


def gradient_step(loss, optimisers: Mapping[str, torch.optim.Optimizer], updater, batch):
    """One update: the sum of ``loss(batch)``'s ``loss_*`` terms backpropagated, every
    optimiser stepped, the target networks updated. Returns the loss output (detached)."""
    out = loss(batch)
    total = sum(value for key, value in out.items() if key.startswith("loss_"))
    for opt in optimisers.values():
        opt.zero_grad()
    total.backward()
    for opt in optimisers.values():
        opt.step()
    updater.step()
    return out.detach()


@dataclass
class Learner:
    """A loss with everything one of its updates touches.

    Attributes:
        loss: a TorchRL ``LossModule`` (its ``loss_*`` outputs are summed and minimised).
        target_updater: its ``SoftUpdate`` (created before any forward of the loss).
        optimisers: name -> optimiser; checkpointed under these names.
        logged_keys: the loss outputs logged as ``train/<key>`` when present.
    """

    loss: torch.nn.Module
    target_updater: object
    optimisers: dict[str, torch.optim.Optimizer]
    logged_keys: Sequence[str] = field(default_factory=tuple)

    def step(self, batch: TensorDictBase) -> TensorDictBase:
        """One gradient step on ``batch`` (:func:`gradient_step`); the loss output, detached."""
        return gradient_step(self.loss, self.optimisers, self.target_updater, batch)

    def metrics(self, out: TensorDictBase) -> dict[str, float]:
        """``train/<key>`` of each logged key ``out`` holds."""
        keys = out.keys()
        return {f"train/{key}": out[key].item() for key in self.logged_keys if key in keys}

    def checkpoint_modules(self) -> dict[str, object]:
        """What a checkpoint must restore for this learner: the loss and its optimisers."""
        return {"loss": self.loss, **self.optimisers}
