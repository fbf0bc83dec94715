"""Small helpers shared by the env classes: specs from sample data, argument checks, seeds."""

from __future__ import annotations

from collections.abc import Sequence

import torch
from tensordict import TensorDictBase
from torchrl.data import Composite, Unbounded

from torchrl_auv.control import Controller, available_controllers, make_controller

__all__ = [
    "checked_action",
    "checked_batch_size",
    "controller_from_name",
    "scene_generator",
    "unbounded_spec_like",
]


def unbounded_spec_like(td: TensorDictBase) -> Composite:
    """A :class:`~torchrl.data.Composite` of ``Unbounded`` leaves shaped like ``td``'s entries.

    Nested TensorDicts become nested Composites with their own batch size.

    >>> import torch
    >>> from tensordict import TensorDict
    >>> spec = unbounded_spec_like(TensorDict({"a": {"b": torch.zeros(2, 3)}}, batch_size=[2]))
    >>> spec["a", "b"].shape
    torch.Size([2, 3])
    """
    return Composite(
        {
            key: unbounded_spec_like(value)
            if isinstance(value, TensorDictBase)
            else Unbounded(shape=value.shape, dtype=value.dtype, device=value.device)
            for key, value in td.items()
        },
        shape=td.batch_size,
    )


def controller_from_name(controller: str) -> Controller:
    """:func:`~torchrl_auv.control.make_controller` with an error that names ``controller``.

    >>> controller_from_name("lqr")
    Traceback (most recent call last):
        ...
    ValueError: controller must be one of 'pid', 's_surface', 'smc', got 'lqr'
    """
    try:
        return make_controller(controller)
    except ValueError:
        names = ", ".join(repr(n) for n in available_controllers())
        raise ValueError(f"controller must be one of {names}, got {controller!r}") from None


def checked_batch_size(batch_size: object) -> torch.Size:
    """``batch_size`` as a ``torch.Size`` of scene dims, each an int >= 1 (``[]`` for one
    unbatched scene); anything else is a ValueError naming the argument.

    >>> checked_batch_size([4])
    torch.Size([4])
    >>> checked_batch_size(4)
    Traceback (most recent call last):
        ...
    ValueError: batch_size must be a list of ints >= 1 (e.g. [4] for 4 scenes, [] for one), got 4
    """
    ok = isinstance(batch_size, (Sequence, torch.Size)) and not isinstance(batch_size, str)
    ok = ok and all(isinstance(d, int) and not isinstance(d, bool) and d >= 1 for d in batch_size)
    if not ok:
        raise ValueError(
            f"batch_size must be a list of ints >= 1 (e.g. [4] for 4 scenes, [] for "
            f"one), got {batch_size!r}"
        )
    return torch.Size(batch_size)


def checked_action(action: torch.Tensor, shape: Sequence[int], key: object) -> torch.Tensor:
    """``action`` if it has ``shape`` and only finite values, clipped to [-1, 1] (the action
    spec's bounds: values outside are clipped, as the env card says); a wrong shape or a
    NaN/inf entry is a ValueError naming ``key`` and the expected shape.

    >>> checked_action(torch.tensor([0.5, 2.0]), (2,), "action").tolist()
    [0.5, 1.0]
    >>> checked_action(torch.zeros(3), (2,), "action")
    Traceback (most recent call last):
        ...
    ValueError: action must have shape [2] (batch and action dims), got [3]
    """
    if tuple(action.shape) != tuple(shape):
        raise ValueError(
            f"{key} must have shape {list(shape)} (batch and action dims), got {list(action.shape)}"
        )
    finite = torch.isfinite(action)
    if not bool(finite.all()):
        raise ValueError(
            f"{key} has {int((~finite).sum())} non-finite entries (NaN or inf); "
            "actions must be finite, in [-1, 1]"
        )
    return action.clamp(-1.0, 1.0)


def scene_generator(seed: int | None) -> torch.Generator:
    """The generator an env draws its scenes from: seeded with ``seed``, or, with ``None``,
    from the OS's entropy (gymnasium's and TorchRL's convention: two envs built or seeded
    without a seed differ; before, they all behaved as seed 0).

    >>> a, b = scene_generator(3), scene_generator(3)
    >>> torch.equal(torch.rand(2, generator=a), torch.rand(2, generator=b))
    True
    >>> scene_generator(None).initial_seed() != scene_generator(None).initial_seed()
    True
    """
    generator = torch.Generator()
    if seed is None:
        generator.seed()
    else:
        generator.manual_seed(int(seed))
    return generator
