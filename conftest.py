"""Shared pytest configuration for torchrl-auv (tests under ``tests/`` and package doctests).

* One thread for torch (``OMP_NUM_THREADS=1``): on the 2-core machines this project is developed
  on, two torch threads made small batched ops 4-50x slower than one.
* Every test starts from a seed derived from its node id (independent of test order), and the
  global RNG states (python, numpy, torch) are restored afterwards, so no test's draws leak into
  another's.  Library code must not use the global RNG at all; the ``global_rng_guard`` fixture
  lets a test assert that.
* HOME-based caches (wandb, matplotlib) point into a per-session temp dir; wandb runs offline.
* ``slow`` tests run only with ``--runslow``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import random
import sys
import tempfile
import zlib

import numpy as np
import pytest
import torch

torch.set_num_threads(1)

# Processes a test spawns (collector workers, artefact builders) unpickle functions of the test
# modules by name (``tests.training...``): the project root must be on the path they inherit,
# also in pytest-xdist's workers (``make test`` runs two), whose path starts elsewhere.
_ROOT = os.path.dirname(os.path.abspath(__file__))
if _ROOT not in sys.path:
    sys.path.insert(0, _ROOT)

_CACHE_ROOT = tempfile.mkdtemp(prefix="torchrl_auv_tests_")
for _var, _sub in {
    "WANDB_DIR": "wandb",
    "WANDB_CACHE_DIR": "wandb_cache",
    "WANDB_CONFIG_DIR": "wandb_config",
    "WANDB_DATA_DIR": "wandb_data",
    "WANDB_ARTIFACT_DIR": "wandb_artifacts",
    "MPLCONFIGDIR": "matplotlib",
    "XDG_CACHE_HOME": "xdg_cache",
}.items():
    os.environ[_var] = os.path.join(_CACHE_ROOT, _sub)
    os.makedirs(os.environ[_var], exist_ok=True)
os.environ["WANDB_MODE"] = "offline"
os.environ.setdefault("MPLBACKEND", "Agg")


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--runslow", action="store_true", default=False, help="run tests marked slow")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if config.getoption("--runslow"):
        return
    skip_slow = pytest.mark.skip(reason="slow: pass --runslow to run")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip_slow)


def _seed_for(nodeid: str) -> int:
    return zlib.crc32(nodeid.encode())


@pytest.fixture(autouse=True)
def _seed_and_restore_rng(request: pytest.FixtureRequest):
    """Seed python/numpy/torch per test and restore the previous global RNG states after it."""
    py_state = random.getstate()
    np_state = np.random.get_state()
    torch_state = torch.random.get_rng_state()
    seed = _seed_for(request.node.nodeid)
    random.seed(seed)
    np.random.seed(seed % 2**32)
    torch.manual_seed(seed)
    yield seed
    random.setstate(py_state)
    np.random.set_state(np_state)
    torch.random.set_rng_state(torch_state)


def _numpy_state_equal(a: tuple, b: tuple) -> bool:
    """Whole legacy numpy RNG states: name, key array, position, gaussian cache."""
    return a[0] == b[0] and np.array_equal(a[1], b[1]) and a[2:] == b[2:]


class GlobalRNGGuard:
    """Context manager asserting that the wrapped code never draws from a global RNG (torch's,
    numpy's legacy one or python's ``random``): the whole state of each is compared, so a
    single draw is caught (numpy's key array alone changes only every 624 draws)."""

    def __enter__(self) -> GlobalRNGGuard:
        self._torch = torch.random.get_rng_state().clone()
        self._numpy = np.random.get_state()
        self._python = random.getstate()
        return self

    def __exit__(self, *exc) -> None:
        if exc[0] is None:
            assert torch.equal(torch.random.get_rng_state(), self._torch), (
                "code under test drew from torch's global RNG; pass a torch.Generator instead"
            )
            assert _numpy_state_equal(np.random.get_state(), self._numpy), (
                "code under test drew from numpy's global RNG"
            )
            assert random.getstate() == self._python, (
                "code under test drew from python's global random module"
            )


@pytest.fixture(autouse=True)
def _doctest_torch(request: pytest.FixtureRequest):
    """Make ``torch`` available in every collected docstring example."""
    if isinstance(request.node, pytest.DoctestItem):
        request.getfixturevalue("doctest_namespace")["torch"] = torch


@pytest.fixture
def global_rng_guard() -> GlobalRNGGuard:
    """``with global_rng_guard: ...`` fails the test if the block used a global RNG."""
    return GlobalRNGGuard()


#: What torch.distributed says when Ray's workers did not join the weight-sync rendezvous within
#: TorchRL's fixed 60 s (``torchrl.weight_update._ray._DIST_TIMEOUT``): seen on a loaded 2-core
#: machine, where each worker spends most of a minute importing torch and building its env.
RAY_SLOW_START = ("diststoreerror", "rendezvous", "socket timeout", "timed out after")


def _skip_if_ray_started_too_slowly(text: str) -> None:
    lines = [
        line
        for line in str(text).splitlines()
        if any(sign in line.lower() for sign in RAY_SLOW_START)
    ]
    if lines:
        pytest.skip(
            "Ray's workers did not start within TorchRL's 60 s weight-sync timeout on "
            f"this (loaded) machine: {lines[-1].strip()[:200]}"
        )


@pytest.fixture
def skip_if_ray_started_too_slowly():
    """``check(text)``: skip the test, quoting the line, when ``text`` (an error message or a
    process's stderr) says Ray's workers missed TorchRL's rendezvous; otherwise return."""
    return _skip_if_ray_started_too_slowly
