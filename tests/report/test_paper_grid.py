"""The paper's experiments as jobs: each job once, the first stages built before they are
reused, each framework given only the keys its config has."""

from __future__ import annotations

import pytest

from torchrl_auv.report.paper.grid import (
    EXPERIMENTS,
    Job,
    experiment_jobs,
    first_stage_job,
    grid,
)


def test_shared_jobs_run_once_and_the_jobs_of_a_first_stage_follow_its_builder():
    jobs = grid(list(EXPERIMENTS), seeds=(0, 1, 2))
    names = [job.name for job in jobs]
    assert len(names) == len(set(names))
    # Fig. 7's LAC run in VES is also Table II's, Table III's and Fig. 8/9's
    shared = "diffusion_lac/ves/s_surface/seed1"
    for experiment in ("fig7", "table2", "table3", "fig8_9"):
        assert shared in {job.name for job in experiment_jobs(experiment, (0, 1, 2))}
    # Fig. 11's softplus run is Fig. 10's alpha 0.1 run and the advisor ablation's fixed row
    assert "diffusion_lac/ves/s_surface/fixed-softplus-alpha0.1/seed0" in names
    assert sum("fixed-softplus-alpha0.1" in n for n in names) == 3
    # every (sea, controller, seed) of a diffusion job has its proposer-alone builder, and the
    # jobs that reuse a first stage follow its builder, before the next first stage's
    builders = [job for job in jobs if job.framework == "diffusion"]
    needed = {(j.sea, j.controller, j.seed) for j in jobs if j.framework != "sac"}
    assert needed == {(j.sea, j.controller, j.seed) for j in builders}
    for builder in builders:
        users = [i for i, job in enumerate(jobs) if first_stage_job(job) == builder]
        at = jobs.index(builder)
        assert users == list(range(at + 1, at + 1 + len(users)))
    # seed by seed: one seed of every experiment before the next seed's jobs
    assert [job.seed for job in jobs] == sorted(job.seed for job in jobs)
    assert first_stage_job(Job("sac", "es", "pid", 0)) is None
    assert first_stage_job(builders[0]) is None


def test_overrides_give_each_framework_only_its_groups(tmp_path):
    sac = Job("sac", "es", "pid", 1).overrides("quick", root=tmp_path)
    assert not any(o.startswith(("proposer.", "eval.ranks")) for o in sac)
    assert "collector.init_random_frames=100" in sac
    lac = Job("diffusion_lac", "ves", "s_surface", 0).overrides(
        "paper", root=tmp_path, frames=50000
    )
    assert "collector.total_frames=50000" in lac and "eval.ranks=True" in lac
    assert f"run_dir={tmp_path}/jobs/diffusion_lac/ves/s_surface/seed0" in lac
    assert f"proposer.cache_dir={tmp_path}/first_stage" in lac
    assert "eval.sea_states=[ves]" in lac and "preset=paper" in lac
    # a paper job resumed in a later sitting goes on with its replay buffer, sized to its frames
    assert "checkpoint.replay_buffer=True" in lac and "replay_buffer.size=50000" in lac
    assert "checkpoint.every_frames=10000" in lac
    alone = Job("diffusion", "es", "smc", 0).overrides("paper", root=tmp_path, frames=50000)
    assert "collector.total_frames=1000" in alone  # the proposer alone trains nothing
    assert "collector.total_frames=50000" not in alone
    assert not any(o.startswith(("replay_buffer.", "checkpoint.replay")) for o in alone)
    assert not any(o.startswith(("replay_buffer.", "checkpoint.replay")) for o in sac)  # quick
    variant = experiment_jobs("sampler", (0,))[-1].overrides("paper", root=tmp_path)
    assert "eval.ranks=False" in variant and "proposer.sampler=ddim" in variant


def test_unknown_budget_experiment_or_no_seed_is_refused(tmp_path):
    with pytest.raises(ValueError, match="budget must be one of"):
        Job("sac", "es", "pid", 0).overrides("full", root=tmp_path)
    with pytest.raises(ValueError, match="experiment must be one of"):
        experiment_jobs("fig12", (0,))
    with pytest.raises(ValueError, match="seeds"):
        experiment_jobs("fig7", ())
