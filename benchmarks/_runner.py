"""A small common runner for the benchmarks in this folder.

Each benchmark script builds a list of rows with :func:`measure`, prints them with
:func:`print_table` and ends with exactly one :func:`print_summary` line holding its ratios.
Benchmarks are never timed tests: they report, they do not assert.

Threads default to one (``OMP_NUM_THREADS=1``): on the 2-core development machines two torch
threads made small batched ops 4-50x slower than one. Pass ``--threads N`` to change it.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass


def setup(
    description: str,
    argv: Sequence[str] | None = None,
    add_arguments: Callable[[argparse.ArgumentParser], None] | None = None,
) -> argparse.Namespace:
    """Parse the common options (and a benchmark's own, from ``add_arguments``) and pin
    torch's thread count before heavy work starts."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--threads", type=int, default=1, help="torch intra-op threads")
    parser.add_argument("--quick", action="store_true", help="fewer repeats (smoke run)")
    if add_arguments is not None:
        add_arguments(parser)
    args = parser.parse_args(argv)
    os.environ["OMP_NUM_THREADS"] = str(args.threads)
    import torch

    torch.set_num_threads(args.threads)
    return args


@dataclass
class Timing:
    """Seconds per call: the median and the minimum over ``repeats`` timed blocks."""

    median: float
    best: float
    calls: int


def measure(
    fn: Callable[[], object], *, min_time: float = 0.5, repeats: int = 5, warmup: int = 3
) -> Timing:
    """Time ``fn`` in blocks of calls lasting about ``min_time / repeats`` seconds each."""
    for _ in range(warmup):
        fn()
    start = time.perf_counter()
    fn()
    one = max(time.perf_counter() - start, 1e-7)
    per_block = max(1, int(min_time / repeats / one))
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(per_block):
            fn()
        samples.append((time.perf_counter() - t0) / per_block)
    return Timing(statistics.median(samples), min(samples), per_block * repeats)


def print_table(title: str, header: Sequence[str], rows: Sequence[Sequence[object]]) -> None:
    """Print a fixed-width table: one header line, a rule, one line per row."""
    cells = [[_fmt(c) for c in row] for row in rows]
    widths = [max(len(h), *(len(r[i]) for r in cells)) for i, h in enumerate(header)]
    print(f"\n{title}")
    print("  ".join(h.rjust(w) for h, w in zip(header, widths, strict=True)))
    print("  ".join("-" * w for w in widths))
    for row in cells:
        print("  ".join(c.rjust(w) for c, w in zip(row, widths, strict=True)))


def print_summary(name: str, **values: object) -> None:
    """Print the one-line summary that closes every benchmark: ``SUMMARY name: k=v, ...``."""
    print(f"\nSUMMARY {name}: " + ", ".join(f"{k}={_fmt(v)}" for k, v in values.items()))


def _fmt(value: object) -> str:
    if isinstance(value, float):
        return f"{value:.4g}" if abs(value) < 1e5 else f"{value:,.0f}"
    return str(value)
