"""Plot one environment episode: top view and depth profile (PNG)."""

from __future__ import annotations

from pathlib import Path

import torch
from tensordict import TensorDictBase

from torchrl_auv.report.pyplot import pyplot

__all__ = ["plot_episode"]


def plot_episode(rollout: TensorDictBase, path: str | Path, *, index: int = 0) -> Path:
    """Top view (true tracks and Kalman estimates, NED x north / y east) and depth profiles.

    Works for both envs: one AUV (:class:`~torchrl_auv.envs.AUVTrackingEnv`) or a fleet
    (:class:`~torchrl_auv.envs.DataCollectionEnv`, which also draws the sensor nodes, filled
    served at least once by the end of the rollout, and the ASV's track).

    Args:
        rollout: an env rollout shaped ``[B, T]`` or ``[T]`` (reads ``("next", "truth",
            "eta")``, ``("next", "kf", "mean")``, ``("next", "setpoint")`` and, if present,
            ``("next", "task", "nodes", ...)`` and ``("next", "asv")``; under ``("next",
            "sim")`` for the data-collection env).
        path: where to write the PNG.
        index: which batch element to draw.

    >>> import tempfile
    >>> from torchrl_auv.envs import AUVTrackingEnv, DataCollectionEnv
    >>> td = AUVTrackingEnv(batch_size=[1], seed=0).rollout(3)
    >>> plot_episode(td, tempfile.mkdtemp() + "/episode.png").suffix
    '.png'
    >>> td = DataCollectionEnv(batch_size=[1], seed=0).rollout(3)
    >>> plot_episode(td, tempfile.mkdtemp() + "/fleet.png").suffix
    '.png'
    """
    plt = pyplot()

    nxt = rollout["next"]
    if "sim" in nxt.keys():  # DataCollectionEnv keeps its simulator state under "sim"
        nxt = nxt["sim"]
    if nxt.batch_dims == 2:
        nxt = nxt[index]
    nxt = nxt.cpu()  # an env on a GPU (device=cuda) rolls out there; matplotlib reads numpy
    eta = nxt["truth", "eta"].detach()
    estimate = nxt["kf", "mean"].detach()
    setpoint = nxt["setpoint"].detach()
    if eta.dim() == 2:  # one vehicle: add the fleet dim
        eta, estimate, setpoint = eta[:, None], estimate[:, None], setpoint[:, None]
    fleet = eta.shape[1]
    time = torch.arange(1, eta.shape[0] + 1).numpy()  # decisions (s)
    fig, (ax_top, ax_depth) = plt.subplots(1, 2, figsize=(11, 4.5))
    if "task" in nxt.keys():
        nodes = nxt["task", "nodes"][-1]
        xy, served = nodes["position"].detach(), nodes["services"] > 0
        ax_top.scatter(
            xy[~served, 1].numpy(),
            xy[~served, 0].numpy(),
            s=12,
            marker="s",
            facecolors="none",
            edgecolors="grey",
            label="node",
        )
        ax_top.scatter(
            xy[served, 1].numpy(),
            xy[served, 0].numpy(),
            s=12,
            marker="s",
            color="tab:green",
            label="served node",
        )
    if "asv" in nxt.keys():
        asv = nxt["asv"].detach()
        ax_top.plot(asv[:, 1].numpy(), asv[:, 0].numpy(), ":", color="grey", label="ASV")
    for j in range(fleet):
        name = f"AUV {j} " if fleet > 1 else ""
        (line,) = ax_top.plot(eta[:, j, 1].numpy(), eta[:, j, 0].numpy(), label=f"{name}true")
        color = line.get_color()
        ax_top.plot(
            estimate[:, j, 1].numpy(),
            estimate[:, j, 0].numpy(),
            "--",
            color=color,
            alpha=0.7,
            label=f"{name}KF estimate",
        )
        ax_top.plot(eta[:1, j, 1].numpy(), eta[:1, j, 0].numpy(), "o", color=color)
        ax_depth.plot(time, eta[:, j, 2].numpy(), color=color, label=f"{name}depth (true)")
        ax_depth.plot(
            time,
            setpoint[:, j, 0].numpy(),
            "--",
            color=color,
            alpha=0.7,
            label=f"{name}depth setpoint",
        )
    ax_top.set_xlabel("east y (m)")
    ax_top.set_ylabel("north x (m)")
    ax_top.set_aspect("equal", adjustable="datalim")
    ax_top.legend(loc="best", fontsize="small")
    ax_top.set_title("top view (o: start)")
    ax_depth.invert_yaxis()
    ax_depth.set_xlabel("time (s)")
    ax_depth.set_ylabel("depth (m)")
    ax_depth.legend(loc="best", fontsize="small")
    ax_depth.set_title("depth profile")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
