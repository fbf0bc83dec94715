"""The ``recipes`` extra this layer needs beyond the core: checked on import, so a missing
package is named with the command that installs it, not met as a bare ``ModuleNotFoundError``
deep in a file.

Examples:
    >>> sorted(set(RECIPES_PACKAGES.values()))
    ['hydra-core', 'tqdm']
"""

from __future__ import annotations

import importlib.util

__all__ = ["RECIPES_PACKAGES"]

#: the packages the training layer imports beyond the core's: import name -> distribution
RECIPES_PACKAGES = {"omegaconf": "hydra-core", "hydra": "hydra-core", "tqdm": "tqdm"}

_missing = sorted({d for m, d in RECIPES_PACKAGES.items() if importlib.util.find_spec(m) is None})
if _missing:
    raise ImportError(
        "torchrl_auv.training (what the recipes build) needs the recipes extra: "
        f"pip install 'torchrl-auv[recipes]' (missing: {', '.join(_missing)}); the core "
        "layers (envs, modules, objectives, evaluation) import without it"
    )
