"""Metrics tables, plots and the paper's experiments as functions.

Owns experiment drivers that compose the layers below (e.g. the Table III tracking comparison
of the low-level controllers behind the Kalman filter, :mod:`torchrl_auv.report.tracking`) and
their tables and figures. Recipes call these; they hold no library logic of their own.
"""

from __future__ import annotations

from torchrl_auv.report.curves import plot_learning_curve, read_curve
from torchrl_auv.report.episode import plot_episode
from torchrl_auv.report.lyapunov_trace import (
    executed_lyapunov,
    lyapunov_trace,
    write_lyapunov_trace,
)
from torchrl_auv.report.proposals import (
    plot_candidate_stages,
    plot_pretraining_loss,
    setpoint_paths,
)
from torchrl_auv.report.run_plots import plot_run
from torchrl_auv.report.tracking import KalmanObserver, plot_tracking, tracking_table

__all__ = [
    "KalmanObserver",
    "executed_lyapunov",
    "lyapunov_trace",
    "plot_candidate_stages",
    "plot_episode",
    "plot_learning_curve",
    "plot_pretraining_loss",
    "plot_run",
    "plot_tracking",
    "read_curve",
    "setpoint_paths",
    "tracking_table",
    "write_lyapunov_trace",
]
