"""Table III driver: rows, the Kalman filter in the loop, plots."""

from __future__ import annotations

import numpy as np
import pytest

from torchrl_auv.report import plot_tracking, tracking_table


def _errors_by_hand(trace) -> dict[str, float]:
    """Table III statistics from a trace, in numpy: |wrapped heading error| and |depth error|
    between setpoint and true state after the initial row; mean and (n-1) std over time per
    run, then the mean over runs."""
    sp, eta = trace.setpoint.double().numpy()[1:], trace.eta.double().numpy()[1:]
    d = sp[..., 1] - eta[..., 5]
    heading = np.abs(np.arctan2(np.sin(d), np.cos(d)))
    depth = np.abs(sp[..., 0] - eta[..., 2])
    return {
        "heading_error_mean": heading.mean(0).mean(),
        "heading_error_std": heading.std(0, ddof=1).mean(),
        "depth_error_mean": depth.mean(0).mean(),
        "depth_error_std": depth.std(0, ddof=1).mean(),
    }


def test_tracking_table_rows_and_kf_beats_usbl(tmp_path):
    rows, traces = tracking_table(("pid", "smc"), ("es",), runs=2, duration=30.0)
    assert [(r["sea_state"], r["controller"]) for r in rows] == [("es", "pid"), ("es", "smc")]
    for row in rows:
        assert row["kf_rms"] < row["usbl_rms"]
        expected = _errors_by_hand(traces[(row["sea_state"], row["controller"])])
        for key, value in expected.items():
            assert row[key] == pytest.approx(value, rel=1e-5, abs=1e-7), key
    path = plot_tracking(traces, "es", tmp_path / "es.png")
    assert path.stat().st_size > 10_000


def test_true_state_variant_has_no_kf_columns():
    rows, _ = tracking_table(("pid",), ("ideal",), runs=1, duration=5.0, localised=False)
    assert "kf_rms" not in rows[0]
