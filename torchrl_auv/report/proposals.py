"""Figures of the diffusion proposer: the pretraining loss curve (paper Fig. 4) and the K
candidates at several denoising stages drawn as setpoint paths (paper Fig. 5)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import torch

from torchrl_auv.envs.tracking import DEPTH_STEP, HEADING_STEP, RPM_SCALE
from torchrl_auv.report.pyplot import pyplot

__all__ = ["plot_candidate_stages", "plot_pretraining_loss", "setpoint_paths"]


def setpoint_paths(
    chunks: torch.Tensor, depth: float = 0.0, heading: float = 0.0
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Depth (m), heading (rad) and rpm setpoints an action chunk ``[..., H, 3]`` commands
    from ``depth`` and ``heading`` (the envs' action semantics), each ``[..., H + 1]`` (rpm
    ``[..., H]``).

    >>> d, h, n = setpoint_paths(torch.ones(8, 3))
    >>> round(d[-1].item(), 1), round(h[-1].item(), 2), n[0].item()
    (6.4, 1.2, 1520.0)
    """
    zero = torch.zeros_like(chunks[..., :1, 0])
    d = torch.cat([zero, (DEPTH_STEP * chunks[..., 0]).cumsum(-1)], -1) + depth
    h = torch.cat([zero, (HEADING_STEP * chunks[..., 1]).cumsum(-1)], -1) + heading
    return d, h, RPM_SCALE * (chunks[..., 2] + 3.0)


def plot_pretraining_loss(
    steps: Sequence[int],
    losses: Sequence[float],
    path: str | Path,
    *,
    heldout_steps: Sequence[int] = (),
    heldout_losses: Sequence[float] = (),
    phases: Sequence[tuple[int, str]] = (),
) -> Path:
    """The denoising loss against optimiser steps (log scale), PNG (the paper's Fig. 4);
    ``phases`` ``(first step, name)`` after the first are marked by a dashed line (e.g. the
    DAgger rounds of :func:`~torchrl_auv.training.build_first_stage`).

    >>> import tempfile
    >>> plot_pretraining_loss([1, 2, 3], [1.0, 0.5, 0.3], tempfile.mkdtemp() + "/loss.png").suffix
    '.png'
    """
    plt = pyplot()

    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(list(steps), list(losses), label="training")
    if len(heldout_steps):
        ax.plot(list(heldout_steps), list(heldout_losses), "o-", label="held out")
    for start, name in list(phases)[1:]:
        ax.axvline(start, color="grey", linestyle="--", linewidth=0.8)
        ax.annotate(
            name,
            (start, 1.0),
            xycoords=("data", "axes fraction"),
            xytext=(3, -12),
            textcoords="offset points",
            fontsize=8,
            color="grey",
        )
    ax.set_yscale("log")
    ax.set_xlabel("optimiser step")
    ax.set_ylabel("denoising loss (MSE of the noise)")
    ax.set_title("diffusion proposer pretraining")
    ax.legend(loc="best")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def plot_candidate_stages(
    stages: torch.Tensor,
    path: str | Path,
    *,
    depth: float = 0.0,
    heading: float = 0.0,
    stage_labels: Sequence[str] | None = None,
) -> Path:
    """The K candidate chunks at S denoising stages as depth and heading setpoint paths.

    Args:
        stages: ``[S, K, H, 3]`` (e.g. ``DiffusionProposer(num_stages=S)``'s output for one
            state), the last stage being the final candidates.
        path: where to write the PNG.
        depth, heading: the setpoints the chunks start from (m, rad).
        stage_labels: titles of the columns.

    >>> import tempfile
    >>> plot_candidate_stages(torch.rand(3, 5, 8, 3) * 2 - 1, tempfile.mkdtemp() + "/c.png").suffix
    '.png'
    """
    plt = pyplot()

    if stages.dim() != 4 or stages.shape[-1] != 3:
        raise ValueError(f"stages must be shaped [S, K, H, 3], got {tuple(stages.shape)}")
    n_stages, k = stages.shape[:2]
    labels = stage_labels or [f"stage {i + 1}/{n_stages}" for i in range(n_stages)]
    d, h, _ = setpoint_paths(stages.detach().float(), depth, heading)
    steps = torch.arange(d.shape[-1]).numpy()
    fig, axes = plt.subplots(2, n_stages, figsize=(3.2 * n_stages, 5.5), squeeze=False)
    for i in range(n_stages):
        for j in range(k):
            axes[0, i].plot(steps, d[i, j].numpy(), label=f"candidate {j}")
            axes[1, i].plot(steps, h[i, j].numpy())
        axes[0, i].set_title(labels[i])
        axes[0, i].invert_yaxis()
        axes[1, i].set_xlabel("decision in the chunk")
    axes[0, 0].set_ylabel("depth setpoint (m)")
    axes[1, 0].set_ylabel("heading setpoint (rad)")
    axes[0, -1].legend(loc="best", fontsize="small")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
