"""Worker processes that end with their parent.

A :class:`~concurrent.futures.ProcessPoolExecutor` worker waits on its job queue until the
pool shuts it down; a parent killed by ``SIGKILL`` (or by ``SIGTERM``, whose default action
skips the shutdown) never does, and its workers run on as orphans (``docs/design_notes.md``,
worker processes). Pass :func:`end_with_parent` as the pool's
``initializer`` with the parent's pid in ``initargs`` (or call it from one): the worker ends
itself within ``every_s`` of its parent's death, also one that died while the worker started.

Example:
    >>> import multiprocessing, os
    >>> from concurrent.futures import ProcessPoolExecutor
    >>> from torchrl_auv.envs.processes import end_with_parent
    >>> context = multiprocessing.get_context("spawn")
    >>> with ProcessPoolExecutor(1, mp_context=context, initializer=end_with_parent,
    ...                          initargs=(os.getpid(),)) as pool:
    ...     pool.submit(abs, -3).result()
    3
"""

from __future__ import annotations

import os
import threading
import time

__all__ = ["end_with_parent"]


def end_with_parent(parent: int, every_s: float = 0.5) -> None:
    """In a worker process: end it (``os._exit(1)``) once ``parent`` is gone, checked every
    ``every_s`` seconds by a daemon thread.

    ``parent``: the pid of the process that made the pool (``os.getpid()`` there, passed in
    ``initargs``), not ``os.getppid()`` read here: that is already the reaper if the parent
    died while this worker was still starting (importing torch takes seconds)."""
    thread = threading.Thread(
        target=_exit_with_parent, args=(parent, every_s), daemon=True, name="end-with-parent"
    )
    thread.start()


def _exit_with_parent(parent: int, every_s: float) -> None:
    while os.getppid() == parent:
        time.sleep(every_s)
    os._exit(1)
