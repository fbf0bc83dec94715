"""One held-out episode of a policy as a video: the data-collection top view, decision by decision.

:func:`episode_frames` rolls a policy out (deterministic actions) in the first scene of a
held-out env and draws each decision with :func:`torchrl_auv.envs.render.top_view` (the AUVs'
tracks so far included); :func:`write_episode_video` writes them as an mp4 (``imageio`` with
its ffmpeg plugin: ``pip install -e '.[video]'``, in the lock) and logs them to a wandb logger.
A run writes ``eval_episode.mp4`` with ``eval.video_steps > 0``
(:meth:`~torchrl_auv.training.Run.evaluate`).

>>> from torchrl_auv.envs import DataCollectionEnv, ScriptedExpert
>>> env = DataCollectionEnv(batch_size=[1], seed=0, max_steps=3)
>>> episode_frames(env, ScriptedExpert(env), steps=3, size=64).shape
(4, 64, 64, 3)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.record.loggers.wandb import WandbLogger

from torchrl_auv.envs import SIM_KEY
from torchrl_auv.envs.render import top_view
from torchrl_auv.evaluation import first_episode

__all__ = ["FPS", "episode_frames", "write_episode_video"]

#: decisions per second of video
FPS = 10


def episode_frames(env, policy, steps: int, *, size: int = 400) -> np.ndarray:
    """``uint8 [T + 1, size, size, 3]``: the reset and each decision of the first scene's first
    episode (at most ``steps`` decisions) of ``policy`` in ``env`` (a
    :class:`~torchrl_auv.envs.DataCollectionEnv`, or one wrapped, with a batch of scenes)."""
    if not (isinstance(steps, int) and steps >= 1):
        raise ValueError(f"steps must be an int >= 1, got {steps!r}")
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        rollout = env.rollout(steps, policy, break_when_all_done=True)
    rollout = rollout.reshape(-1, rollout.shape[-1]).cpu()
    end = int(first_episode(rollout)[0][0]) + 1  # the first scene's first episode
    scene = rollout[0]
    states = [scene[0][SIM_KEY], *scene["next", SIM_KEY][:end].unbind(0)]
    positions = np.stack([s["truth", "eta"][:, :2].double().numpy() for s in states])
    area = getattr(env, "base_env", env).config.area_m
    return np.stack(
        [top_view(sim, area, size=size, tracks=positions[: t + 1]) for t, sim in enumerate(states)]
    )


def write_episode_video(frames: np.ndarray, path: str | Path, *, logger=None, step=None) -> Path:
    """Write ``frames`` (``uint8 [T, H, W, 3]``) as an mp4 at :data:`FPS` and, with a TorchRL
    ``WandbLogger``, log them as ``eval/episode`` at ``step``. Returns the file's path."""
    try:
        import imageio.v2 as imageio
    except ImportError as error:
        raise ImportError(
            "eval.video_steps needs imageio with its ffmpeg plugin: pip install -e '.[video]'"
        ) from error
    path = Path(path)
    imageio.mimwrite(path, list(frames), fps=FPS, macro_block_size=1)
    if isinstance(logger, WandbLogger):
        video = torch.from_numpy(frames).permute(0, 3, 1, 2).contiguous()
        logger.log_video("eval/episode", video, step=step, fps=FPS)
    return path
