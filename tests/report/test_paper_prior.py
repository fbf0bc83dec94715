"""The RL stage against its own prior: each finished Diffusion+RL / Diffusion+RL (LAC) job's
evaluation at frame 0 and at the end against the same job's proposer alone, counted."""

from __future__ import annotations

import math

import pytest

from torchrl_auv.report.paper.grid import Job
from torchrl_auv.report.paper.prior import (
    cost_term_changes,
    extreme_shares,
    format_cost_term_changes,
    format_extreme_shares,
    format_prior,
    prior_counts,
)


def _job(root, job, *, start, end, end_ssn, alone=(1.5, 10.0), curve=True):
    folder = root / "jobs" / job.name
    folder.mkdir(parents=True)
    (folder / "eval.csv").write_text(
        "sea_state,policy,cost_mean,ssn\n"
        f"{job.sea},{job.framework},{end},{end_ssn}\n"
        f"{job.sea},proposer alone,{alone[0]},{alone[1]}\n"
    )
    if curve:
        (folder / "eval_curve.csv").write_text(
            f"step,key,value\n0,eval/cost_mean,{start}\n25000,eval/cost_mean,{end}\n"
        )


def test_each_job_is_compared_with_its_own_proposer_alone(tmp_path):
    rl = [Job("diffusion_rl", "es", "s_surface", s) for s in (0, 1, 2)]
    lac = [
        Job("diffusion_lac", "ves", "pid", 0),
        Job("diffusion_lac", "ves", "s_surface", 0, "fixed-softplus-alpha0.1"),
    ]
    _job(tmp_path, rl[0], start=6.0, end=1.2, end_ssn=8.0)  # starts worse, ends cheaper, fewer
    _job(tmp_path, rl[1], start=1.4, end=1.45, end_ssn=12.0, alone=(1.5, 10.0))
    # within 1 % of the proposer alone's value: a tie, counted as compared but not as holding
    _job(tmp_path, rl[2], start=1.51, end=1.495, end_ssn=9.95, alone=(1.5, 10.0))
    _job(tmp_path, lac[0], start=5.0, end=1.4, end_ssn=9.0, curve=False)  # no frame-0 point
    _job(tmp_path, lac[1], start=9.0, end=1.0, end_ssn=1.0)  # a variant: left out
    unfinished = Job("diffusion_lac", "ves", "smc", 0)  # no eval.csv: not counted
    others = [Job("sac", "es", "s_surface", 0), Job("diffusion", "es", "s_surface", 0)]
    counts = prior_counts(tmp_path, [*rl, *lac, unfinished, *others])
    assert counts["diffusion_rl"] == {
        "jobs": 3,
        "start_worse": (1, 3),
        "end_cheaper": (2, 3),
        "end_fewer_ssn": (1, 3),
    }
    assert counts["diffusion_lac"] == {
        "jobs": 1,
        "start_worse": (0, 0),
        "end_cheaper": (1, 1),
        "end_fewer_ssn": (1, 1),
    }
    text = "\n".join(format_prior(counts))
    assert "| costs more than the proposer alone at frame 0" in text
    assert "| 1 of 3 | 0 of 0 |" in text and "| 2 of 3 | 1 of 1 |" in text


def test_no_finished_rl_stage_says_so(tmp_path):
    counts = prior_counts(tmp_path, [Job("diffusion_rl", "es", "s_surface", 0)])
    assert counts["diffusion_rl"]["jobs"] == 0
    assert "no Diffusion+RL or Diffusion+RL (LAC) job has finished" in "\n".join(
        format_prior(counts)
    )


def _curve(root, job, shares, *, finished=True):
    """``train_curve.csv`` with ``train/selected_extreme_1`` (heading) at 1000-frame batches
    (and an ``eval.csv`` where the job has ``finished``)."""
    folder = root / "jobs" / job.name
    folder.mkdir(parents=True, exist_ok=True)
    if finished:
        row = f"{job.sea},{job.framework},1.0"
        (folder / "eval.csv").write_text(f"sea_state,policy,cost_mean\n{row}\n")
    lines = ["step,key,value"]
    for i, share in enumerate(shares, start=1):
        lines += [f"{1000 * i},train/cost_mean,2.0", f"{1000 * i},train/selected_extreme_1,{share}"]
    (folder / "train_curve.csv").write_text("\n".join(lines) + "\n")


