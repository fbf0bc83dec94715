"""The first stage as one cached artefact: built once per values, reused by any recipe config
with the same values, rebuilt for other values, refused when stale; acting values do not
rebuild it; the artefact holds the Fig. 4 loss curve."""

from __future__ import annotations

import csv
import json

import pytest
import torch
from omegaconf import OmegaConf

from torchrl_auv.envs.demonstrations import load_demonstrations
from torchrl_auv.modules import DiffusionProposer
from torchrl_auv.training import first_stage_frames, first_stage_from_config, first_stage_values
from torchrl_auv.training.first_stage import FIRST_STAGE_FRAMES_FACT


def _cfg(cache_dir, **proposer):
    return OmegaConf.create(
        {
            "seed": 0,
            "env": {"sea_state": "ideal", "controller": "s_surface", "rate_model": "shannon"},
            "proposer": {
                "cache_dir": str(cache_dir),
                "path": None,
                "demo_sea_state": "ideal",
                "demo_batches": 1,
                "demo_episodes": 1,
                "demo_steps": 12,
                "demo_workers": 1,
                "horizon": 4,
                "history": 2,
                "hidden": 16,
                "cond_dim": 16,
                "depth": 1,
                "pretrain_steps": 4,
                "batch_size": 8,
                "num_candidates": 2,
                "num_inference_steps": 2,
                "sampler": "ddim",
                "dagger_rounds": 1,
                "dagger_batches": 1,
                "dagger_inference_steps": 2,
                "dagger_steps": 3,
                **proposer,
            },
        }
    )


