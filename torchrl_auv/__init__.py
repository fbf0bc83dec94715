"""torchrl-auv: TorchRL components for stable and robust control of AUVs.

The package is layered; each layer imports only the layers listed before it (checked by
``tests/test_package.py``, which also checks that no two files import each other, directly
or through others):

* :mod:`torchrl_auv.physics`: the REMUS-100 6-DoF model (``docs/spec/remus100.md``), ocean
  sea states, acoustics and energy (plain batched torch, like the next three layers).
* :mod:`torchrl_auv.estimation`: sensor models and the Kalman filter (physics).
* :mod:`torchrl_auv.control`: the S-surface, PID and SMC low-level controllers (physics).
* :mod:`torchrl_auv.iout`: the data-collection task: nodes, network, expert, cost (the above).
* :mod:`torchrl_auv.envs`: the TorchRL ``EnvBase`` environments and their gymnasium ids
  (the above).
* :mod:`torchrl_auv.modules`: the ``TensorDictModule`` s: the diffusion proposer, the candidate
  selector and its rule, the Q ensemble, the Lyapunov forms and spec (none).
* :mod:`torchrl_auv.objectives`: the ``LossModule`` s: the Lyapunov actor-critic, the denoising
  loss, SAC with the candidate backup or a residual actor (modules).
* :mod:`torchrl_auv.advisor`: the LLM / rule-based outer loop (objectives, modules).
* :mod:`torchrl_auv.evaluation`: held-out evaluation: episode statistics, reference policies,
  the worker pool (envs, modules, objectives and below).
* :mod:`torchrl_auv.training`: what the recipes build: envs, learners, collectors, runs
  (every layer above).
* :mod:`torchrl_auv.report` and :mod:`torchrl_auv.cli`: tables, figures and command-line tools
  (every layer).

>>> import torchrl_auv
>>> isinstance(torchrl_auv.__version__, str)
True
"""

from __future__ import annotations

__version__ = "0.1.0"

__all__ = ["__version__"]
