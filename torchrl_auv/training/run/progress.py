"""A run's counters: frames collected and gradient updates made.

One :class:`Progress` per run, owned by :class:`~torchrl_auv.training.Run`: ``Run.collect``
counts the frames of each batch as it arrives, the run's
:class:`~torchrl_auv.training.Learner` counts its own updates into the same object
(``Run.restore(learner)`` shares it), and the checkpoint saves and restores it
(:class:`~torchrl_auv.training.ProgressState`).

>>> progress = Progress()
>>> progress.frames += 100
>>> progress
Progress(frames=100, updates=0)
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Progress"]


@dataclass
class Progress:
    """A run's counters, checkpointed with it: frames collected, gradient updates made."""

    frames: int = 0
    updates: int = 0
