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
    >>> list(learner.metrics(out)), learner.progress.updates
    (['train/loss_y'], 1)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import torch
from tensordict import TensorDictBase

from torchrl_auv.training.run.progress import Progress

__all__ = ["Learner", "gradient_step"]


def gradient_step(
    loss,
    optimisers: Mapping[str, torch.optim.Optimizer],
    updater,
    batch,
    steps: Sequence | None = None,
):
    """One update: the sum of ``loss(batch)``'s ``loss_*`` terms backpropagated, every
    optimiser stepped (through ``steps``, the optimisers' ``step`` callables, when given: their
    compiled versions), the target networks updated. Returns the loss output (detached)."""
    out = loss(batch)
    total = sum(value for key, value in out.items() if key.startswith("loss_"))
    for opt in optimisers.values():
        opt.zero_grad()
    total.backward()
    for step in steps if steps is not None else [opt.step for opt in optimisers.values()]:
        step()
    updater.step()
    return out.detach()


def _compiled(function):
    """``torch.compile(function)`` run with TorchRL losses' functional parameters traceable
    (tensordict's ``to_module`` builds ``nn.Parameter``s, a graph break by default)."""
    compiled = torch.compile(function)

    def run(*args):
        with torch._dynamo.config.patch(graph_break_on_nn_param_ctor=False):
            return compiled(*args)

    return run


@dataclass
class Learner:
    """A loss with everything one of its updates touches.

    Attributes:
        loss: a TorchRL ``LossModule`` (its ``loss_*`` outputs are summed and minimised).
        target_updater: its ``SoftUpdate`` (created before any forward of the loss).
        optimisers: name -> optimiser; checkpointed under these names.
        logged_keys: the loss outputs logged as ``train/<key>`` when present.
        compile: run the loss's forward (with its backward) and the optimisers' steps through
            ``torch.compile`` (compiled on the first step, and again when a Python value the
            loss reads changes, e.g. the Lyapunov form an advisor picks). The same update up to
            float rounding, except the actor's sampling noise: compiled random draws are
            inductor's, not eager torch's (reproducible from the same seed all the same).
    """

    loss: torch.nn.Module
    target_updater: object
    optimisers: dict[str, torch.optim.Optimizer]
    logged_keys: Sequence[str] = field(default_factory=tuple)
    compile: bool = False
    progress: Progress = field(default_factory=Progress)
    _compiled: tuple | None = field(default=None, init=False, repr=False)

    def step(self, batch: TensorDictBase) -> TensorDictBase:
        """One gradient step on ``batch`` (:func:`gradient_step`), counted in
        ``progress.updates``; the loss output, detached."""
        if not self.compile:
            out = gradient_step(self.loss, self.optimisers, self.target_updater, batch)
        else:
            if self._compiled is None:
                steps = [_compiled(opt.step) for opt in self.optimisers.values()]
                self._compiled = (_compiled(self.loss), steps)
            loss, steps = self._compiled
            out = gradient_step(loss, self.optimisers, self.target_updater, batch, steps)
        self.progress.updates += 1
        return out

    def metrics(self, out: TensorDictBase) -> dict[str, float]:
        """``train/<key>`` of each logged key ``out`` holds."""
        keys = out.keys()
        return {f"train/{key}": out[key].item() for key in self.logged_keys if key in keys}

    def checkpoint_modules(self) -> dict[str, object]:
        """What a checkpoint must restore for this learner: the loss and its optimisers."""
        return {"loss": self.loss, **self.optimisers}
