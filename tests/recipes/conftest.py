"""Tests that compose ``recipes/train.py``'s config (``compose("train", ...)``) need its
``framework/<name>`` options, which the script registers in Hydra's ConfigStore on import."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

TRAIN = Path(__file__).resolve().parents[2] / "recipes" / "train.py"


@pytest.fixture(autouse=True, scope="session")
def _frameworks_registered():
    spec = importlib.util.spec_from_file_location("_recipes_train", TRAIN)
    spec.loader.exec_module(importlib.util.module_from_spec(spec))
