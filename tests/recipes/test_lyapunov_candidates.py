"""recipes/lyapunov_candidates.py: hand-made Lyapunov candidates on the expert's and idle
AUVs' approach legs, each policy's one rollout scored by every candidate."""

from __future__ import annotations

import csv
import math

import pytest

from recipes.lyapunov_candidates import main, measure


def test_every_candidate_scores_the_same_transitions_of_one_rollout():
    rows = measure(["ideal"], scenes=1, steps=40, seed=5, alpha=0.1)
    assert [(r["policy"], r["candidate"]) for r in rows] == [
        ("expert", "decisions_to_go"),
        ("expert", "distance_squared"),
        ("idle", "decisions_to_go"),
        ("idle", "distance_squared"),
    ]
    for policy in ("expert", "idle"):
        one, other = (r for r in rows if r["policy"] == policy)
        # one rollout, one set of approach transitions and costs, two functions of them
        assert one["transitions"] == other["transitions"] > 0
        assert one["margin_mean"] == pytest.approx(other["margin_mean"])
        assert one["change_std"] != pytest.approx(other["change_std"])
        for row in (one, other):
            assert 0.0 <= row["decrease_holds"] <= 1.0
            assert 1 - row["decrease_holds"] <= row["violation_upper95"] <= 1.0
            assert math.isfinite(row["delta_mean"])


def test_the_table_and_the_csv(tmp_path, capsys):
    out = tmp_path / "candidates.csv"
    main(["--seas", "ideal", "--scenes", "1", "--steps", "30", "--csv", str(out)])
    printed = capsys.readouterr().out
    assert printed.count("| ideal |") == 4
    rows = list(csv.DictReader(out.open()))
    assert {r["candidate"] for r in rows} == {"decisions_to_go", "distance_squared"}
