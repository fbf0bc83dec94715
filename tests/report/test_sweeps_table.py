"""Runs started one by one (each with its own ``run_dir=``) aggregate like a sweep's jobs: the
overrides that say where a job writes are not axes of the table."""

from __future__ import annotations

import math

from torchrl_auv.report.sweeps import aggregate, load_runs, markdown_table


def _run(folder, seed: int, cost: float) -> None:
    (folder / ".hydra").mkdir(parents=True)
    (folder / ".hydra" / "overrides.yaml").write_text(
        f"- env.sea_state=ves\n- seed={seed}\n- run_dir={folder}\n- proposer.cache_dir=/c{seed}\n"
    )
    (folder / "eval.csv").write_text(f"sea_state,policy,cost_mean\nves,diffusion,{cost}\n")


def test_run_dir_and_cache_dir_are_not_axes(tmp_path):
    _run(tmp_path / "a", 0, 1.0)
    _run(tmp_path / "b", 1, 3.0)
    (row,) = aggregate(load_runs(tmp_path), over="seed", metrics=["cost_mean"], policies=None)
    assert row["runs"] == 2 and "run_dir" not in row and "proposer.cache_dir" not in row


def test_one_run_has_no_spread_and_the_table_says_so(tmp_path):
    """A single run measured no spread: its std is NaN (not 0) and its cell says "one run"."""
    _run(tmp_path / "a", 0, 1.5)
    (row,) = aggregate(load_runs(tmp_path), over="seed", metrics=["cost_mean"], policies=None)
    assert row["runs"] == 1 and row["cost_mean"] == 1.5 and math.isnan(row["cost_mean_std"])
    assert (
        markdown_table([row], metrics=["cost_mean"])
        .splitlines()[-1]
        .endswith("| 1 | 1.5 (one run) |")
    )
    _run(tmp_path / "b", 1, 2.5)
    table = markdown_table(
        aggregate(load_runs(tmp_path), over="seed", metrics=["cost_mean"], policies=None),
        metrics=["cost_mean"],
    )
    assert table.splitlines()[-1].endswith("| 2 | 2 ± 0.707 |")