def test_extreme_shares_average_each_jobs_first_and_last_frames_over_jobs(tmp_path):
    rl = [Job("diffusion_rl", "es", "s_surface", s) for s in (0, 1, 2)]
    # 12 batches: the first 5,000 frames are batches 1-5, the last 5,000 batches 8-12
    _curve(tmp_path, rl[0], [0.8, 0.6, 0.6, 0.6, 0.4, 0.0, 0.0, 0.5, 0.5, 0.5, 0.5, 0.5])
    _curve(tmp_path, rl[1], [1.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.3, 0.3, 0.3, 0.3, 0.3])
    (tmp_path / "jobs" / rl[2].name).mkdir(parents=True)  # no curve: not counted
    running = Job("diffusion_rl", "ves", "s_surface", 0)
    _curve(tmp_path, running, [0.0] * 12, finished=False)  # no eval.csv yet: not counted
    alone = Job("diffusion", "es", "s_surface", 0)
    _curve(tmp_path, alone, [0.1] * 12)  # the proposer alone (its own K): left out
    short = Job("diffusion_lac", "es", "s_surface", 0)
    _curve(tmp_path, short, [0.9, 0.7, 0.8, 0.8, 0.8, 0.0, 0.0])  # < two windows: no last
    lac = Job("diffusion_lac", "ves", "s_surface", 0, "fixed-softplus-alpha0.1")
    _curve(tmp_path, lac, [0.9] * 12)  # a variant: left out
    shares = extreme_shares(tmp_path, [*rl, running, alone, short, lac], window=5000)
    cell = shares["diffusion_rl"]["heading"]
    assert cell["jobs"] == 2
    assert cell["first"] == pytest.approx((0.8, math.sqrt(0.08)))  # job means 0.6 and 1.0
    assert cell["last"] == pytest.approx((0.4, math.sqrt(0.02)))  # 0.5 and 0.3
    assert "diffusion" not in shares
    assert shares["diffusion_lac"]["heading"]["jobs"] == 1
    assert shares["diffusion_lac"]["heading"]["first"][0] == pytest.approx(0.8)
    assert math.isnan(shares["diffusion_lac"]["heading"]["last"][0])
    assert shares["diffusion_rl"]["depth"]["jobs"] == 0  # not logged in these curves
    text = "\n".join(format_extreme_shares(shares, num_candidates=5))
    assert "0.8 ± 0.283" in text and "0.4 ± 0.141" in text and "0.8 (one job)" in text
    assert "2 / K = 0.4" in text


def test_no_logged_selection_says_so(tmp_path):
    shares = extreme_shares(tmp_path, [Job("diffusion_rl", "es", "s_surface", 0)])
    assert "No job has logged" in "\n".join(format_extreme_shares(shares, num_candidates=5))


def _terms_job(root, job, own, alone, *, ended=(0.0, 0.0), variant_csv=False):
    """``eval.csv`` with the cost, whether a scene ended early and each term's share, for the
    job's row and its proposer alone's; ``own`` / ``alone``: ``(cost_mean, {term: share})``
    (terms not named share what is left equally)."""
    from torchrl_auv.report.paper.prior import COST_TERMS_V2 as COST_TERMS

    folder = root / "jobs" / job.name
    folder.mkdir(parents=True)
    header = "sea_state,policy,cost_mean,ssn,terminated," + ",".join(
        f"share_{t}" for t in COST_TERMS
    )
    rows = [header]
    for policy, (cost, named), end in (
        (job.framework, own, ended[0]),
        ("proposer alone", alone, ended[1]),
    ):
        rest = (1.0 - sum(named.values())) / (len(COST_TERMS) - len(named))
        shares = [named.get(t, rest) for t in COST_TERMS]
        rows.append(f"{job.sea},{policy},{cost},8,{end}," + ",".join(map(str, shares)))
    (folder / "eval.csv").write_text("\n".join(rows) + "\n")


def test_cost_term_changes_split_each_jobs_change_by_term(tmp_path):
    rl = [Job("diffusion_rl", "es", "s_surface", s) for s in (0, 1, 2)]
    # seed 0: violation 0.5 -> 0.1, distance 0.2 -> 0.3 (cost 2.0 -> 1.6)
    _terms_job(
        tmp_path,
        rl[0],
        (1.6, {"violation": 0.1 / 1.6, "distance": 0.3 / 1.6}),
        (2.0, {"violation": 0.25, "distance": 0.1}),
    )
    # seed 1: violation 0.3 -> 0.1, distance 0.2 -> 0.205 (within 1 % of 2.0: a tie)
    _terms_job(
        tmp_path,
        rl[1],
        (1.805, {"violation": 0.1 / 1.805, "distance": 0.205 / 1.805}),
        (2.0, {"violation": 0.15, "distance": 0.1}),
    )
    # seed 2: a scene of the proposer alone ended early: its termination cost is in no term
    _terms_job(tmp_path, rl[2], (1.0, {}), (700.0, {}), ended=(0.0, 0.25))
    variant = Job("diffusion_lac", "ves", "s_surface", 0, "fixed-softplus-alpha0.1")
    _terms_job(tmp_path, variant, (1.0, {"violation": 0.0}), (2.0, {"violation": 0.5}))
    older = Job("diffusion_lac", "es", "pid", 0)  # an eval.csv without the shares: left out
    _job(tmp_path, older, start=2.0, end=1.0, end_ssn=8.0)
    changes = cost_term_changes(tmp_path, [*rl, variant, older, Job("sac", "es", "pid", 0)])
    cell = changes["diffusion_rl"]
    assert cell["jobs"] == 2 and cell["ended_early"] == 1
    assert cell["violation"]["change"] == pytest.approx((-0.3, math.sqrt(0.02)))
    assert (cell["violation"]["lower"], cell["violation"]["higher"]) == (2, 0)
    assert cell["distance"]["change"] == pytest.approx((0.0525, math.sqrt(0.0045125)))
    assert (cell["distance"]["lower"], cell["distance"]["higher"]) == (0, 1)
    assert cell["total"]["change"] == pytest.approx((-0.2975, math.sqrt(0.0210125)))
    assert changes["diffusion_lac"]["jobs"] == 0
    text = "\n".join(format_cost_term_changes(changes))
    assert "| violation" in text and "-0.3 ± 0.141 (lower in 2, higher in 0 of 2)" in text
    assert "1 job left out" in text


def test_no_job_with_cost_terms_says_so(tmp_path):
    changes = cost_term_changes(tmp_path, [Job("diffusion_rl", "es", "s_surface", 0)])
    assert "No finished" in "\n".join(format_cost_term_changes(changes))
