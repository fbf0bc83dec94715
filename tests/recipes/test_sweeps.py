"""recipes/sweeps and recipes/wandb_sweeps: every job of every grid composes and passes the checks;
the wandb YAMLs launch the same jobs; bad values fail before any job; a sweep runs and
aggregates (locally: slow; on Hydra's Ray launcher: in the default suite)."""

from __future__ import annotations

import itertools
import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from hydra import compose, initialize_config_dir
from hydra.core.override_parser.overrides_parser import OverridesParser
from omegaconf import OmegaConf

from torchrl_auv.training import check_config

REPO = Path(__file__).resolve().parents[2]
RECIPES = REPO / "recipes"
#: The grids of the issue: Fig. 7 3 frameworks x 3 seas, Table II 2 x 3 controllers x 2 seas,
#: Table III 4 x 3, alpha 4 values, forms 3, tiny 2 frameworks, rl_stage (issue [21/26]) 3 x 3,
#: rl_stage_residual 2 x 3, rl_stage_finetune 1 x 3,
#: first_stage (issue [13/18]) the
#: proposer alone x 3 seas; each x its seeds.
JOBS = {
    "tiny": 2 * 2,
    "fig7": 3 * 3 * 3,
    "table2": 2 * 3 * 2 * 3,
    "table3": 4 * 3 * 3,
    "rl_stage": 3 * 3 * 5,
    "rl_stage_residual": 2 * 3 * 5,
    "rl_stage_finetune": 1 * 3 * 5,
    "alpha": 4 * 3,
    "forms": 3 * 3,
    "first_stage": 3 * 3,
}
SWEEPS = sorted(p.stem for p in (RECIPES / "sweeps").glob("*.yaml") if not p.stem.startswith("_"))


def _compose(overrides: list[str], *, hydra: bool = False):
    with initialize_config_dir(config_dir=str(RECIPES), version_base="1.3"):
        return compose("train", overrides=overrides, return_hydra_config=hydra)


def _grid(params: dict) -> list[list[str]]:
    """Every job's overrides of a sweeper's ``params`` (Hydra's own parser expands them)."""
    parser = OverridesParser.create()
    axes = [
        [f"{o.key_or_group}={v}" for v in o.sweep_string_iterator()]
        for o in parser.parse_overrides([f"{k}={v}" for k, v in params.items()])
    ]
    return [list(job) for job in itertools.product(*axes)]


def _job(overrides: list[str]) -> dict:
    cfg = _compose(overrides)
    return OmegaConf.to_container(cfg, resolve=True)


def test_the_sweeps_are_the_issues_grids():
    assert SWEEPS == sorted(JOBS)


@pytest.mark.parametrize("name", sorted(JOBS))
def test_every_job_of_a_sweep_composes_passes_the_checks_and_has_its_own_folder(name):
    params = _compose([f"+sweeps={name}"], hydra=True).hydra.sweeper.params
    assert "seed" in params
    jobs = _grid(dict(params))
    assert len(jobs) == JOBS[name]
    folders = set()
    for overrides in jobs:
        cfg = _job([f"+sweeps={name}", "run_root=/sweeps", *overrides])
        check_config(cfg)
        assert cfg["logger"]["group"] == name == cfg["sweep_name"]
        assert cfg["run_dir"] == f"/sweeps/sweeps/{name}/{cfg['logger']['exp_name']}"
        folders.add(cfg["run_dir"])
        for item in overrides:  # the job's values are in its config
            key, value = item.split("=")
            assert str(OmegaConf.select(OmegaConf.create(cfg), key)) == value
        if cfg["framework"] != "sac":  # the diffusion recipes' keys came with the framework
            assert "proposer" in cfg
    assert len(folders) == len(jobs)


@pytest.mark.parametrize("name", ["alpha", "forms"])
def test_the_alpha_and_form_studies_fix_the_lyapunov_spec(name):
    cfg = _job([f"+sweeps={name}"])
    assert cfg["framework"] == "diffusion_lac" and cfg["advisor"]["backend"] == "fixed"


@pytest.mark.parametrize("name", sorted(JOBS))
def test_the_wandb_sweep_launches_the_hydra_sweeps_jobs(name):
    from wandb.sdk.launch.sweeps.utils import create_sweep_command_args

    spec = yaml.safe_load((RECIPES / "wandb_sweeps" / f"{name}.yaml").read_text())
    assert spec["program"] == "recipes/train.py" and spec["method"] == "grid"
    assert spec["command"][:3] == ["${env}", "${interpreter}", "${program}"]
    assert spec["command"][-1] == "${args_no_hyphens}"
    params = spec["parameters"]
    folders = set()
    for values in itertools.product(*(p["values"] for p in params.values())):
        # what wandb's agent runs: its macros filled in by wandb's own helper
        args = create_sweep_command_args(
            {"args": {k: {"value": v} for k, v in zip(params, values, strict=True)}}
        )["args_no_hyphens"]
        macros = {
            "${env}": ["/usr/bin/env"],
            "${interpreter}": ["python"],
            "${program}": [spec["program"]],
            "${args_no_hyphens}": args,
        }
        command = [part for item in spec["command"] for part in macros.get(item, [item])]
        assert command[:3] == ["/usr/bin/env", "python", "recipes/train.py"]
        cfg = _job([*command[3:], "run_root=/sweeps"])  # Hydra accepts every override
        check_config(cfg)
        assert cfg["logger"]["group"] == name and cfg["logger"]["offline"] is False
        folders.add(cfg["run_dir"])
    hydra_params = _compose([f"+sweeps={name}"], hydra=True).hydra.sweeper.params
    hydra_folders = {
        _job([f"+sweeps={name}", "run_root=/sweeps", *job])["run_dir"]
        for job in _grid(dict(hydra_params))
    }
    assert folders == hydra_folders


