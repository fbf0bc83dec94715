"""The paper's figures and tables from job folders: the numbers are the jobs' (mean ± std over
the seeds that finished), every output comes as PNG or Markdown, CSV and JSON."""

from __future__ import annotations

import csv
import json
import math
import statistics

import pytest

from torchrl_auv.report.paper import figures, store, write_report
from torchrl_auv.report.paper.figures import pool_traces, tenth_means
from torchrl_auv.report.paper.grid import Job, experiment_jobs
from torchrl_auv.report.paper.output import mean_std, write_table

POLICIES = (
    "diffusion_rl",
    "diffusion_lac",
    "sac",
    "diffusion",
    "OA",
    "CA1",
    "CA2",
    "CA3",
    "CA4",
    "RL",
    "proposer alone",
    "expert",
    "random",
)
COLUMNS = (
    "sdr_mbit",
    "ssn",
    "ec_w",
    "cost_mean",
    "decisions",
    "heading_error_mean",
    "heading_error_std",
    "depth_error_mean",
    "depth_error_std",
    "violation_rate",
    "terminated",
)


def _value(job: Job, policy: str, column: str) -> float:
    """A distinct, reproducible number per job, policy and metric."""
    return float(len(job.name) + 3 * job.seed + POLICIES.index(policy) + COLUMNS.index(column))


