"""Intervals over training runs (rliable's stratified bootstrap) and the sweep table's use of
them: closed forms where there are some, the normal approximation where there is not."""

from __future__ import annotations

import math

import numpy as np
import pytest

from torchrl_auv.report.intervals import Interval, interval, probability_of_improvement
from torchrl_auv.report.sweeps import aggregate, compare, comparison_table, markdown_table


def test_the_mean_interval_of_many_runs_is_the_normal_one():
    # percentile bootstrap of a mean: mean +- 1.96 s / sqrt(n) (s with ddof 0) for large n
    scores = np.random.default_rng(3).normal(10.0, 2.0, size=200)
    found = interval(scores, reps=4000, seed=1)
    half = 1.96 * scores.std() / math.sqrt(scores.size)
    assert found.point == pytest.approx(scores.mean())
    assert found.low == pytest.approx(scores.mean() - half, abs=0.15 * half)
    assert found.high == pytest.approx(scores.mean() + half, abs=0.15 * half)


def test_the_iqm_drops_the_outer_quarters_and_a_constant_has_no_spread():
    assert interval([0.0, 1.0, 2.0, 3.0, 100.0], "iqm", reps=200).point == pytest.approx(2.0)
    assert interval([0.0, 1.0, 2.0, 3.0, 100.0], reps=200).point == pytest.approx(21.2)
    flat = interval([1.5] * 5, reps=200)
    assert (flat.point, flat.low, flat.high) == (1.5, 1.5, 1.5)
    assert 1.5 in flat and 1.6 not in flat


def test_the_probability_of_improvement_counts_pairs_of_runs():
    assert probability_of_improvement([5.0, 6.0], [1.0, 2.0], reps=200).point == 1.0
    assert probability_of_improvement([1.0, 2.0], [5.0, 6.0], reps=200).point == 0.0
    assert probability_of_improvement([2.0, 2.0], [2.0, 2.0], reps=200).point == 0.5  # ties
    # (1 > 2) = 0, (3 > 2) = 1
    assert probability_of_improvement([1.0, 3.0], [2.0], reps=200).point == 0.5


def test_the_same_seed_gives_the_same_interval():
    scores = [1.0, 1.4, 0.9, 1.7, 1.2]
    assert interval(scores, seed=4) == interval(scores, seed=4)
    assert isinstance(interval(scores), Interval)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"statistic": "median"}, "statistic must be"),
        ({"confidence": 1.5}, "confidence must be"),
        ({"reps": 10}, "reps must be"),
        ({"scores": []}, "scores must be"),
        ({"scores": [1.0, float("nan")]}, "scores must be"),
    ],
)
def test_bad_arguments_are_refused_naming_them(kwargs, match):
    call = {"scores": [1.0, 2.0], **kwargs}
    with pytest.raises(ValueError, match=match):
        interval(**call)


def _rows(preset: str, costs, sdrs):
    return [
        {
            "sea_state": "ves",
            "policy": "lac",
            "framework": "lac",
            "preset": preset,
            "seed": str(seed),
            "run": f"{preset}-{seed}",
            "cost_mean": cost,
            "sdr_mbit": sdr,
        }
        for seed, (cost, sdr) in enumerate(zip(costs, sdrs, strict=True))
    ]


def test_compare_says_whether_a_preset_lies_inside_the_reference_interval():
    rows = _rows("paper", [1.0, 1.1, 1.2, 1.3, 1.4], [5.0, 6.0, 7.0, 8.0, 9.0])
    rows += _rows("fast", [0.5] * 5, [6.5, 7.0, 7.5, 7.0, 7.0])
    pairs = compare(
        rows, axis="preset", reference="paper", metrics=("cost_mean", "sdr_mbit"), reps=500
    )
    found = {row["metric"]: row for row in pairs}
    assert not found["cost_mean"]["inside"]
    assert found["cost_mean"]["improvement"].point == 1.0  # a lower cost is the better one
    assert found["sdr_mbit"]["inside"] and found["sdr_mbit"]["mean"] == pytest.approx(7.0)
    assert found["sdr_mbit"]["reference"].low < 7.0 < found["sdr_mbit"]["reference"].high
    assert "| fast |" in comparison_table(list(found.values()))
    with pytest.raises(ValueError, match="reference must be one of"):
        compare(rows, axis="preset", reference="slow", metrics=("cost_mean",))
    with pytest.raises(ValueError, match="axis must be one of"):
        compare(rows, axis="sampler", reference="paper", metrics=("cost_mean",))


def test_compare_sets_each_framework_against_another_row_of_its_own_jobs():
    rows = _rows("paper", [1.0, 1.1, 1.2, 1.3], [5.0, 6.0, 7.0, 8.0])
    alone = _rows("paper", [0.9, 1.0, 1.1, 1.2], [9.0, 9.5, 10.0, 11.0])
    rows += [{**row, "policy": "proposer alone"} for row in alone]
    rows += [{**row, "policy": "expert", "sdr_mbit": 0.0} for row in alone]  # neither side
    pairs = compare(
        rows, axis="policy", reference="proposer alone", metrics=("sdr_mbit",), reps=500
    )
    assert [(row["policy"], row["runs"], row["reference_runs"]) for row in pairs] == [("lac", 4, 4)]
    assert pairs[0]["improvement"].point == 0.0 and not pairs[0]["inside"]
    assert pairs[0]["mean"] == pytest.approx(6.5)
    with pytest.raises(ValueError, match="reference must be one of"):
        compare(rows, axis="policy", reference="idle", metrics=("sdr_mbit",))


def test_the_sweep_table_shows_the_interval_when_asked():
    rows = _rows("paper", [1.0, 1.1, 1.2], [5.0, 6.0, 7.0])
    table = aggregate(rows, metrics=("cost_mean",), intervals=True, reps=500)
    assert table[0]["cost_mean_low"] <= 1.1 <= table[0]["cost_mean_high"]
    assert "1.1 [" in markdown_table(table, metrics=("cost_mean",))
    plain = markdown_table(aggregate(rows, metrics=("cost_mean",)), metrics=("cost_mean",))
    assert "1.1 ± 0.1" in plain


def test_the_aggregate_script_compares_two_presets_run_over_the_same_seeds(tmp_path, capsys):
    from recipes.aggregate import main

    for preset, costs in (("paper", (1.0, 1.2, 1.4)), ("fast", (1.1, 1.2, 1.3))):
        for seed, cost in enumerate(costs):
            job = tmp_path / f"{preset}-s{seed}"
            (job / ".hydra").mkdir(parents=True)
            (job / ".hydra/overrides.yaml").write_text(
                f"- framework=lac\n- seed={seed}\n- preset={preset}\n- run_dir={job}\n"
            )
            (job / "eval.csv").write_text(f"sea_state,policy,cost_mean\nves,lac,{cost}\n")
    main([str(tmp_path), "--metrics", "cost_mean", "--intervals", "--against", "preset=paper"])
    out = capsys.readouterr().out
    assert "| paper | lac | ves | lac | 3 | 1.2 [" in out
    assert "| fast | lac | ves | lac | cost_mean | 3 | 1.2 | 3 | 1.2 [1, 1.4] | yes |" in out
    with pytest.raises(SystemExit):
        main([str(tmp_path), "--against", "preset"])
    assert "--against must be KEY=VALUE" in capsys.readouterr().err