def test_built_once_then_reused_with_acting_values_applied(tmp_path):
    first = first_stage_from_config(_cfg(tmp_path))
    assert first.built and first.folder.parent == tmp_path
    assert first.folder.name.startswith("ideal-s_surface-shannon-seed0-")
    for name in ("proposer.pt", "metrics.json", "pretrain_loss.csv", "values.json"):
        assert (first.folder / name).exists(), name
    assert (first.folder / "demonstrations" / "metadata.json").exists()
    with open(first.folder / "pretrain_loss.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert {row["split"] for row in rows} == {"train", "heldout"}
    assert {row["phase"] for row in rows} == {"pretraining", "dagger1"}
    steps = [int(row["step"]) for row in rows if row["split"] == "train"]
    assert steps == sorted(steps) and steps[-1] == 4 + 3  # DAgger's steps follow pretraining's
    metrics = json.loads((first.folder / "metrics.json").read_text())
    assert metrics["samples"] == 24  # 12 decisions x 2 AUVs
    assert metrics["dagger1_samples"] == 24 and metrics["training_samples"] == 48
    # before DAgger; DAgger fine-tunes the weights under the standardisation fitted first
    before = DiffusionProposer.load(first.folder / "proposer_bc.pt")
    after = DiffusionProposer.load(first.folder / "proposer.pt")
    torch.testing.assert_close(before.state_loc, after.state_loc)
    assert not torch.equal(before.state_loc, torch.zeros_like(before.state_loc))
    assert (first.folder / "dagger1" / "metadata.json").exists()
    # the DAgger round runs on new scenes: its first observations are not the expert's
    demos, visited = (
        load_demonstrations(first.folder / name)[:] for name in ("demonstrations", "dagger1")
    )
    assert not torch.allclose(
        demos["observation"][demos["step"] == 0], visited["observation"][visited["step"] == 0]
    )
    # other acting values: the same artefact, the values applied to the loaded proposer
    again = first_stage_from_config(_cfg(tmp_path, num_candidates=7, sampler="ddpm", compile=True))
    assert not again.built and again.folder == first.folder
    assert again.proposer.num_candidates == 7 and again.proposer.sampler == "ddpm"
    assert again.proposer.compile is True
    assert "reused" in again.facts["first stage"]
    # the offline frames it reports are the frames its demonstrations and DAgger round hold
    frames = first_stage_frames(first_stage_values(_cfg(tmp_path)))
    assert again.facts[FIRST_STAGE_FRAMES_FACT] == frames
    assert demos.shape[0] + visited.shape[0] == frames * 2  # one sample per AUV (2) and frame
    # a value that shapes the weights: a new artefact
    other = first_stage_from_config(_cfg(tmp_path, pretrain_steps=5))
    assert other.built and other.folder != first.folder


def test_proposer_path_is_checked_against_the_config(tmp_path):
    built = first_stage_from_config(_cfg(tmp_path / "cache"))
    path = built.folder / "proposer.pt"
    same = first_stage_from_config(_cfg(tmp_path / "elsewhere", path=str(path)))
    assert same.folder is None and same.proposer.num_candidates == 2
    assert not (tmp_path / "elsewhere").exists()  # nothing built
    with pytest.raises(ValueError, match=r"pretraining\.pretrain_steps"):
        first_stage_from_config(_cfg(tmp_path / "elsewhere", path=str(path), pretrain_steps=9))
    with pytest.raises(FileNotFoundError, match=r"proposer\.path"):
        first_stage_from_config(_cfg(tmp_path, path=str(tmp_path / "none.pt")))


def test_a_proposer_path_of_another_shape_is_refused_naming_the_key(tmp_path):
    # a bare file (no values.json beside it) is checked against the config's structure
    built = first_stage_from_config(_cfg(tmp_path / "cache"))
    bare = tmp_path / "bare" / "proposer.pt"
    bare.parent.mkdir()
    bare.write_bytes((built.folder / "proposer.pt").read_bytes())
    ok = first_stage_from_config(
        _cfg(tmp_path / "x", path=str(bare), sampler="ddpm", num_inference_steps=3)
    )
    assert (ok.proposer.sampler, ok.proposer.num_inference_steps) == ("ddpm", 3)
    with pytest.raises(ValueError, match=r"proposer\.horizon is 6"):
        first_stage_from_config(_cfg(tmp_path / "x", path=str(bare), horizon=6))
    with pytest.raises(ValueError, match=r"proposer\.history=3"):
        first_stage_from_config(_cfg(tmp_path / "x", path=str(bare), history=3))


def test_values_name_sea_controller_rate_and_seed():
    cfg = {
        "seed": 3,
        "env": {"sea_state": "ves", "controller": "pid", "rate_model": "paper"},
        "proposer": {"demo_sea_state": "es", "lr": 5e-4},
    }
    values = first_stage_values(cfg)
    assert (values["sea_state"], values["controller"], values["rate_model"], values["seed"]) == (
        "es",
        "pid",
        "paper",
        3,
    )
    assert values["pretraining"]["lr"] == 5e-4
    assert "num_candidates" not in json.dumps(values)  # acting values are not part of the key


@pytest.mark.parametrize(
    ("key", "value"),
    [("dagger_rounds", -1), ("demo_episodes", 0), ("pretrain_steps", 2.5), ("dagger_lr", 0)],
)
def test_bad_first_stage_values_are_refused_naming_the_key(key, value):
    with pytest.raises(ValueError, match=rf"proposer\.{key} must be"):
        first_stage_values({"proposer": {key: value}})


@pytest.mark.parametrize("recipe", ["diffusion", "diffusion_rl", "diffusion_lac"])
def test_paper_presets_run_dagger_only_in_a_current(recipe):
    """The paper presets' DAgger rounds follow the first stage's sea (recipes/README.md):
    none in still water, one in es and ves; an unknown sea is named, not a lookup error."""
    from pathlib import Path

    from hydra import compose, initialize_config_dir

    from torchrl_auv.training.config import resolve_config

    folder = Path(__file__).resolve().parents[2] / "recipes" / recipe
    with initialize_config_dir(config_dir=str(folder), version_base=None):
        rounds = {
            sea: first_stage_values(compose("paper", [f"env.sea_state={sea}"]))["dagger"][
                "dagger_rounds"
            ]
            for sea in ("ideal", "es", "ves")
        }
        assert rounds == {"ideal": 0, "es": 1, "ves": 1}
        with pytest.raises(ValueError, match=r"env\.sea_state must be one of"):
            resolve_config(compose("paper", ["env.sea_state=calm"]))


def test_building_or_reusing_the_first_stage_leaves_the_global_rng_alike(tmp_path):
    # a run that builds its artefact and one that reuses it must go on with the same numbers
    torch.manual_seed(7)
    first_stage_from_config(_cfg(tmp_path))  # builds
    after_build = torch.rand(3)
    torch.manual_seed(7)
    assert not first_stage_from_config(_cfg(tmp_path)).built  # reuses
    torch.testing.assert_close(torch.rand(3), after_build)


def test_a_build_cut_short_goes_on_to_the_artefact_an_uninterrupted_build_writes(
    tmp_path, monkeypatch
):
    import torchrl_auv.training.first_stage.build as build

    def built(folder):  # each build from the same global RNG state, as a fresh run's
        torch.manual_seed(0)
        return first_stage_from_config(_cfg(folder))

    whole = built(tmp_path / "whole")
    collect, calls = build.collect_demonstration_batches, []

    def counted(*args, policy=None, **kwargs):
        calls.append("dagger" if policy is not None else "expert")
        if policy is not None and cut_short:
            raise KeyboardInterrupt  # the sitting ends while the DAgger round collects
        return collect(*args, policy=policy, **kwargs)

    monkeypatch.setattr(build, "collect_demonstration_batches", counted)
    pretrain = build.pretrain_proposer
    monkeypatch.setattr(
        build, "pretrain_proposer", lambda *a, **k: calls.append("fit") or pretrain(*a, **k)
    )
    cut_short = True
    with pytest.raises(KeyboardInterrupt):
        built(tmp_path / "cut")
    (kept,) = (tmp_path / "cut").glob(".*.partial-*")  # kept for the next build
    assert json.loads((kept / build.PROGRESS_FILE).read_text())["done"] == ["pretraining"]
    cut_short, calls[:] = False, []
    resumed = built(tmp_path / "cut")
    # the expert's demonstrations and the pretrained proposer were loaded, not made again
    assert resumed.built and calls == ["dagger", "fit"]
    assert not list((tmp_path / "cut").glob(".*.partial-*"))
    assert sorted(p.name for p in resumed.folder.iterdir()) == sorted(
        p.name for p in whole.folder.iterdir()
    )
    for name in ("proposer.pt", "proposer_bc.pt"):
        one, other = (
            DiffusionProposer.load(f / name).state_dict() for f in (whole.folder, resumed.folder)
        )
        assert one.keys() == other.keys()
        for key in one:
            torch.testing.assert_close(one[key], other[key], rtol=0, atol=0, msg=key)
    assert (whole.folder / "pretrain_loss.csv").read_text() == (
        resumed.folder / "pretrain_loss.csv"
    ).read_text()
    keep = (
        "samples",
        "overridden_samples",
        "dagger1_samples",
        "training_samples",
        "pretraining_heldout_loss",
        "dagger1_heldout_loss",
        "heldout_loss",
    )
    metrics = [json.loads((f / "metrics.json").read_text()) for f in (whole.folder, resumed.folder)]
    assert {k: metrics[0][k] for k in keep} == {k: metrics[1][k] for k in keep}
