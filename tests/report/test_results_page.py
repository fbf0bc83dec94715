"""The results page: claims judged from the jobs' own numbers by the stated rule, every
figure and table of the report on the page, the run's facts, nothing not yet run shown as
a number."""

from __future__ import annotations

import csv
import json

from torchrl_auv.report.paper.claims import CLAIMS, compare, judge, verdict
from torchrl_auv.report.paper.grid import Job
from torchrl_auv.report.paper.results_page import write_results_page

COLUMNS = ("sea_state", "policy", "cost_mean", "ssn", "sdr_mbit", "ec_w")


def _finish(root, job, **metrics):
    """A finished job whose own policy row has ``metrics`` (the rest 0)."""
    folder = root / "jobs" / job.name
    folder.mkdir(parents=True)
    with open(folder / "eval.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=COLUMNS)
        writer.writeheader()
        writer.writerow(
            {
                "sea_state": job.sea,
                "policy": job.framework,
                "cost_mean": 0.0,
                "ssn": 0.0,
                "sdr_mbit": 0.0,
                "ec_w": 0.0,
                **metrics,
            }
        )


def _claim(text_start):
    return next(i for i, claim in enumerate(CLAIMS) if claim.text.startswith(text_start))


def test_the_outcome_follows_the_gap_against_the_standard_error():
    # gap 1.0; standard error sqrt(2 * 0.9^2 / 3) = 0.73 (holds) or sqrt(2 * 1.5^2 / 3) = 1.22
    assert compare((3.0, 0.9, 3), (2.0, 0.9, 3), higher=True) == "holds"
    assert compare((3.0, 1.5, 3), (2.0, 1.5, 3), higher=True) == "within noise"
    assert compare((2.0, 0.9, 3), (3.0, 0.9, 3), higher=False) == "holds"  # lower is better
    assert compare((3.0, 0.0, 1), (2.0, 0.0, 1), higher=True) == "within noise"  # one seed
    assert compare((2.0, 1.5, 3), (3.0, 1.5, 3), higher=True) == "reversed within noise"
    assert compare((2.0, 0.0, 1), (3.0, 0.0, 1), higher=True) == "reversed within noise"
    assert compare((3.0, 0.1, 3), (float("nan"), 0.0, 0), higher=True) == "missing"
    assert verdict(["holds", "within noise"]) == "partly"
    assert verdict(["reversed", "missing"]) == "not reproduced (1 of 2 comparisons ran)"
    assert verdict(["reversed within noise", "within noise"]) == "inconclusive"


def test_claims_are_judged_from_each_jobs_own_row(tmp_path):
    """RL (SAC) against both diffusion frameworks in every sea: the diffusion jobs cost less
    than SAC by far in ideal and ES, and more in VES: 'partly', with VES reversed."""
    seeds = (0, 1, 2)
    for seed in seeds:
        for sea in ("ideal", "es", "ves"):
            _finish(tmp_path, Job("sac", sea, "s_surface", seed), cost_mean=2.0 + 0.01 * seed)
            for framework in ("diffusion_rl", "diffusion_lac"):
                cost = 3.0 if sea == "ves" else 1.0 + 0.01 * seed
                _finish(
                    tmp_path,
                    Job(framework, sea, "s_surface", seed),
                    cost_mean=cost,
                    ssn=5.0 + seed,
                    sdr_mbit=9.0 + seed,
                )
    rows = judge(tmp_path, seeds)
    cost = rows[_claim("Diffusion+RL and Diffusion+RL (LAC) reach a better return")]
    outcomes = [outcome for outcome, _ in cost["comparisons"]]
    assert outcomes == ["holds"] * 4 + ["reversed"] * 2
    assert cost["verdict"] == "partly"
    assert "ves: Diffusion+RL 3 ± 0 vs RL 2.01 ± 0.01" in cost["comparisons"][4][1]
    # seeds whose row lacks the metric are not counted: one value is one seed, no spread
    for seed in (1, 2):
        (tmp_path / "jobs" / Job("sac", "ideal", "s_surface", seed).name / "eval.csv").write_text(
            "sea_state,policy,cost_mean\nideal,sac,nan\n"
        )
    first = judge(tmp_path, seeds)[_claim("Diffusion+RL and Diffusion+RL (LAC) reach a better")]
    assert first["comparisons"][0] == (
        "within noise",
        "ideal: Diffusion+RL 1.01 ± 0.01 vs RL 2 (one seed)",
    )
    ssn = rows[_claim("... and serve more sensor nodes")]
    assert ssn["verdict"] == "reproduced"  # 5-7 nodes against SAC's 0, every sea
    sdr = rows[_claim("... and deliver more data (SDR)")]
    assert sdr["verdict"] == "reproduced" and len(sdr["comparisons"]) == 6  # 9-11 against 0
    # the claims whose jobs did not run say so
    assert rows[_claim("The return falls monotonically")]["verdict"] == "not run yet"


def test_the_page_embeds_the_report_and_counts_the_finished_jobs(tmp_path):
    root, page = tmp_path / "run", tmp_path / "docs" / "results.md"
    jobs = [Job("sac", "ves", "s_surface", 0), Job("diffusion", "ves", "s_surface", 0)]
    _finish(root, jobs[0], cost_mean=2.0)
    (root / "jobs" / jobs[0].name / "summary.md").write_text(
        "- wall time this session (s): 3600\n- training frames/s: 41.5\n"
        "- evaluation wall time (s): 1800\n"
    )
    report = root / "report"
    (report / "fig7").mkdir(parents=True)
    (report / "fig7" / "fig7.png").write_bytes(b"\x89PNG figure")
    (report / "table2").mkdir()
    (report / "table2" / "table2.md").write_text(
        "budget paper, seeds [0]\n\n| framework | ssn |\n|---|---|\n| LAC | nan ± nan |\n"
    )
    (report / "run.json").write_text(
        json.dumps(
            {
                "budget": "paper",
                "frames": 50000,
                "commit": "abc1234",
                "command": "run_all.py x",
                "date": "2026-12-04",
                "machine": "Linux",
            }
        )
    )
    sittings = [
        {
            "start": "2026-12-04T19:00:00+00:00",
            "end": "2026-12-04T20:30:00+00:00",
            "jobs_finished": 3,
        },
        {
            "start": "2026-12-05T09:00:00+00:00",
            "end": "2026-12-05T09:45:00+00:00",
            "jobs_finished": 1,
        },
    ]
    write_results_page(root, page, seeds=[0], jobs=jobs, sittings=sittings)
    text = page.read_text()
    assert (tmp_path / "docs" / "results" / "fig7.png").read_bytes() == b"\x89PNG figure"
    assert "![Fig. 7: learning curves](results/fig7.png)" in text
    assert "*budget paper, seeds [0]*" in text and "| LAC | – |" in text
    assert "nan" not in text
    assert "**1 of 2**" in text
    # 4 jobs in 2.25 h of sittings: the one left takes about 0.56 h
    assert (
        "| jobs finished | 1 of 2; about 0.6 h more at the sittings' rate so far (1.8 jobs "
        "per hour) |"
    ) in text
    assert "| wall time | 2.2 h over 2 sittings" in text and "4 jobs finished in them" in text
    assert (
        "| training speed | frames/s per job as the grid ran them, median and range: RL "
        "(SAC) 42 (1 job) |"
    ) in text
    assert "1.5 h of one core" in text and "`abc1234`" in text and "50,000 frames" in text
    # every claim has its verdict row, and an experiment without outputs says so
    assert text.count("| **not run yet** |") == len(CLAIMS)
    assert "Not in this report" in text
    # the RL stage against its prior: no Diffusion+RL job among these
    assert "## The RL stage against its own prior" in text
    assert "no Diffusion+RL or Diffusion+RL (LAC) job has finished" in text
    assert "No job has logged which candidate it executed yet" in text


def test_rank_returns_and_the_convergence_point_are_the_pages_own(tmp_path):
    """Fig. 8's order is of returns (cost x decisions: CA4's episodes end early, so its return
    beats CA3's though its cost per decision is worse); the convergence claim looks at the
    first evaluation after frame 0 (at frame 0 nothing has trained)."""
    for seed in (0, 1, 2):
        folder = tmp_path / "jobs" / Job("diffusion_lac", "ves", "s_surface", seed).name
        folder.mkdir(parents=True)
        rows = ["sea_state,policy,cost_mean,decisions"]
        for policy, cost, decisions in (
            ("OA", 1.0, 1000),
            ("CA1", 1.2, 1000),
            ("CA2", 1.4, 1000),
            ("CA3", 1.6, 1000),
            ("CA4", 5.0, 100),
        ):
            rows.append(f"ves,{policy},{cost + 0.01 * seed},{decisions}")
        (folder / "eval.csv").write_text("\n".join(rows) + "\n")
    curve = [
        {
            "sea_state": sea,
            "framework": label,
            "metric": "eval/cost_mean",
            "frames": f,
            "runs": 3,
            "value": value,
            "value_std": 0.01,
        }
        for sea in ("ideal", "es", "ves")
        for label, at0, at25 in (
            ("RL (SAC)", 20.0, 1.5),
            ("Diffusion+RL", 1.6, 2.0),
            ("Diffusion+RL (LAC)", 1.6, 2.0),
        )
        for f, value in ((0, at0), (25000, at25))
    ]
    (tmp_path / "report" / "fig7").mkdir(parents=True)
    (tmp_path / "report" / "fig7" / "fig7.json").write_text(json.dumps({"rows": curve}))
    rows = judge(tmp_path, (0, 1, 2))
    ranks = rows[_claim("The return falls monotonically")]["comparisons"]
    assert [o for o, _ in ranks] == ["holds", "holds", "holds", "reversed"]
    assert ranks[3][1] == "CA3 -1.61e+03 ± 10 vs CA4 -501 ± 1"
    faster = rows[_claim("... and converge faster")]
    assert [o for o, _ in faster["comparisons"]] == ["reversed"] * 6
    assert faster["verdict"] == "not reproduced"


def test_the_contraction_ratio_weighs_each_decision_by_its_running_episodes(tmp_path):
    """Fig. 10's ratio (last tenth over first tenth of the Lyapunov trace) pools the episodes
    still running: a late decision of one surviving episode weighs 1/8 of a decision of all
    eight, and decisions after every episode ended (no value) are not part of the trace."""

    def trace(variant, seed, rows):
        folder = tmp_path / "jobs" / Job("diffusion_lac", "ves", "s_surface", seed, variant).name
        folder.mkdir(parents=True)
        lines = ["decision,mean,std,episodes"]
        lines += [f"{i},{mean},0.0,{episodes}" for i, (mean, episodes) in enumerate(rows)]
        (folder / "lyapunov_trace.csv").write_text("\n".join(lines) + "\n")

    middle = [(5.0, 8)] * 16  # 20 decisions with episodes running: a tenth is 2
    for seed in (0, 1, 2):
        # alpha 0.1: last tenth (2 x 8 + 20 x 1) / 9 = 4 over 10: 0.4 (not (2 + 20) / 2 / 10),
        # then two decisions with no episode left
        trace(
            "fixed-softplus-alpha0.1",
            seed,
            [(10.0, 8)] * 2 + middle + [(2.0, 8), (20.0, 1), ("nan", 0), ("nan", 0)],
        )
        # alpha 0.05: (8 x 8 + 8 x 8) / 16 = 8 over 10: 0.8
        trace("fixed-softplus-alpha0.05", seed, [(10.0, 8)] * 2 + middle + [(8.0, 8)] * 2)
    rows = judge(tmp_path, (0, 1, 2))
    pairs = rows[_claim("A larger stability weight alpha contracts")]["comparisons"]
    assert pairs[0] == ("holds", "softplus-alpha0.1 0.4 ± 0 vs softplus-alpha0.05 0.8 ± 0")


def test_training_speed_counts_sessions_that_trained_and_training_jobs_only(tmp_path):
    """The proposer alone (its 1,000 acting frames) and a short resumed session (mostly
    start-up) say nothing about training speed; the sampler ablation is its own row."""
    root, page = tmp_path / "run", tmp_path / "docs" / "results.md"
    facts = {
        Job("diffusion_lac", "ves", "s_surface", 0): (40.0, 1250),
        Job("diffusion_lac", "ves", "s_surface", 1): (50.0, 1000),
        Job("diffusion_lac", "ves", "s_surface", 2): (90.0, 100),  # 9,000 frames
        Job("diffusion_lac", "es", "s_surface", 0): (60.0, 1000),  # stated: 15,000
        Job("diffusion_lac", "ves", "s_surface", 0, "ddim10"): (77.0, 650),
        Job("diffusion", "ves", "s_surface", 0): (5.0, 200),
    }
    for job, (fps, wall) in facts.items():
        _finish(root, job)
        stated = "- frames this session: 15000\n" if job.sea == "es" else ""
        (root / "jobs" / job.name / "summary.md").write_text(
            f"{stated}- wall time this session (s): {wall}\n- training frames/s: {fps}\n"
        )
    text = write_results_page(root, page, seeds=[0, 1, 2], jobs=list(facts)).read_text()
    assert (
        "median and range: Diffusion+RL (LAC) 45, 40-50 (2 jobs); Diffusion+RL (LAC), "
        "10 DDIM steps 77 (1 job) |"
    ) in text


def test_the_pages_k_is_the_paper_presets_number_of_candidates():
    import pathlib

    from hydra import compose, initialize_config_dir

    from torchrl_auv.report.paper.results_page import NUM_CANDIDATES

    recipes = pathlib.Path(__file__).resolve().parents[2] / "recipes"
    for framework in ("diffusion_rl", "diffusion_lac"):
        with initialize_config_dir(config_dir=str(recipes / framework), version_base="1.3"):
            preset = compose("paper")
        assert preset.proposer.num_candidates == NUM_CANDIDATES, framework
