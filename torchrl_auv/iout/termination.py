r"""When an episode of the data-collection task ends, and what ending costs.

An AUV *ends* the episode when its state diverges (:func:`~torchrl_auv.physics.limits.diverged`:
non-finite or physically absurd) or it leaves the area by more than a margin; the episode is
*terminated* when any AUV ends it and *truncated* when the decision budget runs out first.
The AUV that ends it pays a terminal cost on top of its step cost (a NaN cost becomes that
terminal cost): with :math:`c_T \ge c_{max} / (1 - \gamma)` ending is never cheaper than
continuing (spec v2).

Examples:
    >>> import torch
    >>> from torchrl_auv.iout.config import IoUTConfig
    >>> eta = torch.zeros(1, 2, 6)
    >>> eta[0, 1, 0] = 260.0  # 60 m beyond the 200 m x 200 m area
    >>> ending = ending_auvs(eta, torch.zeros(1, 2, 6), None, IoUTConfig(), margin_m=20.0)
    >>> ending.tolist()
    [[False, True]]
    >>> with_termination(torch.tensor([[1.0, 2.0]]), ending, 500.0).tolist()
    [[1.0, 502.0]]
    >>> [flag.tolist() for flag in episode_flags(ending, torch.tensor([[3]]), max_steps=1000)]
    [[[True]], [[False]], [[True]]]
"""

from __future__ import annotations

import torch

from torchrl_auv.iout.config import IoUTConfig
from torchrl_auv.physics.limits import diverged

__all__ = ["ending_auvs", "episode_flags", "outside_area", "with_termination"]


def outside_area(eta: torch.Tensor, config: IoUTConfig, margin_m: float) -> torch.Tensor:
    """Whether each AUV is more than ``margin_m`` (m) outside the area, ``[*B, N]``."""
    x, y, m = eta[..., 0], eta[..., 1], margin_m
    return (x < -m) | (x > config.area_m[0] + m) | (y < -m) | (y > config.area_m[1] + m)


def ending_auvs(
    eta: torch.Tensor,
    nu: torch.Tensor,
    actuators: torch.Tensor | None,
    config: IoUTConfig,
    margin_m: float,
) -> torch.Tensor:
    """The AUVs that end the episode at this decision (diverged or out of the area),
    ``[*B, N]``."""
    return diverged(eta, nu, actuators) | outside_area(eta, config, margin_m)


def with_termination(cost: torch.Tensor, ending: torch.Tensor, terminal: float) -> torch.Tensor:
    """``cost`` plus ``terminal`` for the AUVs that end the episode; a NaN cost (a diverged
    state) becomes ``terminal``."""
    return torch.nan_to_num(cost + torch.where(ending, terminal, 0.0), nan=terminal)


def episode_flags(
    ending: torch.Tensor, step_count: torch.Tensor, max_steps: int
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """``(terminated, truncated, done)`` of each scene, ``[*B, 1]``: terminated when an AUV
    ends it, truncated when ``step_count`` reaches ``max_steps`` first."""
    terminated = ending.any(-1, keepdim=True)
    truncated = (step_count >= max_steps) & ~terminated
    return terminated, truncated, terminated | truncated
