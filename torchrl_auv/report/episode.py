"""Plot one environment episode: top view and depth profile (PNG)."""

from __future__ import annotations

from pathlib import Path

import torch
from tensordict import TensorDictBase

__all__ = ["plot_episode"]


def plot_episode(rollout: TensorDictBase, path: str | Path, *, index: int = 0) -> Path:
    """Top view (true track and Kalman estimate, NED x north / y east) and depth profile.

    Args:
        rollout: a rollout of :class:`~torchrl_auv.envs.AUVTrackingEnv` shaped ``[B, T]`` or
            ``[T]`` (reads ``("next", "truth", "eta")``, ``("next", "kf", "mean")`` and
            ``("next", "setpoint")``).
        path: where to write the PNG.
        index: which batch element to draw.

    >>> import tempfile
    >>> from torchrl_auv.envs import AUVTrackingEnv
    >>> td = AUVTrackingEnv(batch_size=[1], seed=0).rollout(3)
    >>> plot_episode(td, tempfile.mkdtemp() + "/episode.png").suffix
    '.png'
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    nxt = rollout["next"]
    if nxt.batch_dims == 2:
        nxt = nxt[index]
    eta = nxt["truth", "eta"].detach()
    estimate = nxt["kf", "mean"].detach()
    setpoint = nxt["setpoint"].detach()
    time = torch.arange(1, eta.shape[0] + 1).numpy()  # decisions (s)
    fig, (ax_top, ax_depth) = plt.subplots(1, 2, figsize=(11, 4.5))
    ax_top.plot(eta[:, 1].numpy(), eta[:, 0].numpy(), label="true")
    ax_top.plot(estimate[:, 1].numpy(), estimate[:, 0].numpy(), "--", label="KF estimate")
    ax_top.plot(eta[:1, 1].numpy(), eta[:1, 0].numpy(), "ko", label="start")
    ax_top.set_xlabel("east y (m)")
    ax_top.set_ylabel("north x (m)")
    ax_top.set_aspect("equal", adjustable="datalim")
    ax_top.legend(loc="best")
    ax_top.set_title("top view")
    ax_depth.plot(time, eta[:, 2].numpy(), label="depth (true)")
    ax_depth.plot(time, setpoint[:, 0].numpy(), "k--", label="depth setpoint")
    ax_depth.invert_yaxis()
    ax_depth.set_xlabel("time (s)")
    ax_depth.set_ylabel("depth (m)")
    ax_depth.legend(loc="best")
    ax_depth.set_title("depth profile")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
