"""The paper's experimental section (§IV) as code: the jobs each figure and table needs
(:mod:`~torchrl_auv.report.paper.grid`), and the figures and tables from their run folders
(:func:`write_report`), the store that keeps finished jobs' outputs across machines
(:mod:`~torchrl_auv.report.paper.store`), and the results page
(:mod:`~torchrl_auv.report.paper.results_page`: the paper's claims judged by
:mod:`~torchrl_auv.report.paper.claims`). ``recipes/paper/run_all.py`` runs the jobs and calls
them."""

from __future__ import annotations

from torchrl_auv.report.paper import grid, store
from torchrl_auv.report.paper.report import REPORTS, write_report

__all__ = ["REPORTS", "grid", "store", "write_report"]
