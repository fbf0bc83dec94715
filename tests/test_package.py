"""Package-level checks: version, subpackage docstrings, the layers of the package docstring,
no import circle between files."""

from __future__ import annotations

import ast
import importlib
import pkgutil
import re
from pathlib import Path

import pytest

import torchrl_auv

PACKAGE_ROOT = Path(torchrl_auv.__file__).parent

# Which torchrl_auv subpackages each layer may import (the package docstring).
# The four lowest layers are plain torch: they must not import torchrl either.
ALLOWED_IMPORTS: dict[str, set[str]] = {
    "physics": set(),
    "estimation": {"physics"},
    "control": {"physics"},
    "iout": {"physics", "estimation", "control"},
    "envs": {"physics", "estimation", "control", "iout"},
    "modules": set(),
    "objectives": {"modules"},
    "advisor": {"objectives", "modules"},
    "evaluation": {"physics", "estimation", "control", "iout", "envs", "modules", "objectives"},
    "training": {
        "physics",
        "estimation",
        "control",
        "iout",
        "envs",
        "modules",
        "objectives",
        "advisor",
        "evaluation",
    },
    "report": {
        "training",
        "evaluation",
        "physics",
        "estimation",
        "control",
        "iout",
        "envs",
        "modules",
        "objectives",
        "advisor",
    },
}
# the command-line tools sit on top: they may import every layer
ALLOWED_IMPORTS["cli"] = ALLOWED_IMPORTS["report"] | {"report"}
PLAIN_TORCH_LAYERS = {"physics", "estimation", "control", "iout"}


def _subpackages() -> list[str]:
    return sorted(m.name for m in pkgutil.iter_modules([str(PACKAGE_ROOT)]) if m.ispkg)


def _imported_modules(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    names: set[str] = set()
    package = ".".join(path.relative_to(PACKAGE_ROOT.parent).with_suffix("").parts)
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative import: resolve against this module's package
                base = package.rsplit(".", node.level)[0]
                module = f"{base}.{node.module}" if node.module else base
            elif node.module:
                module = node.module
            else:
                continue
            names.add(module)
            # `from package import submodule` imports that file too
            names.update(f"{module}.{alias.name}" for alias in node.names)
    return names


def test_version_is_pep440():
    assert re.fullmatch(r"\d+\.\d+\.\d+((a|b|rc)\d+)?(\.dev\d+)?", torchrl_auv.__version__)


def test_every_subpackage_is_a_known_layer_with_a_docstring():
    subpackages = _subpackages()
    assert subpackages, "the package has no subpackages"
    for name in subpackages:
        assert name in ALLOWED_IMPORTS, f"torchrl_auv.{name} is not a documented layer"
        module = importlib.import_module(f"torchrl_auv.{name}")
        assert module.__doc__ and len(module.__doc__.strip()) > 20, f"{name} lacks a docstring"


@pytest.mark.parametrize("layer", _subpackages())
def test_layer_imports_only_layers_below(layer):
    allowed = ALLOWED_IMPORTS[layer] | {layer}
    for path in sorted((PACKAGE_ROOT / layer).rglob("*.py")):
        for name in _imported_modules(path):
            parts = name.split(".")
            if parts[0] == "torchrl_auv" and len(parts) > 1:
                assert parts[1] in allowed, f"{path.name} imports {name}: not below {layer}"
            if layer in PLAIN_TORCH_LAYERS:
                assert parts[0] != "torchrl", f"{path.name} imports {name} in a plain-torch layer"


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE_ROOT.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _file_imports() -> dict[str, set[str]]:
    """Each module file of the package (``__init__`` files left out: they re-export) -> the
    package's module files it imports anywhere in it (module level or inside a function)."""
    paths = {_module_name(p): p for p in PACKAGE_ROOT.rglob("*.py")}
    files = {name for name, path in paths.items() if path.name != "__init__.py"}
    graph: dict[str, set[str]] = {}
    for name in files:
        targets = set()
        for imported in _imported_modules(paths[name]):
            if imported in files and imported != name:
                targets.add(imported)
        graph[name] = targets
    return graph


def _import_circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one file (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    circles: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for other in graph[node]:
            if other not in index:
                visit(other)
                low[node] = min(low[node], low[other])
            elif other in stack:
                low[node] = min(low[node], index[other])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                circles.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return circles


def test_no_two_files_import_each_other_even_through_others():
    assert _import_circles(_file_imports()) == []


def test_the_circle_check_finds_a_circle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert _import_circles(graph) == [["a", "b", "c"]]
    assert _import_circles({"a": {"b"}, "b": set()}) == []


def test_the_library_imports_and_collects_without_the_ray_extra():
    import subprocess
    import sys

    code = """
import sys
sys.modules["ray"] = None  # as if the .[ray] extra were not installed
import torchrl_auv, torchrl_auv.training as t
from functools import partial
env = partial(t.make_env, "ideal", num_envs=1, max_steps=5)
collector = t.make_collector(env, None, seed=0, frames_per_batch=5, total_frames=5)
print(sum(d.numel() for d in collector))
try:
    t.check_ray_backend()
except ImportError as error:
    print(error)
"""
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300
    )
    assert result.returncode == 0, result.stderr[-2000:]
    frames, message = result.stdout.strip().splitlines()[-2:]
    assert frames == "5" and "collector.backend='ray' needs Ray" in message
