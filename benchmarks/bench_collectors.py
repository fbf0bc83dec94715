"""Collection frames/s of the scale-out backends against one process (issue [12/13]).

Each backend collects ``--frames`` frames (default 4000) from the data-collection env (ideal
sea, 2 scenes per worker, 300-decision episodes) with an untrained SAC actor (64x64), the
weights pushed to the workers after every batch of 200 frames as a training loop does:

* ``local x1``: TorchRL's ``Collector`` in this process;
* ``local x2``: ``MultiSyncCollector``, 2 spawned worker processes;
* ``ray x2``: ``RayCollector``, 2 remote collectors on a local Ray instance (``ray.init`` with 2
  CPUs; skipped without the ``.[ray]`` extra).

Printed per backend: the time from construction to the first batch (start-up and the first
batch, s), the steady rate over the batches after the first (frames/s) and its ratio to
``local x1``. One process with one torch thread leaves the second core of a 2-core machine
idle; two workers use it (less the weight pushes and the batch transfers).

``--sweeps`` also times the 4-job ``tiny`` sweep of ``recipes/train.py`` run by Hydra's basic
launcher (one job after the other) and by Hydra's Ray launcher (2 CPUs: two jobs at a time),
wall time each.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import tempfile
import time
from functools import partial
from pathlib import Path

from _runner import print_summary, print_table, setup

REPO = Path(__file__).resolve().parents[1]
BACKENDS = (("local", 1), ("local", 2), ("ray", 2))


def _collect(backend: str, workers: int, frames: int) -> tuple[float, float]:
    """``(start-up s, steady frames/s)`` of one backend."""
    from torchrl_auv.training import make_actor, make_collector, make_env

    create = partial(make_env, "ideal", num_envs=2, max_steps=300)
    actor = make_actor(create(seed=0), hidden=(64, 64))
    start = time.perf_counter()
    collector = make_collector(
        create,
        actor,
        seed=0,
        frames_per_batch=200,
        total_frames=frames,
        num_workers=workers,
        backend=backend,
    )
    first, steady_frames = None, 0
    for data in collector:
        if first is None:
            first = time.perf_counter()
        else:
            steady_frames += data.numel()
        collector.update_policy_weights_()
    end = time.perf_counter()
    collector.shutdown()
    if backend == "ray":
        import ray

        ray.shutdown()
    return first - start, steady_frames / (end - first)


def _sweep(tmp: str, *overrides: str) -> float:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "WANDB_MODE": "offline", "RAY_ADDRESS": ""}
    start = time.perf_counter()
    subprocess.run(
        [
            sys.executable,
            "recipes/train.py",
            "-m",
            "+sweeps=tiny",
            f"run_root={tmp}",
            "logger.backend=",
            *overrides,
        ],
        cwd=REPO,
        env=env,
        check=True,
        capture_output=True,
    )
    return time.perf_counter() - start


def main() -> None:
    args = setup(
        __doc__.split("\n")[0],
        add_arguments=lambda p: (
            p.add_argument("--frames", type=int, default=4000),
            p.add_argument("--sweeps", action="store_true", help="also time the tiny sweep"),
        ),
    )
    frames = 1000 if args.quick else args.frames
    has_ray = importlib.util.find_spec("ray") is not None
    rows, rates = [], {}
    for backend, workers in BACKENDS:
        if backend == "ray" and not has_ray:
            continue
        startup, rate = _collect(backend, workers, frames)
        rates[(backend, workers)] = rate
        rows.append((backend, workers, startup, rate, rate / rates[("local", 1)]))
    header = ("backend", "workers", "to 1st batch s", "frames/s", "vs local x1")
    print_table(f"collection, {frames} frames, weights pushed every 200", header, rows)
    summary = {f"{b}_x{w}_ratio": r / rates[("local", 1)] for (b, w), r in rates.items()}
    if args.sweeps:
        with tempfile.TemporaryDirectory() as tmp:
            local = _sweep(f"{tmp}/local")
            ray_run = float("nan")
            if has_ray:
                ray_run = _sweep(
                    f"{tmp}/ray", "hydra/launcher=ray", "+hydra.launcher.ray.init.num_cpus=2"
                )
        print_table(
            "tiny sweep (4 jobs)",
            ("launcher", "wall s"),
            [("hydra basic (serial)", local), ("hydra ray (2 CPUs)", ray_run)],
        )
        summary.update(sweep_local_s=local, sweep_ray_s=ray_run)
    print_summary("collectors", **summary)


if __name__ == "__main__":
    main()
