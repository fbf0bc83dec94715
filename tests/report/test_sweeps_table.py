"""Runs started one by one (each with its own ``run_dir=``) aggregate like a sweep's jobs: the
overrides that say where a job writes are not axes of the table."""

from __future__ import annotations

from torchrl_auv.report.sweeps import aggregate, load_runs


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
