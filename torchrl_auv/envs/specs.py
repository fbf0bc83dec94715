"""Small helpers shared by the env classes: specs from sample data and argument checks."""

from __future__ import annotations

from tensordict import TensorDictBase
from torchrl.data import Composite, Unbounded

from torchrl_auv.control import Controller, available_controllers, make_controller

__all__ = ["controller_from_name", "unbounded_spec_like"]


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
