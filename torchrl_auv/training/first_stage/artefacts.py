"""A folder of cached artefacts keyed by the values that made them, safe across processes.

:class:`ArtefactCache` keeps one folder per set of values under its root,
``<name>-<key>``, where ``key`` is a hash of the values: the same values (from any recipe or
sweep job) find the same folder and reuse what it holds, other values get a folder of their
own. A folder is written under a temporary name and renamed once complete, so an interrupted
build leaves nothing that looks finished (a resumable build goes on from it later); a lock
file makes a second process with the same values wait for the first one's build and then
reuse it. Each folder holds ``values.json``;
a folder whose stored values differ from the ones asked for (edited by hand, or written by a
version whose values hashed the same) is refused, naming the keys that differ.

Examples:
    >>> import tempfile
    >>> cache = ArtefactCache(tempfile.mkdtemp())
    >>> def build(folder):
    ...     (folder / "weights.txt").write_text("42")
    >>> first, built = cache.get_or_build("stage", {"seed": 0}, build)
    >>> again, built_again = cache.get_or_build("stage", {"seed": 0}, build)
    >>> first == again, built, built_again
    (True, True, False)
    >>> cache.get_or_build("stage", {"seed": 1}, build)[0] == first
    False
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import logging
import os
import shutil
from collections.abc import Callable, Mapping
from pathlib import Path

__all__ = ["VALUES_FILE", "ArtefactCache", "check_values", "differing_keys", "values_key"]

log = logging.getLogger(__name__)
VALUES_FILE = "values.json"


def values_key(values: Mapping) -> str:
    """12 hex digits of the SHA-256 of ``values`` as canonical JSON (sorted keys).

    >>> values_key({"a": 1, "b": [1, 2]}) == values_key({"b": [1, 2], "a": 1})
    True
    """
    text = json.dumps(values, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:12]


def differing_keys(stored: Mapping, wanted: Mapping) -> list[str]:
    """Dotted names of the entries that differ between two nested mappings.

    >>> differing_keys({"a": 1, "b": {"c": 2}}, {"a": 1, "b": {"c": 3}, "d": 0})
    ['b.c', 'd']
    """
    out = []
    for key in sorted(set(stored) | set(wanted), key=str):
        left, right = stored.get(key), wanted.get(key)
        if isinstance(left, Mapping) and isinstance(right, Mapping):
            out += [f"{key}.{inner}" for inner in differing_keys(left, right)]
        elif left != right:
            out.append(str(key))
    return out


def check_values(folder: Path, values: Mapping) -> None:
    """Raise ``ValueError`` when ``folder/values.json`` is missing or holds other values."""
    path = Path(folder) / VALUES_FILE
    if not path.exists():
        raise ValueError(f"{folder} holds no {VALUES_FILE}: it is not a cached artefact")
    stored = json.loads(path.read_text())
    # compare as JSON sees them (tuples become lists)
    wanted = json.loads(json.dumps(values, default=str))
    differ = differing_keys(stored, wanted)
    if differ:
        raise ValueError(
            f"the artefact in {folder} was made with other values ({', '.join(differ)} differ): "
            "refusing to use it; remove the folder to rebuild it"
        )


class ArtefactCache:
    """Folders of artefacts under ``root``, one per (name, values) (module docstring).

    Args:
        root: the cache's folder (created when needed).
    """

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)

    def folder(self, name: str, values: Mapping) -> Path:
        """Where the artefact of ``values`` lives (it may not exist yet)."""
        if not name or "/" in name or name.startswith("."):
            raise ValueError(f"name must be a plain folder name, got {name!r}")
        return self.root / f"{name}-{values_key(values)}"

    def get_or_build(
        self,
        name: str,
        values: Mapping,
        build: Callable[[Path], None],
        *,
        resumable: bool = False,
    ) -> tuple[Path, bool]:
        """The folder of ``values``, built by ``build(folder)`` if it does not exist yet.

        ``build`` writes into a temporary folder, which becomes the artefact only when
        ``build`` returns (with ``values.json`` added). Returns ``(folder, built)``; a folder
        that exists with other stored values raises ``ValueError`` naming the keys.

        ``resumable``: ``build`` can go on from what a build of the same values cut short
        left in its folder (a kill, the end of a sitting): the newest such folder is handed to
        it instead of a fresh one, and an interruption (``KeyboardInterrupt``, ``SystemExit``)
        keeps the folder for the next build. A build that raises an error leaves nothing,
        either way.
        """
        folder = self.folder(name, values)
        self.root.mkdir(parents=True, exist_ok=True)
        with open(self.root / f".{folder.name}.lock", "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)  # a concurrent build of the same values waits
            if folder.exists():
                check_values(folder, values)
                log.info("artefact: reusing %s", folder)
                return folder, False
            # builds of this folder cut short (the lock is ours: none is running), newest first
            stale = sorted(
                self.root.glob(f".{folder.name}.partial-*"),
                key=lambda path: path.stat().st_mtime,
                reverse=True,
            )
            partial = self.root / f".{folder.name}.partial-{os.getpid()}"
            if resumable and stale:
                stale.pop(0).rename(partial)
                log.info("artefact: going on with the build cut short in %s", partial)
            for path in stale:
                shutil.rmtree(path, ignore_errors=True)
            partial.mkdir(exist_ok=True)
            try:
                build(partial)
                (partial / VALUES_FILE).write_text(json.dumps(values, indent=2, default=str))
            except Exception:  # a failed build leaves nothing behind
                shutil.rmtree(partial, ignore_errors=True)
                raise
            except BaseException:  # interrupted: kept for the next build when resumable
                if not resumable:
                    shutil.rmtree(partial, ignore_errors=True)
                raise
            partial.rename(folder)
            log.info("artefact: built %s", folder)
            return folder, True
