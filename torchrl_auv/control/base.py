"""The common controller interface, angle wrapping, and the controller registry.

Sign conventions of the REMUS-100 model (``docs/spec/remus100.md``): a positive rudder angle
turns the vehicle to starboard (positive yaw rate), a positive stern-plane angle pitches the
nose down so the vehicle dives (depth ``z`` increases, pitch ``theta`` decreases).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, fields

import torch
from tensordict import TensorDict

__all__ = [
    "FIN_LIMIT",
    "RPM_LIMIT",
    "Controller",
    "available_controllers",
    "make_controller",
    "wrap_angle",
]

FIN_LIMIT = 15.0 * math.pi / 180.0  # rad, the REMUS-100 fin limit
RPM_LIMIT = 1525.0  # rpm


def wrap_angle(angle: torch.Tensor) -> torch.Tensor:
    """Wrap angles to (-pi, pi] (rad).

    >>> wrap_angle(torch.tensor([math.pi, -math.pi, 3 * math.pi / 2, 0.1]))
    tensor([ 3.1416,  3.1416, -1.5708,  0.1000])
    """
    return math.pi - torch.remainder(math.pi - angle, 2 * math.pi)


@dataclass(frozen=True)
class Gains:
    """Base class of the controllers' gain containers: every field must be >= 0."""

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not (isinstance(value, (int, float)) and value >= 0):
                raise ValueError(f"gain {f.name} must be a number >= 0, got {value!r}")


def build_gains(gains_cls: type[Gains], gains: dict[str, float]) -> Gains:
    """Instantiate a gain container, naming unknown gains in a ValueError."""
    known = {f.name for f in fields(gains_cls)}
    unknown = sorted(set(gains) - known)
    if unknown:
        raise ValueError(
            f"unknown gains {unknown} for {gains_cls.__name__}; known: {sorted(known)}"
        )
    return gains_cls(**gains)


class Controller(ABC):
    """A batched low-level controller with caller-held memory.

    ``__call__(setpoint, eta, nu, memory, dt) -> (command, memory)`` with ``setpoint``
    ``[*B, 3]`` = (depth m, heading rad, rpm), ``eta``/``nu`` ``[*B, 6]`` as in
    :func:`torchrl_auv.physics.remus100.step` (usually the estimated state), and ``command``
    ``[*B, 3]`` = (rudder rad, stern plane rad, rpm): fins saturated at :data:`FIN_LIMIT`,
    rpm clamped to ``[0, RPM_LIMIT]``. ``memory`` is a :class:`~tensordict.TensorDict` of
    batch ``[*B]`` from :meth:`init_memory`; a new one is returned, the input is not modified.
    """

    gains: Gains

    @abstractmethod
    def memory_keys(self) -> tuple[str, ...]:
        """Names of the scalar memory entries (integrators, filter states)."""

    def init_memory(
        self,
        batch_shape: torch.Size | tuple[int, ...],
        dtype: torch.dtype = torch.float32,
        device: torch.device | str | None = None,
    ) -> TensorDict:
        """Zeroed memory for a batch of vehicles."""
        batch_shape = torch.Size(batch_shape)
        return TensorDict(
            {k: torch.zeros(batch_shape, dtype=dtype, device=device) for k in self.memory_keys()},
            batch_size=batch_shape,
        )

    def __call__(
        self,
        setpoint: torch.Tensor,
        eta: torch.Tensor,
        nu: torch.Tensor,
        memory: TensorDict,
        dt: float,
    ) -> tuple[torch.Tensor, TensorDict]:
        _check(setpoint, eta, nu, dt)
        command, new_memory = self.command(setpoint, eta, nu, memory, dt)
        return command, TensorDict(new_memory, batch_size=memory.batch_size)

    def command(
        self,
        setpoint: torch.Tensor,
        eta: torch.Tensor,
        nu: torch.Tensor,
        memory: Mapping[str, torch.Tensor],
        dt: float,
    ) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
        """:meth:`__call__` without input checks, on a plain mapping of memory tensors.

        For compiled inner loops (``torch.compile`` traces it without graph breaks).
        """
        rudder, stern, new_memory = self._fins(setpoint, eta, nu, memory, dt)
        rpm = setpoint[..., 2].clamp(0.0, RPM_LIMIT)
        command = torch.stack(
            (rudder.clamp(-FIN_LIMIT, FIN_LIMIT), stern.clamp(-FIN_LIMIT, FIN_LIMIT), rpm), -1
        )
        return command, dict(new_memory)

    @abstractmethod
    def _fins(self, setpoint, eta, nu, memory, dt) -> tuple[torch.Tensor, torch.Tensor, dict]:
        """Return unsaturated (rudder, stern plane) angles (rad) and the new memory entries."""

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.gains})"


def _check(setpoint, eta, nu, dt) -> None:
    if setpoint.shape[-1:] != (3,):
        raise ValueError(f"setpoint must be shaped [*B, 3], got {tuple(setpoint.shape)}")
    for name, tensor in (("eta", eta), ("nu", nu)):
        if tensor.shape[-1:] != (6,) or tensor.shape[:-1] != setpoint.shape[:-1]:
            raise ValueError(
                f"{name} must be shaped [*B, 6] with the setpoint's batch "
                f"{tuple(setpoint.shape[:-1])}, got {tuple(tensor.shape)}"
            )
    if not dt > 0:
        raise ValueError(f"dt must be > 0 (seconds), got {dt}")


def depth_to_pitch(depth_error: torch.Tensor, gain: float, max_pitch: float) -> torch.Tensor:
    """Outer loop of successive loop closure: a desired pitch (rad) from a depth error (m).

    Diving (positive error) needs the nose down, i.e. a negative pitch.
    """
    return -max_pitch * torch.tanh(gain * depth_error / max_pitch)


_REGISTRY: dict[str, type[Controller]] = {}


def register(name: str):
    def wrap(cls):
        _REGISTRY[name] = cls
        return cls

    return wrap


def available_controllers() -> tuple[str, ...]:
    """Names accepted by :func:`make_controller`, sorted.

    >>> available_controllers()
    ('pid', 's_surface', 'smc')
    """
    return tuple(sorted(_REGISTRY))


def make_controller(name: str, **gains: float) -> Controller:
    """Build a controller by name: ``"s_surface"``, ``"pid"`` or ``"smc"``; ``gains`` override
    the documented defaults.

    >>> make_controller("smc", lam=0.4).gains.lam
    0.4
    """
    if name not in _REGISTRY:
        raise ValueError(f"name must be one of {sorted(_REGISTRY)}, got {name!r}")
    return _REGISTRY[name](**gains)
