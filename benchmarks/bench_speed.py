"""Issue [11/13]'s speed figures, each printed with the ratio it is judged by (1 thread).

* ``remus100.step`` eager, one vehicle, float64, against the numpy REMUS-100 of Fossen's Python
  Vehicle Simulator (``--pvs-src``: the ``src`` folder of a checkout of
  ``cybergalactic/PythonVehicleSimulator``; it is not a dependency, so it is timed only when
  given). Target: our step >= 0.5x the reference's speed.
* ``DataCollectionEnv`` (``es``, waves and Kalman filter on), batch 1: ms per decision, eager
  and with ``compile_physics=True`` (target <= 5 ms); the first two steps' compilation on a
  fresh inductor cache and on a warm one (targets 30 s and 5 s; issue [20/26]: 60 s fresh),
  each in its own process (the physics compiles at the first decision, the code around it at
  the second).
* The same env at batch 256: AUV-decisions per second (target >= 50,000).
* The gymnasium id ``torchrl_auv/DataCollection-v2`` (the newest ``DataCollection`` id of
  the package measured; one scene, 2 AUVs): ms per decision, eager
  and compiled (target: the same speed as the env at batch 1).

``--before PATH`` runs the same measurements on the package found at ``PATH`` (for example a
``git worktree`` of an older commit) in a subprocess first and prints both columns with the
ratio after / before. Times are medians of repeated blocks; on the shared 2-core machines they
vary by 10-30 % from run to run, so compare columns of one run. The training-time and memory
figures are in ``bench_recipes.py --paper``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _runner import measure, print_summary, print_table, setup

HERE = Path(__file__).resolve().parent

# (key, label, target, "low" if lower is better else "high")
FIGURES = (
    ("step_us", "remus100.step eager, N=1, float64 (us)", None, "low"),
    ("pvs_us", "numpy reference step (us)", None, "low"),
    ("step_vs_reference", "reference time / our time", 0.5, "high"),
    ("env_b1_eager_ms", "env batch 1 eager (ms / decision)", 5.0, "low"),
    ("env_b1_compiled_ms", "env batch 1 compiled (ms / decision)", 5.0, "low"),
    ("compile_cold_s", "first compiled step, fresh cache (s)", 30.0, "low"),
    ("compile_warm_s", "first compiled step, warm cache (s)", 5.0, "low"),
    ("env_b256_eager_rate", "env batch 256 eager (AUV-decisions / s)", 50_000.0, "high"),
    ("env_b256_compiled_rate", "env batch 256 compiled (AUV-decisions / s)", 50_000.0, "high"),
    ("gym_eager_ms", "gymnasium id eager (ms / decision)", 5.0, "low"),
    ("gym_compiled_ms", "gymnasium id compiled (ms / decision)", 5.0, "low"),
)

FIRST_STEP = """
import sys, time, torch
torch.set_num_threads(1)
from torchrl_auv.envs import DataCollectionEnv
env = DataCollectionEnv(batch_size=[1], sea_state="es", seed=0, compile_physics=True)
td = env.rand_action(env.reset())
start = time.perf_counter()
env.step(td).pop("next")
env.step(td)  # the decision's code around the physics compiles at the second decision
print(time.perf_counter() - start)
"""


def _first_step_seconds(cache: str) -> float:
    env = {**os.environ, "TORCHINDUCTOR_CACHE_DIR": cache, "OMP_NUM_THREADS": "1"}
    out = subprocess.run(
        [sys.executable, "-c", FIRST_STEP], env=env, capture_output=True, text=True, check=True
    )
    return float(out.stdout.strip().splitlines()[-1])


def _pvs_step_us(src: str, min_time: float) -> float:
    import numpy as np

    sys.path.insert(0, src)
    from python_vehicle_simulator.lib.gnc import attitudeEuler
    from python_vehicle_simulator.vehicles.remus100 import remus100

    vehicle = remus100()
    state = {
        "eta": np.array([0, 0, 10, 0, 0, 0.0]),
        "nu": np.array([1.5, 0, 0, 0, 0, 0.0]),
        "act": np.array([0, 0, 1200.0]),
    }
    command = np.array([0.05, 0.02, 1200.0])

    def one() -> None:
        state["nu"], state["act"] = vehicle.dynamics(
            state["eta"], state["nu"], state["act"], command, 0.05
        )
        state["eta"] = attitudeEuler(state["eta"], state["nu"], 0.05)

    return measure(one, min_time=min_time, repeats=7, warmup=200).median * 1e6


def measure_all(quick: bool, pvs_src: str | None) -> dict[str, float]:
    import gymnasium
    import torch

    from torchrl_auv.envs import DataCollectionEnv
    from torchrl_auv.physics import remus100

    min_time = 1.0 if quick else 3.0
    out: dict[str, float] = {}
    f64 = torch.float64
    eta, nu = torch.zeros(1, 6, dtype=f64), torch.zeros(1, 6, dtype=f64)
    eta[:, 2], nu[:, 0] = 10.0, 1.5
    act = torch.tensor([[0.0, 0.0, 1200.0]], dtype=f64)
    cmd = torch.tensor([[0.05, 0.02, 1200.0]], dtype=f64)
    current = torch.tensor([[0.5, 1.0]], dtype=f64)
    timing = measure(
        lambda: remus100.step(eta, nu, act, cmd, current, 0.05),
        min_time=min_time,
        repeats=7,
        warmup=200,
    )
    out["step_us"] = timing.median * 1e6
    if pvs_src:
        out["pvs_us"] = _pvs_step_us(pvs_src, min_time)
        out["step_vs_reference"] = out["pvs_us"] / out["step_us"]
    for batch, compiled in ((1, False), (1, True), (256, False), (256, True)):
        env = DataCollectionEnv(
            batch_size=[batch], sea_state="es", seed=0, compile_physics=compiled
        )
        td = env.rand_action(env.reset())
        for _ in range(2):  # compiles, if compiled
            env.step(td).pop("next")
        # "next" popped: a step given a "next" entry merges it, which a rollout never does
        seconds = measure(
            lambda env=env, td=td: env.step(td).pop("next"), min_time=min_time, repeats=5, warmup=2
        ).median
        name = f"env_b{batch}_{'compiled' if compiled else 'eager'}"
        if batch == 1:
            out[f"{name}_ms"] = seconds * 1e3
        else:
            out[f"{name}_rate"] = batch * env.num_auvs / seconds
    # the newest DataCollection id of the package measured (an older checkout has older ones)
    newest = max(
        (
            spec
            for name, spec in gymnasium.registry.items()
            if name.startswith("torchrl_auv/DataCollection-v")
        ),
        key=lambda spec: spec.version,
    ).id
    for compiled in (False, True):
        gym_env = gymnasium.make(newest, sea_state="es", compile_physics=compiled)
        gym_env.reset(seed=0)
        action = gym_env.action_space.sample()
        gym_env.step(action)

        def gym_step(gym_env=gym_env, action=action) -> None:
            _, _, terminated, truncated, _ = gym_env.step(action)
            if terminated or truncated:
                gym_env.reset()

        seconds = measure(gym_step, min_time=min_time, repeats=5, warmup=2).median
        out[f"gym_{'compiled' if compiled else 'eager'}_ms"] = seconds * 1e3
    if not quick:
        with tempfile.TemporaryDirectory() as cache:
            out["compile_cold_s"] = _first_step_seconds(cache)
            out["compile_warm_s"] = _first_step_seconds(cache)
    return out


def _run_before(path: str, quick: bool, pvs_src: str | None) -> dict[str, float]:
    command = [sys.executable, str(Path(__file__).resolve()), "--json-only"]
    command += ["--quick"] if quick else []
    command += ["--pvs-src", pvs_src] if pvs_src else []
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([path, str(HERE)])}
    result = subprocess.run(command, env=env, capture_output=True, text=True)
    if result.returncode:
        raise RuntimeError(f"the --before run failed:\n{result.stderr[-3000:]}")
    return json.loads(result.stdout.strip().splitlines()[-1])


def _arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--pvs-src", help="src folder of a PythonVehicleSimulator checkout")
    parser.add_argument("--before", help="another checkout's root, measured first")
    parser.add_argument("--json-only", action="store_true", help=argparse.SUPPRESS)


def main() -> None:
    args = setup(__doc__, add_arguments=_arguments)
    if args.json_only:
        print(json.dumps(measure_all(args.quick, args.pvs_src)))
        return
    pvs_src = args.pvs_src
    start = time.perf_counter()
    before = _run_before(args.before, args.quick, pvs_src) if args.before else {}
    after = measure_all(args.quick, pvs_src)
    rows, summary = [], {}
    for key, label, target, better in FIGURES:
        if key not in after:
            continue
        value = after[key]
        old = before.get(key)
        meets = (
            ""
            if target is None
            else ("yes" if (value <= target if better == "low" else value >= target) else "no")
        )
        ratio = (value / target if better == "high" else target / value) if target else None
        rows.append(
            [
                label,
                "-" if target is None else target,
                "-" if old is None else old,
                value,
                "-" if old is None else value / old,
                "-" if ratio is None else ratio,
                meets or "-",
            ]
        )
        summary[key] = value
    print_table(
        "speed figures of issue [11/13] (1 thread; ratio to target: >= 1 meets it)",
        ["figure", "target", "before", "after", "after / before", "ratio to target", "meets"],
        rows,
    )
    print(f"\n(benchmark wall time {time.perf_counter() - start:.0f} s)")
    print_summary("speed", **summary)


if __name__ == "__main__":
    main()
