"""``TrainingFeedback``: what the advisor is told about recent training, and how it is computed.

:func:`feedback_from_training` builds it from what an off-policy loop already holds: the
collected batches (TorchRL layout, time the last batch dim: ``[T]`` or ``[n_envs, T]``) and the
loss outputs (``LyapunovActorCriticLoss``: ``violation_rate``, ``lambda``,
``lyapunov_value``).

Definitions (all dimensionless):

- ``return_trend``: relative change of the mean step reward, later half of the window minus
  earlier half over ``|earlier half|`` (> 0: improving).
- ``position_oscillation`` / ``velocity_oscillation``: the zero-crossing rate per step of the
  position-like / velocity-like observation entries (tracking errors and rates; the indices of
  :class:`~torchrl_auv.modules.LyapunovSpec`'s priors by default): 0 for a monotone
  approach, about 0.5 for noise, 1 for a sign flip every step. ``oscillation_index`` is the
  larger of the two.
- ``violation_rate``: mean fraction of transitions with :math:`\\Delta L > 0`.
- ``lambda_trend``: last minus first Lagrange multiplier of the window.
- ``lyapunov_trend``: relative change of the mean Lyapunov value, later half vs earlier half.
- ``collisions``: events summed over the window (``collision_key``, when given).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass

import torch
from tensordict import NestedKey, TensorDictBase

from torchrl_auv.objectives import LyapunovSpec

__all__ = ["TrainingFeedback", "feedback_from_training"]

_DEFAULT_INDICES = LyapunovSpec().prior_indices


@dataclass(frozen=True)
class TrainingFeedback:
    """A typed summary of recent training (module docstring for each field's definition).

    Examples:
        >>> TrainingFeedback(violation_rate=0.7).oscillation_index
        0.0
    """

    return_trend: float = 0.0
    position_oscillation: float = 0.0
    velocity_oscillation: float = 0.0
    violation_rate: float = 0.0
    lambda_trend: float = 0.0
    lyapunov_trend: float = 0.0
    collisions: float = 0.0
    steps: int = 0

    @property
    def oscillation_index(self) -> float:
        return max(self.position_oscillation, self.velocity_oscillation)

    def as_dict(self) -> dict[str, float]:
        return {**asdict(self), "oscillation_index": self.oscillation_index}


def _relative_change(values: Sequence[float]) -> float:
    if len(values) < 2:
        return 0.0
    half = len(values) // 2
    early = sum(values[:half]) / half
    late = sum(values[half:]) / (len(values) - half)
    return (late - early) / (abs(early) + 1e-8)


def _crossing_rate(
    batches: Sequence[TensorDictBase], key: NestedKey, index: Sequence[int]
) -> float:
    crossings, pairs = 0.0, 0
    for td in batches:
        x = td.get(key)
        if x.dim() < 2 or x.shape[-2] < 2:  # needs a time dim before the features
            continue
        sign = torch.sign(x[..., list(index)])
        flips = (sign[..., 1:, :] * sign[..., :-1, :]) < 0
        crossings += flips.float().sum().item()
        pairs += flips.numel()
    return crossings / pairs if pairs else 0.0


def _time_halves(batches: Sequence[TensorDictBase], key: NestedKey) -> list[float]:
    """Mean of ``key`` per batch, or per half of the one batch's time dim."""
    if len(batches) == 1:
        value = batches[0].get(key)
        half = value.shape[-2] // 2 if value.dim() >= 2 else 0
        if half == 0:
            return [value.float().mean().item()]
        return [
            value[..., :half, :].float().mean().item(),
            value[..., half:, :].float().mean().item(),
        ]
    return [td.get(key).float().mean().item() for td in batches]


def feedback_from_training(
    batches: TensorDictBase | Sequence[TensorDictBase],
    loss_outputs: Sequence[TensorDictBase] = (),
    *,
    observation_key: NestedKey = "observation",
    reward_key: NestedKey = ("next", "reward"),
    position_indices: Sequence[int] = _DEFAULT_INDICES["position"],
    velocity_indices: Sequence[int] = _DEFAULT_INDICES["velocity"],
    collision_key: NestedKey | None = None,
) -> TrainingFeedback:
    """Summarise recent collected batches and loss outputs (module docstring).

    Args:
        batches: collected tensordicts in time order, time the last batch dim.
        loss_outputs: the loss's outputs over the same window (may be empty).
        observation_key, reward_key: where the tracked states and rewards are.
        position_indices, velocity_indices: observation entries for the oscillation indices.
        collision_key: an optional per-step collision count or flag.

    Examples:
        >>> from tensordict import TensorDict
        >>> t = torch.arange(8.0)
        >>> td = TensorDict({"observation": torch.stack([(-1) ** t, 1 - t / 8], -1),
        ...                  ("next", "reward"): -torch.ones(8, 1)}, [8])
        >>> fb = feedback_from_training(td, position_indices=[0], velocity_indices=[1])
        >>> fb.position_oscillation, fb.velocity_oscillation
        (1.0, 0.0)
    """
    if isinstance(batches, TensorDictBase):
        batches = [batches]
    batches = list(batches)
    if not batches:
        raise ValueError("batches must hold at least one collected tensordict")
    for name, key in (("observation_key", observation_key), ("reward_key", reward_key)):
        if batches[0].get(key, None) is None:
            raise ValueError(f"{name} {key!r} is not in the collected batches")
    size = batches[0].get(observation_key).shape[-1]
    for name, index in (
        ("position_indices", position_indices),
        ("velocity_indices", velocity_indices),
    ):
        if any(not -size <= i < size for i in index):
            raise ValueError(f"{name} {list(index)} out of range for observations of size {size}")
    outputs = list(loss_outputs)

    def series(name: str) -> list[float]:
        return [float(out[name]) for out in outputs if name in out.keys()]

    lambdas, violations = series("lambda"), series("violation_rate")
    collisions = 0.0
    if collision_key is not None:
        collisions = sum(td.get(collision_key).float().sum().item() for td in batches)
    return TrainingFeedback(
        return_trend=_relative_change(_time_halves(batches, reward_key)),
        position_oscillation=_crossing_rate(batches, observation_key, position_indices),
        velocity_oscillation=_crossing_rate(batches, observation_key, velocity_indices),
        violation_rate=sum(violations) / len(violations) if violations else 0.0,
        lambda_trend=lambdas[-1] - lambdas[0] if lambdas else 0.0,
        lyapunov_trend=_relative_change(series("lyapunov_value")),
        collisions=collisions,
        steps=sum(td.numel() for td in batches),
    )
