"""Hydra's basic sweeper, checking every job's values before the first job starts.

Hydra composes every job of a sweep before launching any (an unknown ``framework`` fails
there, naming it), but it does not look at the values: a sea state, controller or collector
backend that does not exist would only fail when its job runs, after the jobs before it.
:class:`CheckedSweeper` runs :func:`torchrl_auv.training.check_config` on every composed job
first (the choices of every key, a reachable Ray address), and that the address of Hydra's
Ray launcher (``hydra.launcher.ray.init.address``), when given, answers. The sweeps in
``recipes/sweeps/`` select it with ``hydra.sweeper._target_``; Hydra finds it because
``recipes/`` (the script's folder) is on ``sys.path`` when a recipe runs as
``python recipes/train.py``.
"""

from __future__ import annotations

from collections.abc import Sequence

from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
from hydra.errors import ConfigCompositionException
from omegaconf import OmegaConf

from torchrl_auv.training import check_config, check_ray_address


class CheckedSweeper(BasicSweeper):
    """:class:`BasicSweeper` (grids from ``hydra.sweeper.params`` and the command line) whose
    batch check also checks each job's values; the error names the job's overrides."""

    def validate_batch_is_legal(self, batch: Sequence[Sequence[str]]) -> None:
        launcher = self.config.hydra.launcher
        address = OmegaConf.select(launcher, "ray.init.address", default=None)
        if address:  # Hydra's Ray launcher connecting to a cluster
            try:
                check_ray_address(address, key="hydra.launcher.ray.init.address")
            except ValueError as error:
                raise ConfigCompositionException(str(error)) from error
        loader = self.hydra_context.config_loader
        for overrides in batch:
            job = loader.load_sweep_config(self.config, list(overrides))
            values = OmegaConf.to_container(job, resolve=False)
            values.pop("hydra", None)
            try:
                check_config(values)
            except (ValueError, ImportError) as error:
                # Hydra reports a composition error as its message alone, no traceback
                raise ConfigCompositionException(
                    f"sweep job {' '.join(overrides)}: {error}"
                ) from error
