"""One table from a sweep: every job's eval.csv, mean ± std over seeds.

    .venv/bin/python recipes/aggregate.py runs/sweeps/fig7
    .venv/bin/python recipes/aggregate.py runs/sweeps/fig7 --policies expert random --csv fig7.csv

Rows: the sweep's axes (the overrides that differ between jobs, the seed excepted), the
evaluation sea state and the policy (by default each job's own framework); columns: the number
of runs and each metric as mean ± std (``torchrl_auv.report.sweeps``).
"""

from __future__ import annotations

import argparse
import csv

from torchrl_auv.report.sweeps import DEFAULT_METRICS, aggregate, load_runs, markdown_table


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
    args = parser.parse_args(argv)
    table = aggregate(load_runs(args.root), over=args.over, metrics=args.metrics,
                      policies=args.policies)  # fmt: skip
    print(markdown_table(table, metrics=args.metrics))
    if args.csv and table:
        with open(args.csv, "w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(table[0]))
            writer.writeheader()
            writer.writerows(table)


if __name__ == "__main__":
    main()
