"""The paper's experimental section (§IV) as code: the jobs each figure and table needs
(:mod:`~torchrl_auv.report.paper.grid`), and the figures and tables from their run folders
(:func:`write_report`). ``recipes/paper/run_all.py`` runs the jobs and calls it."""

from __future__ import annotations

from torchrl_auv.report.paper import grid
from torchrl_auv.report.paper.report import REPORTS, write_report

__all__ = ["REPORTS", "grid", "write_report"]
