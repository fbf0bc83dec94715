"""A run's folder under Hydra: nothing written into it before the run's values are checked.

Hydra creates its job folder and, by default, writes ``.hydra/{config,hydra,overrides}.yaml``
and opens ``train.log`` there before the recipe's ``main`` runs: a start refused by the checks
(an unknown value, a ``run_dir`` that already holds a run) used to overwrite an existing run's
``.hydra/`` files or leave a half-made folder behind. The recipes' presets therefore set
``hydra.output_subdir: null`` and a delayed log file, and point Hydra's folder at the run's own
(``${run_folder:${resume},${run_dir}}``: the resumed run's folder when resuming);
:class:`~torchrl_auv.training.Run` then writes the ``.hydra/`` files with
:func:`write_hydra_files` once the checks pass, or, refusing, removes the folder Hydra made for
it if it is empty (:func:`remove_if_unused`).

Importing :mod:`torchrl_auv.training` registers the ``run_folder`` resolver.

Examples:
    >>> from omegaconf import OmegaConf
    >>> cfg = OmegaConf.create({"resume": None, "run_dir": "runs/new",
    ...                         "dir": "${run_folder:${resume},${run_dir}}"})
    >>> cfg.dir
    'runs/new'
    >>> cfg.resume = "runs/old"
    >>> cfg.dir
    'runs/old'
"""

from __future__ import annotations

from pathlib import Path

from omegaconf import OmegaConf

__all__ = ["hydra_folder", "remove_if_unused", "write_hydra_files"]

OmegaConf.register_new_resolver(
    "run_folder", lambda resume, run_dir: str(resume or run_dir), replace=True
)


def hydra_folder() -> Path | None:
    """The folder Hydra made for this job (``None`` outside a Hydra app)."""
    from hydra.core.hydra_config import HydraConfig

    if not HydraConfig.initialized():
        return None
    return Path(HydraConfig.get().runtime.output_dir)


def write_hydra_files(run_dir: Path, cfg) -> None:
    """Write ``config.yaml`` (``cfg``, the job's config), ``hydra.yaml`` and ``overrides.yaml``
    into ``run_dir/.hydra`` as Hydra would (nothing outside a Hydra app)."""
    from hydra.core.hydra_config import HydraConfig

    if not HydraConfig.initialized():
        return
    hydra_cfg = HydraConfig.get()
    folder = Path(run_dir) / ".hydra"
    folder.mkdir(parents=True, exist_ok=True)
    OmegaConf.save(cfg, folder / "config.yaml")
    OmegaConf.save(OmegaConf.create({"hydra": hydra_cfg}), folder / "hydra.yaml")
    OmegaConf.save(OmegaConf.create(list(hydra_cfg.overrides.task)), folder / "overrides.yaml")


def remove_if_unused(folder: Path | None) -> None:
    """Remove ``folder`` if it exists and is empty (what Hydra made for a refused start)."""
    if folder is not None and folder.is_dir() and not any(folder.iterdir()):
        folder.rmdir()
