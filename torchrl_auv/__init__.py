"""torchrl-auv: TorchRL components for stable and robust control of AUVs.

The package is layered (see ``ARCHITECTURE.md`` in the design notes):

* :mod:`torchrl_auv.physics`: REMUS-100 6-DoF dynamics, ocean sea states and energy models
  (plain batched torch, no TorchRL import).

Higher layers (controllers, estimation, environments, proposer, losses, advisor) are added on
top of it and import only the layers below them.

>>> import torchrl_auv
>>> isinstance(torchrl_auv.__version__, str)
True
"""

from __future__ import annotations

__version__ = "0.1.0"

__all__ = ["__version__"]
