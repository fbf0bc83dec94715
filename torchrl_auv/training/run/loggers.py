"""The recipes' loggers: TorchRL's (wandb offline by default, CSV, TensorBoard), the learning
curves as CSV files beside them, and a clean finish.

Examples:
    >>> import tempfile
    >>> from pathlib import Path
    >>> with tempfile.TemporaryDirectory() as run_dir:
    ...     log_metrics(None, {"train/cost_mean": 1.5}, 1000, curve=Path(run_dir) / "c.csv")
    ...     print((Path(run_dir) / "c.csv").read_text().split())
    ['step,key,value', '1000,train/cost_mean,1.5']
"""

from __future__ import annotations

import csv
import os
from collections.abc import Mapping
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

__all__ = [
    "close_logger",
    "log_metrics",
    "logger_from_config",
    "make_logger",
    "truncate_curve",
]


def make_logger(
    backend: str | None,
    run_dir: str | Path,
    *,
    exp_name: str,
    project: str = "torchrl-auv",
    offline: bool = True,
    config: dict | None = None,
    group: str | None = None,
):
    """A TorchRL logger writing under ``run_dir`` (wandb offline by default), or ``None`` when
    ``backend`` is empty. ``config`` is stored with a wandb run, ``group`` is its wandb group
    (a sweep's runs share one)."""
    from torchrl.record.loggers import get_logger

    if not backend:
        return None
    kwargs = {}
    if backend == "wandb":
        # TorchRL's WandbLogger writes under its log_dir (logger_name) already
        kwargs["wandb_kwargs"] = {
            "offline": offline,
            "project": project,
            "config": config or {},
            "group": group,
        }
    return get_logger(backend, logger_name=str(run_dir), experiment_name=exp_name, **kwargs)


def logger_from_config(cfg: DictConfig, run_dir: Path):
    """The logger of ``cfg.logger`` (``None`` when its backend is empty); a wandb run stores
    the resolved config and joins the group ``logger.group`` (a sweep's name)."""
    lg = cfg.logger
    config = OmegaConf.to_container(cfg, resolve=True)
    return make_logger(
        lg.backend,
        run_dir,
        exp_name=lg.exp_name,
        project=lg.project,
        offline=lg.offline,
        config=config,
        group=lg.get("group"),
    )


def log_metrics(
    logger, metrics: Mapping[str, float], step: int, *, curve: Path | None = None
) -> None:
    """Every metric to a TorchRL logger (none when ``logger`` is ``None``) and, with ``curve``,
    appended to that CSV (long format ``step,key,value``: the learning curve survives a resume
    and needs no logger)."""
    if logger is not None:
        for key, value in metrics.items():
            logger.log_scalar(key, value, step=step)
    if curve is not None:
        new = not Path(curve).exists()
        with open(curve, "a", newline="") as handle:
            writer = csv.writer(handle)
            if new:
                writer.writerow(("step", "key", "value"))
            writer.writerows((step, key, value) for key, value in metrics.items())


def truncate_curve(curve: Path, last_step: int) -> int:
    """Drop the rows of a ``step,key,value`` curve logged after ``last_step`` (a resumed run
    goes on from its checkpoint: rows past it were logged by the session that died, and would
    make the curve run back in time); atomic. Returns the rows dropped (0 without a file).

    >>> import tempfile
    >>> path = Path(tempfile.mkdtemp()) / "curve.csv"
    >>> for step in (100, 200):
    ...     log_metrics(None, {"a": step / 100}, step, curve=path)
    >>> truncate_curve(path, 150), path.read_text().split()
    (1, ['step,key,value', '100,a,1.0'])
    """
    curve = Path(curve)
    if not curve.exists():
        return 0
    with open(curve, newline="") as handle:
        rows = list(csv.reader(handle))
    kept = rows[:1] + [row for row in rows[1:] if row and int(row[0]) <= last_step]
    if len(kept) == len(rows):
        return 0
    temporary = curve.with_name(f".{curve.name}.tmp")
    with open(temporary, "w", newline="") as handle:
        csv.writer(handle).writerows(kept)
    os.replace(temporary, curve)
    return len(rows) - len(kept)


def close_logger(logger) -> None:
    """Finish a wandb run (its files are complete after this); TorchRL's CSV and TensorBoard
    loggers (no ``finish``) and ``None`` are left as they are."""
    finish = getattr(getattr(logger, "experiment", None), "finish", None)
    if finish is not None:
        finish()
