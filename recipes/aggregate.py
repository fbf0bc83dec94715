"""One table from a sweep: every job's eval.csv, mean ± std over seeds.

    .venv/bin/python recipes/aggregate.py runs/sweeps/fig7
    .venv/bin/python recipes/aggregate.py runs/sweeps/fig7 --policies expert random --csv fig7.csv

Rows: the sweep's axes (the overrides that differ between jobs, the seed excepted), the
evaluation sea state and the policy (by default each job's own framework); columns: the number
of runs and each metric as mean ± std (``torchrl_auv.report.sweeps``).

``--intervals``: each metric as its mean and 95 % stratified-bootstrap interval over runs
(rliable). ``--against KEY=VALUE``: then, for every group whose axis KEY has another value,
each metric's mean against the reference group's interval (inside or not) and the
probability that one of its runs improves on one of the reference's, e.g. two presets run
over the same seeds:

    .venv/bin/python recipes/aggregate.py runs/presets --intervals --against preset=paper

``--against policy=NAME`` compares each job's framework with another row of the same jobs, e.g.
the RL stage against its own prior (issue [21/26]'s question):

    .venv/bin/python recipes/aggregate.py runs/sweeps/rl_stage --against "policy=proposer alone"
"""

from __future__ import annotations

import argparse
import csv

from torchrl_auv.report.sweeps import (
    DEFAULT_METRICS,
    aggregate,
    compare,
    comparison_table,
    load_runs,
    markdown_table,
)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("root", help="the sweep's folder (run_root/sweeps/<name>)")
    parser.add_argument("--over", default="seed", help="the axis averaged over (default seed)")
    parser.add_argument(
        "--policies",
        nargs="+",
        default=None,
        help="policies to show (default: each job's own framework)",
    )
    parser.add_argument("--metrics", nargs="+", default=list(DEFAULT_METRICS))
    parser.add_argument("--csv", default=None, help="also write the table to this CSV file")
    parser.add_argument(
        "--intervals",
        action="store_true",
        help="each metric's mean with its 95 %% bootstrap interval over runs",
    )
    parser.add_argument(
        "--against",
        default=None,
        metavar="KEY=VALUE",
        help="compare every group with the one whose axis KEY is VALUE (KEY policy: another "
        "row of the same jobs)",
    )
    args = parser.parse_args(argv)
    axis, sep, reference = (args.against or "").partition("=")
    if args.against is not None and not (sep and axis and reference):
        parser.error(f"--against must be KEY=VALUE (e.g. preset=paper), got {args.against!r}")
    rows = load_runs(args.root)
    table = aggregate(
        rows, over=args.over, metrics=args.metrics, policies=args.policies, intervals=args.intervals
    )
    print(markdown_table(table, metrics=args.metrics))
    if args.against is not None:
        try:
            found = compare(
                rows,
                axis=axis,
                reference=reference,
                over=args.over,
                metrics=args.metrics,
                policies=args.policies,
            )
        except ValueError as error:
            parser.error(f"--against: {error}")
        print(f"\nagainst {axis}={reference} (95 % intervals over runs):\n")
        print(comparison_table(found))
    if args.csv and table:
        with open(args.csv, "w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(table[0]))
            writer.writeheader()
            writer.writerows(table)


if __name__ == "__main__":
    main()