def _fake_job(root, job: Job) -> None:
    folder = root / "jobs" / job.name
    folder.mkdir(parents=True)
    with open(folder / "eval.csv", "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["sea_state", "policy", *COLUMNS])
        for policy in POLICIES:
            writer.writerow([job.sea, policy, *(_value(job, policy, c) for c in COLUMNS)])
    lines = ["step,key,value"] + [
        f"{step},eval/{key},{step / 100 + job.seed}"
        for step in (0, 100, 200)
        for key in ("cost_mean", "sdr_mbit", "ssn", "ec_w")
    ]
    (folder / "eval_curve.csv").write_text("\n".join(lines) + "\n")
    train = ["step,key,value"] + [
        f"{step},train/cost_mean,{step / 1000 + job.seed}" for step in range(1000, 10_001, 1000)
    ]
    train += [f"{step},train/episode_ssn,{job.seed}" for step in (3000, 8000)]
    (folder / "train_curve.csv").write_text("\n".join(train) + "\n")
    trace = ["decision,mean,std,episodes"] + [f"{t},{10 - t + job.seed},1.0,4" for t in range(5)]
    (folder / "lyapunov_trace.csv").write_text("\n".join(trace) + "\n")


@pytest.fixture
def root(tmp_path):
    seeds = (0, 1, 2)
    for experiment in ("fig7", "table2", "table3", "fig10", "advisor"):
        for job in experiment_jobs(experiment, seeds):
            if not (tmp_path / "jobs" / job.name).exists():
                _fake_job(tmp_path, job)
    return tmp_path


def _mean(jobs, policy, column):
    return statistics.fmean(_value(j, policy or j.framework, column) for j in jobs)


def test_table2_cells_are_the_seeds_mean_and_std(root):
    write_report(root, ["table2"], seeds=(0, 1, 2), budget="quick")
    rows = json.loads((root / "report/table2/table2.json").read_text())["rows"]
    row = next(
        r for r in rows if r["framework"] == "Diffusion+RL (LAC)" and r["controller"] == "pid"
    )
    jobs = [Job("diffusion_lac", "ves", "pid", s) for s in (0, 1, 2)]
    assert row["ves sdr_mbit"] == pytest.approx(_mean(jobs, None, "sdr_mbit"))
    assert row["ves sdr_mbit_std"] == pytest.approx(3.0)  # the seeds' values step by 3
    assert row["es runs"] == 3
    assert (row["paper ves ssn"], row["paper ves ssn_std"]) == (44.0, 4.2)  # the paper's own
    md = (root / "report/table2/table2.md").read_text()
    assert md.startswith("budget quick, seeds [0, 1, 2]") and "± 3 |" in md


def test_a_missing_job_is_counted_not_invented(root):
    missing = Job("sac", "ves", "smc", 2)
    (root / "jobs" / missing.name / "eval.csv").unlink()
    write_report(root, ["table3"], seeds=(0, 1, 2), budget="quick")
    rows = json.loads((root / "report/table3/table3.json").read_text())["rows"]
    row = next(r for r in rows if r["framework"] == "RL (SAC)" and r["controller"] == "smc")
    assert row["runs"] == 2 and row["heading_error_mean"] == pytest.approx(
        _mean([Job("sac", "ves", "smc", s) for s in (0, 1)], None, "heading_error_mean")
    )


def test_figures_and_their_numbers(root):
    paths = write_report(root, ["fig7", "fig10", "advisor"], seeds=(0, 1, 2), budget="quick")
    names = {p.name for p in paths}
    assert {
        "fig7.png",
        "fig7.csv",
        "fig10.png",
        "fig10_lyapunov.json",
        "advisor.md",
        "run.json",
    } <= names
    curve = json.loads((root / "report/fig7/fig7.json").read_text())["rows"]
    point = next(
        r
        for r in curve
        if r["sea_state"] == "es"
        and r["framework"] == "RL (SAC)"
        and r["metric"] == "eval/ssn"
        and r["frames"] == 200
    )
    assert point["value"] == pytest.approx(3.0) and point["value_std"] == pytest.approx(1.0)
    trace = json.loads((root / "report/fig10/fig10_lyapunov.json").read_text())["rows"]
    assert [r["variant"] for r in trace] == ["alpha 0.05", "alpha 0.1", "alpha 0.25", "alpha 0.5"]
    assert trace[0]["L_first_tenth"] == pytest.approx(11.0)  # 10 + mean seed 1
    run = json.loads((root / "report/run.json").read_text())
    assert run["budget"] == "quick" and run["seeds"] == [0, 1, 2]


def test_the_advisor_table_counts_the_spec_changes_each_job_applied(root):
    """The advisor ablation says how often each advisor changed the spec (its decision log,
    ``advisor.jsonl``, without what a resume rolled back): a model that never changes it
    trains the fixed spec's job."""

    def write_log(job, applied, *, restored=None):
        lines = [{"frame": 1000 * i, "applied": a} for i, a in enumerate(applied)]
        if restored is not None:  # resumed from a checkpoint whose last consultation is here
            lines.append({"event": "restored", "last_consultation_frame": restored})
        (root / "jobs" / job.name / "advisor.jsonl").write_text(
            "".join(json.dumps(line) + "\n" for line in lines)
        )

    main = [Job("diffusion_lac", "ves", "s_surface", s) for s in (0, 1, 2)]
    write_log(main[0], [False, True])
    write_log(main[1], [True, True, False, True, True], restored=2000)  # the last two rolled back
    write_log(main[2], [False])
    fixed_job = Job("diffusion_lac", "ves", "s_surface", 0, "fixed-softplus-alpha0.1")
    write_log(fixed_job, [False, False, False])  # the fixed backend logs, never applies
    unfinished = Job("diffusion_lac", "ves", "s_surface", 1, "fixed-softplus-alpha0.1")
    (root / "jobs" / unfinished.name / "eval.csv").unlink()
    write_log(unfinished, [True])  # not finished: not counted
    # a model that re-states the alpha in force with fewer digits changes nothing it decided
    model = Job("diffusion_lac", "ves", "s_surface", 0, "openai")
    (root / "jobs" / model.name).mkdir(parents=True)
    (root / "jobs" / model.name / "eval.csv").write_text(
        "sea_state,policy,cost_mean\nves,diffusion_lac,1.0\n"
    )
    spec = {"form": "softplus", "prior": None}
    # (alpha before, alpha decided, applied): kept, changed, re-rounded, refused
    steps = [
        (0.1, 0.1, False),
        (0.1, 0.156483279, True),
        (0.156483279, 0.156483, True),
        (0.156483, 0.3, False),
    ]
    (root / "jobs" / model.name / "advisor.jsonl").write_text(
        "".join(
            json.dumps(
                {
                    "frame": 1000 * i,
                    "applied": applied,
                    "spec_before": {**spec, "alpha": before, "prior_weight": 1.0},
                    "decision": {**spec, "alpha": after, "rationale": ""},
                }
            )
            + "\n"
            for i, (before, after, applied) in enumerate(steps)
        )
    )
    write_report(root, ["advisor"], seeds=(0, 1, 2), budget="paper")
    rows = json.loads((root / "report/advisor/advisor.json").read_text())["rows"]
    rules, fixed, llm = rows
    assert rules["spec_changes"] == 1.0 and rules["spec_changes_std"] == 1.0  # 1, 2, 0
    assert rules["consultations"] == 2.0  # 2, 3, 1
    assert fixed["consultations"] == 3.0 and fixed["spec_changes"] == 0.0  # seed 0 alone
    assert math.isnan(fixed["spec_changes_std"])  # one seed
    assert llm["consultations"] == 4.0 and llm["spec_changes"] == 1.0  # the re-rounding: none
    header = (root / "report/advisor/advisor.md").read_text().splitlines()[2]
    assert "| consultations | spec_changes |" in header


def test_an_unknown_experiment_is_refused_before_writing(tmp_path):
    with pytest.raises(ValueError, match="fig99"):
        write_report(tmp_path, ["fig99"], seeds=(0,), budget="quick")
    assert not (tmp_path / "report").exists()


def test_fig5_6_is_drawn_again_from_stored_rollouts_where_the_first_stage_is_gone(tmp_path):
    """The machine that built the first stage wrote fig5_6.json; the store carries it to a
    machine without the first stage, where Fig. 5/6 is drawn from it."""
    first, store_dir, second = tmp_path / "m1", tmp_path / "store", tmp_path / "m2"
    paths = [
        [
            [[[10.0 * s + k + t, 2.0 * t + auv, 5.0] for auv in range(2)] for t in range(9)]
            for k in range(5)
        ]
        for s in range(3)
    ]
    rollouts = {
        "header": "h",
        "artefact": "/m1/first_stage/ves-s_surface-shannon-seed0-abc",
        "stages": ["a", "b", "c"],
        "chunks": [],
        "paths_ned_m": paths,
    }
    (first / "report" / "fig5_6").mkdir(parents=True)
    (first / "report" / "fig5_6" / "fig5_6.json").write_text(json.dumps(rollouts))
    assert store.save_finished(first, store_dir, []) == []  # not right after a report
    assert [p.name for p in store.save_finished(first, store_dir, [], report=True)] == [
        "fig5_6.json"
    ]
    assert [p.name for p in store.restore_finished(store_dir, second, [])] == ["fig5_6.json"]
    out = second / "report" / "fig5_6"
    written = figures.fig5_6(second, out, [0], "h")
    assert sorted(p.name for p in written) == ["fig5.png", "fig5_6.json", "fig6.png"]
    assert all(p.stat().st_size > 1000 for p in written)
    assert json.loads((out / "fig5_6.json").read_text())["paths_ned_m"] == paths
    assert figures.fig5_6(second, out, [1], "h") == []  # seed 0's rollouts are not seed 1's
    # without the stored rollouts and without the first stage there is nothing to draw
    assert figures.fig5_6(tmp_path / "m3", tmp_path / "m3" / "out", [0], "h") == []


def test_fig8_9_puts_the_papers_numbers_beside_ours(tmp_path):
    write_report(tmp_path, ["fig8_9"], seeds=(0,), budget="quick")
    rows = {
        r["policy"]: r
        for r in json.loads((tmp_path / "report/fig8_9/fig8_9.json").read_text())["rows"]
    }
    assert rows["OA"]["paper ssn"] == 67.0 and rows["RL (LAC)"]["paper sdr_mbit"] == 105.0
    assert (
        rows["CA4"]["paper ec_w"] == 378.0 and rows["CA3"]["paper ssn"] != rows["CA3"]["paper ssn"]
    )
    columns = (tmp_path / "report/fig8_9/fig8_9.md").read_text().splitlines()[2]
    assert columns.startswith(
        "| policy | runs | return | paper return (x 1e3) | ended early | sdr_mbit | paper sdr_mbit"
    )


def test_fig8_9_shows_the_proposer_alone_the_expert_and_random_as_reference_rows(root):
    """Beyond the paper's six strategies: the same jobs' proposer alone (no critic), scripted
    expert and random actions, labelled as references, with no paper numbers."""
    write_report(root, ["fig8_9"], seeds=(0, 1, 2), budget="paper")
    rows = json.loads((root / "report/fig8_9/fig8_9.json").read_text())["rows"]
    names = [r["policy"] for r in rows]
    assert names == [
        "OA",
        "CA1",
        "CA2",
        "CA3",
        "CA4",
        "RL (LAC)",
        "proposer alone (reference)",
        "expert (reference)",
        "random (reference)",
    ]
    jobs = [Job("diffusion_lac", "ves", "s_surface", s) for s in (0, 1, 2)]
    for row, policy in zip(rows[6:], ("proposer alone", "expert", "random"), strict=True):
        assert row["runs"] == 3 and row["ssn"] == _mean(jobs, policy, "ssn")
        # each seed's own return (its cost per AUV-decision times its decisions), then the
        # mean and std over the seeds: the numbers the claims compare
        returns = [-_value(j, policy, "cost_mean") * _value(j, policy, "decisions") for j in jobs]
        assert row["return"] == pytest.approx(statistics.fmean(returns))
        assert row["return_std"] == pytest.approx(statistics.stdev(returns))
        assert row["ended early"] == _mean(jobs, policy, "terminated")
        assert math.isnan(row["paper ssn"]) and math.isnan(row["paper return (x 1e3)"])
    assert "ended early" in (root / "report/fig8_9/fig8_9.md").read_text().splitlines()[2]


def test_the_sampler_time_of_an_earlier_report_stands_where_the_first_stage_is_gone(tmp_path):
    job = Job("diffusion_lac", "ves", "s_surface", 0, "ddim10")
    config = tmp_path / "jobs" / job.name / ".hydra" / "config.yaml"
    config.parent.mkdir(parents=True)
    config.write_text("proposer:\n  sampler: ddim\n  num_inference_steps: 10\n  history: 10\n")
    out = tmp_path / "report" / "sampler"
    out.mkdir(parents=True)
    earlier = {
        "rows": [
            {"variant": "10 DDIM steps", "sampler": "ddim 10", "proposer_s_per_decision": 0.0042}
        ]
    }
    (out / "sampler.json").write_text(json.dumps(earlier))
    write_report(tmp_path, ["sampler"], seeds=(0,), budget="paper")
    rows = json.loads((out / "sampler.json").read_text())["rows"]
    assert rows[1]["sampler"] == "ddim 10" and rows[1]["proposer_s_per_decision"] == 0.0042
    assert rows[1]["timed"] == "by an earlier report"
    # the store saves the newer report's file over an older one, and restores it where missing
    store_dir = tmp_path / "store"
    (store_dir / "report" / "sampler").mkdir(parents=True)
    (store_dir / "report" / "sampler" / "sampler.json").write_text("{}")
    store.save_finished(tmp_path, store_dir, [])  # a sitting's start: the store's stays
    assert (store_dir / "report/sampler/sampler.json").read_text() == "{}"
    store.save_finished(tmp_path, store_dir, [], report=True)
    assert (store_dir / "report/sampler/sampler.json").read_text() == (
        out / "sampler.json"
    ).read_text()
    # no earlier report and no first stage: no time, not a crash
    (out / "sampler.json").unlink()
    write_report(tmp_path, ["sampler"], seeds=(0,), budget="paper")
    rows = json.loads((out / "sampler.json").read_text())["rows"]
    assert rows[1]["proposer_s_per_decision"] != rows[1]["proposer_s_per_decision"]  # NaN


def test_fig7_reads_the_curves_of_finished_jobs_only(root):
    """A running job has written part of its curve but no eval.csv: not in Fig. 7."""
    (root / "jobs" / Job("sac", "es", "s_surface", 2).name / "eval.csv").unlink()
    write_report(root, ["fig7"], seeds=(0, 1, 2), budget="quick")
    curve = json.loads((root / "report/fig7/fig7.json").read_text())["rows"]
    point = next(
        r
        for r in curve
        if r["sea_state"] == "es"
        and r["framework"] == "RL (SAC)"
        and r["metric"] == "eval/ssn"
        and r["frames"] == 200
    )
    assert point["runs"] == 2 and point["value"] == pytest.approx(2.5)  # seeds 0 and 1


def test_fig7_training_curves_bin_the_collected_batches_then_pool_the_seeds(root):
    """The training-time curves (``train_curve.csv``: the collected batches, exploration on)
    in 5,000-frame bins: each seed's points in a bin averaged, then mean ± std over seeds."""
    (root / "jobs" / Job("sac", "es", "s_surface", 2).name / "eval.csv").unlink()  # running
    paths = write_report(root, ["fig7"], seeds=(0, 1, 2), budget="quick")
    assert {"fig7.png", "fig7_training.png", "fig7_training.json"} <= {p.name for p in paths}
    rows = json.loads((root / "report/fig7/fig7_training.json").read_text())["rows"]

    def point(*where):  # sea, framework, metric, frames
        keys = ("sea_state", "framework", "metric", "frames")
        return next(r for r in rows if tuple(r[k] for k in keys) == where)

    # frames 1000-5000 of seed s: values 1..5 + s, their mean 3 + s; over seeds 0-2: 4 ± 1
    first = point("ideal", "Diffusion+RL", "train/cost_mean", 5000)
    assert first["runs"] == 3 and first["value"] == pytest.approx(4.0)
    assert first["value_std"] == pytest.approx(1.0)
    assert point("ideal", "Diffusion+RL", "train/cost_mean", 10_000)["value"] == pytest.approx(9.0)
    # SSN at 3,000 and 8,000 frames: one point per bin; the running job's seed is left out
    ssn = point("es", "RL (SAC)", "train/episode_ssn", 10_000)
    assert ssn["runs"] == 2 and ssn["value"] == pytest.approx(0.5)
    assert not [r for r in rows if r["frames"] not in (5000, 10_000)]


def test_fig7_without_training_curves_keeps_its_evaluation_curves(root):
    """A finished job without ``train_curve.csv`` (written before the file existed): no
    training curve of it, the evaluation curves as they were, no error."""
    write_report(root, ["fig7"], seeds=(0, 1, 2), budget="quick")
    before = (root / "report/fig7/fig7.json").read_text()
    (root / "jobs" / Job("sac", "es", "s_surface", 2).name / "train_curve.csv").unlink()
    write_report(root, ["fig7"], seeds=(0, 1, 2), budget="quick")
    assert (root / "report/fig7/fig7.json").read_text() == before
    rows = json.loads((root / "report/fig7/fig7_training.json").read_text())["rows"]
    sac = [r for r in rows if (r["sea_state"], r["framework"]) == ("es", "RL (SAC)")]
    assert sac and all(r["runs"] == 2 for r in sac)


def test_a_partial_last_bin_is_named_by_the_jobs_last_frame(tmp_path):
    """A job of 7,000 frames: its second bin holds 6,000-7,000 and stands at 7,000, not at
    10,000 (frames never trained)."""
    job = Job("sac", "ideal", "s_surface", 0)
    folder = tmp_path / "jobs" / job.name
    folder.mkdir(parents=True)
    (folder / "eval.csv").write_text("sea_state,policy\n")
    (folder / "eval_curve.csv").write_text("step,key,value\n0,eval/cost_mean,1.0\n")
    lines = [f"{step},train/cost_mean,{step / 1000}" for step in range(1000, 7001, 1000)]
    (folder / "train_curve.csv").write_text("step,key,value\n" + "\n".join(lines) + "\n")
    write_report(tmp_path, ["fig7"], seeds=(0,), budget="quick")
    rows = json.loads((tmp_path / "report/fig7/fig7_training.json").read_text())["rows"]
    assert [(r["frames"], r["value"]) for r in rows] == [(5000, 3.0), (7000, 6.5)]


@pytest.mark.slow  # minutes: kept out of the default suite's 20-minute budget
def test_the_papers_rate_formula_inflates_the_experts_data(tmp_path):
    """The rate-model table: the same expert on the same scenes delivers more data with the
    paper's formula (10^SNR instead of 10^(SNR/10)) than with the Shannon rate."""
    from torchrl_auv.report.paper.tables import rate_models

    rate_models(tmp_path, "h", scenes=2, steps=150, seas=("ideal",))
    rows = {
        r["rate_model"]: r for r in json.loads((tmp_path / "rate_models.json").read_text())["rows"]
    }
    assert rows["shannon"]["sdr_mbit"] > 0
    assert rows["paper"]["sdr_mbit"] > rows["shannon"]["sdr_mbit"]
    assert rows["paper"]["paper sdr_mbit"] != rows["paper"]["paper sdr_mbit"]  # no ideal numbers


def test_pooled_traces_weigh_every_running_episode():
    """Seed 0's 3 episodes at 0, 1, 2 (mean 1, sample std 1), seed 1's one episode at 5
    (ended after decision 0): the pooled mean is (3 x 1 + 5) / 4 = 2 at decision 0 (not the
    seeds' (1 + 5) / 2 = 3) and the std that of the four episodes 0, 1, 2, 5; seed 0 alone
    after; nothing where none runs."""
    seed0 = {"mean": [1.0, 1.0, math.nan], "std": [1.0, 1.0, math.nan], "episodes": [3, 3, 0]}
    seed1 = {"mean": [5.0], "std": [0.0], "episodes": [1]}
    pooled = pool_traces([seed0, seed1])
    assert pooled["mean"][:2] == [2.0, 1.0] and math.isnan(pooled["mean"][2])
    assert pooled["std"][0] == pytest.approx(statistics.stdev([0.0, 1.0, 2.0, 5.0]))
    assert pooled["std"][1] == pytest.approx(1.0)  # seed 0's own
    assert pooled["episodes"] == [4.0, 3.0, 0.0]
    assert tenth_means(pooled) == (2.0, 1.0)
    one = pool_traces([{"mean": [3.0], "std": [0.0], "episodes": [1]}])
    assert one["std"] == [0.0]  # one episode: no spread, as lyapunov_trace writes it


def test_one_seed_states_no_spread(tmp_path):
    """A cell of one seed's value says so: a std of 0 would claim a spread measured as none."""
    mean, std = mean_std([2.0, math.nan])
    assert mean == 2.0 and math.isnan(std)
    assert mean_std([2.0, 2.0]) == (2.0, 0.0)  # two equal values: a spread of 0, measured
    rows = [
        {"cell": "one", "x": mean, "x_std": std},
        {"cell": "two", "x": 2.0, "x_std": 0.0},
        {"cell": "none", "x": math.nan, "x_std": math.nan},
    ]
    (md, _, _) = write_table(tmp_path, "t", rows, ["cell", "x"], header="h")
    assert md.read_text().splitlines()[4:] == [
        "| one | 2 (one seed) |",
        "| two | 2 ± 0 |",
        "| none | nan ± nan |",
    ]


def test_the_lyapunov_cost_table_states_the_multiplier_and_the_condition_at_the_end(root):
    """Each row of the Lyapunov-cost ablation says where its Lagrange multiplier ended
    (``train/lambda``'s last value) and how often the training batches violated the
    Lyapunov condition over the last 5,000 frames (``train/violation_rate``), over the
    finished jobs that log them."""

    def curve(job, lam, violated):
        folder = root / "jobs" / job.name
        if not (folder / "eval.csv").exists():
            folder.mkdir(parents=True)
            (folder / "eval.csv").write_text("sea_state,policy,cost_mean\nves,diffusion_lac,1.0\n")
        lines = ["step,key,value"]
        for i, (a, v) in enumerate(zip(lam, violated, strict=True), start=1):
            lines += [f"{1000 * i},train/lambda,{a}", f"{1000 * i},train/violation_rate,{v}"]
        (folder / "train_curve.csv").write_text("\n".join(lines) + "\n")

    main = [Job("diffusion_lac", "ves", "s_surface", s) for s in (0, 1, 2)]
    # 12 batches of 1,000 frames: the last 5,000 frames are batches 8-12
    curve(main[0], [0.1] * 11 + [0.4], [0.9] * 7 + [0.5] * 5)
    curve(main[1], [0.2] * 10 + [0.9, 0.6], [0.9] * 7 + [0.3] * 5)  # ends below its peak
    # seed 2 keeps the fixture's curve, which logs neither: not counted
    task = [Job("diffusion_lac", "ves", "s_surface", s, "task_cost") for s in (0, 1)]
    curve(task[0], [0.5] * 11 + [1.0], [0.6] * 12)
    curve(task[1], [1.0] * 12, [0.7] * 12)
    (root / "jobs" / task[1].name / "eval.csv").unlink()  # not finished: not counted
    write_report(root, ["lyapunov_cost"], seeds=(0, 1, 2), budget="paper")
    rows = json.loads((root / "report/lyapunov_cost/lyapunov_cost.json").read_text())["rows"]
    stability, task_cost = rows
    assert (stability["lambda_end"], stability["lambda_end_std"]) == pytest.approx(
        (0.5, math.sqrt(0.02))
    )
    assert (stability["lyapunov_violated_end"], stability["lyapunov_violated_end_std"]) == (
        pytest.approx((0.4, math.sqrt(0.02)))
    )
    assert task_cost["lambda_end"] == 1.0 and math.isnan(task_cost["lambda_end_std"])
    assert task_cost["lyapunov_violated_end"] == pytest.approx(0.6)
    md = (root / "report/lyapunov_cost/lyapunov_cost.md").read_text()
    assert "lambda_end" in md.splitlines()[2] and "train/violation_rate" in md.splitlines()[0]
