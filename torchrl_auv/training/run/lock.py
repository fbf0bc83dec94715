"""One writer per run folder: an exclusive lock held from a run's start to its end.

Two runs started on one ``run_dir`` at the same moment (a sweep relaunched by hand, a second
terminal), or two ``resume=`` of one run, would otherwise both pass the start's checks and
write into one folder: interleaved learning curves, whichever checkpoint and ``eval.csv``
came last. :func:`acquire_run_folder` takes an exclusive ``flock`` on ``<run_dir>/.run.lock``
and writes the holder into it (pid, host, start time, UTC); a start on a folder another
process holds is refused before it writes anything, naming that holder
(:class:`RunFolderInUse`). The operating system drops the lock with its process, so a run
killed with ``kill -9`` leaves no lock behind, only its holder line: the next start takes the
folder over and says whose lock it was. :func:`release_run_folder` (at the end of the final
evaluation) clears the holder line and lets go. Within one process a second start on a folder
it already holds (an earlier ``Run`` that ended with an exception) takes the lock over with a
warning.

``flock`` is advisory and local: runs on different machines sharing a folder over a network
file system may not see each other's locks.

Examples:
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> acquire_run_folder(folder)
    >>> "pid" in (folder / LOCK_FILE).read_text()
    True
    >>> release_run_folder(folder)
    >>> (folder / LOCK_FILE).read_text()
    ''
"""

from __future__ import annotations

import fcntl
import logging
import os
import socket
import time
from datetime import datetime, timezone
from pathlib import Path

__all__ = ["LOCK_FILE", "RunFolderInUse", "acquire_run_folder", "release_run_folder"]

log = logging.getLogger(__name__)

#: the lock file in a run folder
LOCK_FILE = ".run.lock"

_HELD: dict[Path, int] = {}  # folder -> the descriptor whose lock this process holds


class RunFolderInUse(RuntimeError):
    """A run folder is held by another running process (the message names it)."""


def _holder(descriptor: int) -> str:
    return os.pread(descriptor, 4096, 0).decode(errors="replace").strip()


def acquire_run_folder(folder: str | Path) -> None:
    """Take ``folder``'s lock (creating the folder and its lock file when missing) or raise
    :class:`RunFolderInUse` naming the process that holds it; nothing is written then."""
    folder = Path(folder).resolve()
    if folder in _HELD:
        log.warning(
            "%s is already held by this process (an earlier run in it): taking it over", folder
        )
        release_run_folder(folder)
    folder.mkdir(parents=True, exist_ok=True)
    descriptor = os.open(folder / LOCK_FILE, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = _holder(descriptor)
        for _ in range(20):  # the holder writes its line just after taking the lock
            if holder:
                break
            time.sleep(0.05)
            holder = _holder(descriptor)
        os.close(descriptor)
        raise RunFolderInUse(
            f"run_dir {folder} is in use by another run ({holder or 'holder not named yet'}); "
            "wait for it to end, or choose another run_dir"
        ) from None
    previous = _holder(descriptor)
    if previous:
        log.warning(
            "%s was held by a run that is no longer running (%s; killed, or ended "
            "without releasing it): taking it over",
            folder,
            previous,
        )
    started = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
    line = f"pid {os.getpid()} on {socket.gethostname()} since {started}\n".encode()
    os.ftruncate(descriptor, 0)
    os.pwrite(descriptor, line, 0)
    _HELD[folder] = descriptor


def release_run_folder(folder: str | Path, *, remove: bool = False) -> None:
    """Clear the holder line of ``folder``'s lock and let go of it (nothing when this process
    does not hold it). ``remove``: delete the lock file too (a start refused after taking the
    lock, in a folder that had none)."""
    folder = Path(folder).resolve()
    descriptor = _HELD.pop(folder, None)
    if descriptor is None:
        return
    if remove:
        (folder / LOCK_FILE).unlink(missing_ok=True)
    else:
        os.ftruncate(descriptor, 0)
    fcntl.flock(descriptor, fcntl.LOCK_UN)
    os.close(descriptor)
