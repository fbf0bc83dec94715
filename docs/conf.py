"""Sphinx configuration of the torchrl-auv documentation (``make docs``).

Sphinx because the docstrings are reStructuredText (``:func:`` roles, ``.. math::``
blocks, Google-style sections): autodoc reads them as they are, napoleon turns the
Google sections into fields, MathJax (bundled, no network) renders the equations, and
MyST reads the Markdown pages (README, the recipes page, the results page).
"""

from __future__ import annotations

import inspect
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "docs" / "_ext"))

import torchrl_auv  # noqa: E402

project = "torchrl-auv"
author = "the torchrl-auv authors"
copyright = "2026, the torchrl-auv authors"
release = version = torchrl_auv.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx-mathjax-offline",  # MathJax 3 bundled: the pages render math offline
    "sphinx.ext.viewcode",
    "myst_parser",
    "example_run",  # docs/_ext: the tutorials run their example while the site builds
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "_example_figures"]
# _templates/autosummary/module.rst: a package page shows its docstring and submodules, each
# module documents its own members (its __all__), so a class re-exported by its package is
# described once
templates_path = ["_templates"]

autosummary_generate = True
autodoc_member_order = "bysource"
autodoc_typehints = "description"
napoleon_google_docstring = True
napoleon_numpy_docstring = False
myst_heading_anchors = 3
myst_enable_extensions = ["dollarmath"]
suppress_warnings = ["myst.header"]

html_theme = "furo"
html_title = f"torchrl-auv {release}"

#: links between the repository's Markdown files, as the pages that include them are named
REPOSITORY_LINKS = {
    "](recipes/README.md": "](recipes.md",
    "](CHANGELOG.md": "](changelog.md",
    "](../README.md": "](getting_started.md",
    "](docs/results.md": "](results.md",
    "](docs/spec/data_collection.md": "](spec/data_collection.md",
}


def _repository_links(app, relative_path, parent_docname, content):
    """The README's links to other repository files point at their pages here."""
    for old, new in REPOSITORY_LINKS.items():
        content[0] = content[0].replace(old, new)


def _class_signature(app, what, name, obj, options, signature, return_annotation):
    """A TorchRL module's ``__new__(*args, **kwargs)`` (tensordict's ``TensorDictModuleBase``)
    hides its ``__init__`` from autodoc; ``inspect.signature`` sees through it."""
    if what == "class" and signature == "(*args, **kwargs)":
        try:
            signature = inspect.signature(obj)
        except (TypeError, ValueError):
            return None
        # autodoc_typehints = "description": the types go to the parameter list, not here
        bare = [p.replace(annotation=p.empty) for p in signature.parameters.values()]
        return str(signature.replace(parameters=bare, return_annotation=signature.empty)), None
    return None


def setup(app):
    app.connect("include-read", _repository_links)
    app.connect("autodoc-process-signature", _class_signature)
