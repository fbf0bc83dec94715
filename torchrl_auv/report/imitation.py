"""How learnable the scripted expert is: the held-out variance a supervised regressor explains.

An upper-bound-style diagnostic for the diffusion proposer's first stage (issue [13/18]): the
expert (:class:`~torchrl_auv.envs.ScriptedExpert`) decides from the observation alone, so its
action is a function of what the proposer sees; how much of each action dimension's
variance an ordinary regressor recovers on held-out scenes says how hard that function is to
learn from a given number of demonstrations. :func:`explained_variance` fits an MLP
(standardised inputs, AdamW, cosine learning rate, mean squared error) on the decisions the
env did not override and returns :math:`R^2 = 1 - \\mathrm{MSE} / \\mathrm{Var}` per action
dimension (depth change, heading change, propeller speed), on the training and held-out
samples, for the observation alone or the proposer's full input (observation and the last
``L`` observation-action pairs).

Command line (demonstrations from ``--scenes`` training scenes and ``--heldout-scenes``
held-out ones, seeds ``--seed`` and ``--heldout-seed``)::

    python -m torchrl_auv.cli.imitation --sea-states ideal es ves --scenes 32

Examples:
    >>> from torchrl_auv.envs.demonstrations import collect_demonstrations
    >>> train = collect_demonstrations("data_collection", episodes=2, max_steps=20, history=2)
    >>> test = collect_demonstrations("data_collection", episodes=1, max_steps=20, history=2,
    ...                               seed=1)
    >>> r2 = explained_variance(train, test, inputs="observation", steps=20)
    >>> sorted(r2), len(r2["heldout"])
    (['heldout', 'train'], 3)
"""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from torch import nn

__all__ = ["INPUTS", "explained_variance", "regression_inputs"]

#: ``observation``: the observation alone; ``history``: the proposer's input (observation,
#: the last L observations and actions, their mask).
INPUTS = ("observation", "history")


def regression_inputs(data: TensorDictBase, inputs: str) -> torch.Tensor:
    """The regressor's input ``[N, F]`` of demonstration samples (``inputs`` in :data:`INPUTS`)."""
    if inputs not in INPUTS:
        raise ValueError(f"inputs must be one of {INPUTS}, got {inputs!r}")
    parts = [data["observation"]]
    if inputs == "history":
        history = data["history"]
        parts += [
            history["observation"].flatten(-2),
            history["action"].flatten(-2),
            history["mask"].to(data["observation"].dtype),
        ]
    return torch.cat(parts, -1)


def explained_variance(
    train: TensorDictBase,
    heldout: TensorDictBase,
    *,
    inputs: str = "observation",
    steps: int = 6000,
    batch_size: int = 256,
    width: int = 256,
    lr: float = 1e-3,
    seed: int = 0,
) -> dict[str, list[float]]:
    """Fit an MLP (3 hidden layers of ``width``) from :func:`regression_inputs` to the
    expert's action on ``train`` and return ``{"train": [R^2 per dim], "heldout": [...]}``.
    Overridden decisions (station keeping: the action never ran) are left out of both."""
    train = train[~train["overridden"]] if "overridden" in train.keys() else train
    heldout = heldout[~heldout["overridden"]] if "overridden" in heldout.keys() else heldout
    x, y = regression_inputs(train, inputs), train["action"]
    loc, scale = x.mean(0), x.std(0).clamp_min(1e-3)
    g = torch.Generator().manual_seed(seed)
    with torch.random.fork_rng():
        torch.manual_seed(seed)
        layers, size = [], x.shape[-1]
        for _ in range(3):
            layers += [nn.Linear(size, width), nn.Mish()]
            size = width
        net = nn.Sequential(*layers, nn.Linear(size, y.shape[-1]))
    optimiser = torch.optim.AdamW(net.parameters(), lr=lr, weight_decay=1e-4)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimiser, steps)
    for _ in range(steps):
        index = torch.randint(0, len(x), (batch_size,), generator=g)
        loss = (net((x[index] - loc) / scale) - y[index]).square().mean()
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        schedule.step()

    @torch.no_grad()
    def r2(data: TensorDictBase) -> list[float]:
        target = data["action"]
        prediction = net((regression_inputs(data, inputs) - loc) / scale)
        return (1 - (prediction - target).square().mean(0) / target.var(0)).tolist()

    return {"train": r2(train), "heldout": r2(heldout)}
