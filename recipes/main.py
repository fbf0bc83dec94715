"""Main job: the paper's Table III tracking experiment, written under ``runs/main/<stamp>/``.

Run from the repository root: ``python -m recipes.main`` (``make table3``); Hydra overrides work,
e.g. ``python -m recipes.main experiment.runs=2 logger.backend=csv``.

Outputs: ``table3.csv`` and ``table3.md`` (mean/std of |heading error| rad and |depth error| m
per controller and sea state, plus KF and raw-USBL position RMS), ``tracking_<sea>.png``, and
the wandb run (offline) under the same folder.
"""

from __future__ import annotations

import csv
import logging
import time
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig

from torchrl_auv.training.run.seeding import configure_threads, seed_everything

log = logging.getLogger(__name__)
COLUMNS = (
    "sea_state",
    "controller",
    "heading_error_mean",
    "heading_error_std",
    "depth_error_mean",
    "depth_error_std",
    "kf_rms",
    "usbl_rms",
)


def write_tables(rows: list[dict], run_dir: Path) -> None:
    with open(run_dir / "table3.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=COLUMNS, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)
    lines = [
        "| sea state | controller | heading err mean (rad) | heading err std (rad) | "
        "depth err mean (m) | depth err std (m) | KF RMS (m) | USBL RMS (m) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            "| "
            + " | ".join(
                [str(r["sea_state"]), str(r["controller"])]
                + [f"{r.get(k, float('nan')):.4f}" for k in COLUMNS[2:]]
            )
            + " |"
        )
    (run_dir / "table3.md").write_text("\n".join(lines) + "\n")


@hydra.main(config_path="config", config_name="main", version_base="1.3")
def main(cfg: DictConfig) -> None:
    configure_threads(cfg.threads)
    seed_everything(cfg.seed)
    from torchrl_auv.report import plot_tracking, tracking_table
    from torchrl_auv.training import make_logger

    run_dir = Path(HydraConfig.get().runtime.output_dir)  # runs/main/<stamp>, config in .hydra/
    lg = cfg.logger
    logger = make_logger(
        lg.backend, run_dir, exp_name=lg.exp_name, project=lg.project, offline=lg.mode == "offline"
    )
    log.info("main job: writing under %s", run_dir)

    exp = cfg.experiment
    start = time.perf_counter()
    rows, traces = tracking_table(
        tuple(exp.controllers),
        tuple(exp.sea_states),
        runs=exp.runs,
        seed=cfg.seed,
        duration=exp.duration,
        localised=exp.localised,
    )
    elapsed = time.perf_counter() - start
    write_tables(rows, run_dir)
    for sea in exp.sea_states:
        plot_tracking(traces, sea, run_dir / f"tracking_{sea}.png")
    for row in rows:
        log.info("%s", {k: (round(v, 4) if isinstance(v, float) else v) for k, v in row.items()})
        if logger is not None:
            for key in COLUMNS[2:]:
                if key in row:
                    logger.log_scalar(
                        f"eval/{row['sea_state']}/{row['controller']}/{key}", row[key], step=0
                    )
    if logger is not None:
        logger.log_scalar("time/experiment_s", elapsed, step=0)
        if hasattr(logger, "experiment") and hasattr(logger.experiment, "finish"):
            logger.experiment.finish()
    log.info("done in %.1f s; table: %s", elapsed, run_dir / "table3.md")


if __name__ == "__main__":
    main()