def test_the_ray_cluster_launcher_connects_and_leaves_the_object_store_to_the_cluster():
    pytest.importorskip("hydra_plugins.hydra_ray_launcher")
    launcher = _compose(["+sweeps=tiny", "hydra/launcher=ray_cluster"], hydra=True).hydra.launcher
    assert launcher._target_.endswith("RayLauncher")
    assert launcher.ray.init.address == "auto" and launcher.ray.init.object_store_memory is None


def _env(tmp_path: Path) -> dict:
    return {
        **os.environ,
        "OMP_NUM_THREADS": "1",
        "WANDB_MODE": "offline",
        "RAY_ADDRESS": "",
        "HOME": str(tmp_path / "home"),
    }


def _sweep(tmp_path: Path, *overrides: str, timeout: float = 900) -> subprocess.CompletedProcess:
    command = [
        sys.executable,
        "recipes/train.py",
        "-m",
        "+sweeps=tiny",
        f"run_root={tmp_path}",
        "logger.backend=",
        *overrides,
    ]
    return subprocess.run(
        command, cwd=REPO, env=_env(tmp_path), capture_output=True, text=True, timeout=timeout
    )


@pytest.mark.parametrize(
    ("overrides", "named"),
    [
        (["env.sea_state=ideal,calm"], "env.sea_state must be one of"),
        (["env.controller=pid,lqr"], "env.controller must be one of"),
        (["framework=sac,td3"], "Could not find 'framework/td3'"),
        (
            ["collector.backend=ray", "collector.ray_address=127.0.0.1:9"],
            "collector.ray_address '127.0.0.1:9' is unreachable",
        ),
        (
            ["hydra/launcher=ray", "hydra.launcher.ray.init.address=127.0.0.1:9"],
            "hydra.launcher.ray.init.address '127.0.0.1:9' is unreachable",
        ),
    ],
)
def test_a_bad_value_in_a_sweep_fails_before_any_job_starts(tmp_path, overrides, named):
    if "ray" in " ".join(overrides):
        pytest.importorskip("ray")
    result = _sweep(tmp_path, *overrides, timeout=120)
    assert result.returncode != 0
    assert named in result.stderr, result.stderr[-2000:]
    assert not list(tmp_path.rglob("eval.csv")) and not list(tmp_path.rglob("train.log"))


def _aggregate(root: Path) -> str:
    result = subprocess.run(
        [sys.executable, "recipes/aggregate.py", str(root)],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    return result.stdout


def _check_tiny_sweep(tmp_path: Path, result: subprocess.CompletedProcess) -> None:
    assert result.returncode == 0, result.stderr[-3000:]
    root = tmp_path / "sweeps" / "tiny"
    for framework, seed in itertools.product(("sac", "diffusion"), (0, 1)):
        run = root / framework / "ideal" / f"seed{seed}"
        assert "- frames: 200" in (run / "summary.md").read_text()
        assert (run / "eval.csv").exists() and (run / ".hydra" / "overrides.yaml").exists()
    table = _aggregate(root).splitlines()
    assert table[0].startswith("| framework | sea_state | policy | runs |")
    assert [line.split(" | ")[:4] for line in table[2:]] == [
        ["| diffusion", "ideal", "diffusion", "2"],
        ["| sac", "ideal", "sac", "2"],
    ]


@pytest.mark.slow
def test_the_tiny_sweep_runs_four_jobs_locally_and_aggregates(tmp_path):
    _check_tiny_sweep(tmp_path, _sweep(tmp_path))


@pytest.mark.slow  # minutes: kept out of the default suite's 20-minute budget
def test_a_sweep_runs_on_hydras_ray_launcher_and_aggregates(tmp_path):
    pytest.importorskip("hydra_plugins.hydra_ray_launcher")
    result = _sweep(
        tmp_path,
        "framework=sac,diffusion",
        "seed=0",
        "hydra/launcher=ray",
        "+hydra.launcher.ray.init.num_cpus=2",
        "+hydra.launcher.ray.init.include_dashboard=false",
    )
    assert result.returncode == 0, result.stderr[-3000:]
    root = tmp_path / "sweeps" / "tiny"
    assert sorted(p.parent.relative_to(root).as_posix() for p in root.rglob("eval.csv")) == [
        "diffusion/ideal/seed0",
        "sac/ideal/seed0",
    ]
    table = _aggregate(root).splitlines()
    assert [line.split(" | ")[:4] for line in table[2:]] == [
        ["| diffusion", "ideal", "diffusion", "1"],
        ["| sac", "ideal", "sac", "1"],
    ]
