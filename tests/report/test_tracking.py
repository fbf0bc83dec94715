"""Table III driver: rows, the Kalman filter in the loop, plots."""

from __future__ import annotations

from torchrl_auv.report import plot_tracking, tracking_table


def test_tracking_table_rows_and_kf_beats_usbl(tmp_path):
    rows, traces = tracking_table(("pid", "smc"), ("es",), runs=2, duration=30.0)
    assert [(r["sea_state"], r["controller"]) for r in rows] == [("es", "pid"), ("es", "smc")]
    for row in rows:
        assert row["kf_rms"] < row["usbl_rms"]
        assert 0 <= row["heading_error_mean"] < 3.2 and row["depth_error_std"] >= 0
    path = plot_tracking(traces, "es", tmp_path / "es.png")
    assert path.stat().st_size > 10_000


def test_true_state_variant_has_no_kf_columns():
    rows, _ = tracking_table(("pid",), ("ideal",), runs=1, duration=5.0, localised=False)
    assert "kf_rms" not in rows[0]
