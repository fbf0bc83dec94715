"""REMUS-100 step throughput: vehicle-steps per second at N = 1, 64, 1024, 4096 (float32).

Times ``remus100.step`` (eager) and ``remus100.compiled_step`` (torch.compile) alone, and the
vehicle in its ocean (``step_ocean`` + ``step_in_ocean`` / ``compiled_step_in_ocean``, ``es``
sea state: Gauss-Markov current plus 100 JONSWAP wave components per vehicle).
Targets (issue [2/9]): N = 4096 >= 2,000,000 vehicle-steps/s; N = 1 <= 150 us per step.
For scale: the public single-vehicle numpy implementation runs 4-8 thousand steps/s.
"""

from __future__ import annotations

import time

from _runner import measure, print_summary, print_table, setup


def main() -> None:
    args = setup(__doc__)
    import torch

    from torchrl_auv.physics import ocean, remus100, simulation

    dtype = torch.float32
    sizes = (1, 64, 1024, 4096)
    sea = ocean.get_sea_state("es")
    rows, rates, latency, compile_times = [], {}, {}, {}
    for n in sizes:
        gen = torch.Generator().manual_seed(0)
        eta = torch.zeros(n, 6, dtype=dtype)
        nu = torch.zeros(n, 6, dtype=dtype)
        nu[:, 0] = 1.5
        act = torch.zeros(n, 3, dtype=dtype)
        cmd = torch.tensor([0.05, 0.02, 1200.0], dtype=dtype).expand(n, 3).contiguous()
        cur = torch.tensor([0.5, 1.0], dtype=dtype).expand(n, 2).contiguous()
        sea_td = ocean.reset_ocean(sea, (n,), generator=gen, dtype=dtype)

        eager, eager_with_current, compiled, compiled_with_current = _cases(
            remus100, ocean, simulation, sea, sea_td, gen, (eta, nu, act, cmd, cur)
        )
        torch._dynamo.reset()
        start = time.perf_counter()
        compiled_with_current()
        compile_times[n] = time.perf_counter() - start

        min_time = 0.3 if args.quick else 1.0
        with torch.no_grad():
            t = {
                name: measure(fn, min_time=min_time).median
                for name, fn in (
                    ("eager", eager),
                    ("eager+current", eager_with_current),
                    ("compiled", compiled),
                    ("compiled+current", compiled_with_current),
                )
            }
        rates[n] = {k: n / v for k, v in t.items()}
        latency[n] = {k: v * 1e6 for k, v in t.items()}
        rows.append(
            [
                n,
                *(f"{latency[n][k]:.1f}" for k in t),
                *(f"{rates[n][k]:,.0f}" for k in t),
                f"{compile_times[n]:.1f}",
            ]
        )
    names = ("eager", "eager+current", "compiled", "compiled+current")
    print_table(
        "REMUS-100 step, float32, 1 thread (us per call | vehicle-steps per second)",
        ["N", *(f"us {k}" for k in names), *(f"rate {k}" for k in names), "compile s"],
        rows,
    )
    best = "compiled+current"
    print_summary(
        "bench_physics",
        rate_N4096_eager_current=rates[4096]["eager+current"],
        rate_N4096_compiled_current=rates[4096][best],
        latency_N1_us_eager_current=latency[1]["eager+current"],
        latency_N1_us_compiled_current=latency[1][best],
        per_vehicle_ratio_N4096_over_N1_compiled=rates[4096][best] / rates[1][best],
        per_vehicle_ratio_N4096_over_N1_eager=rates[4096]["eager+current"]
        / rates[1]["eager+current"],
        compile_s_N1=compile_times[1],
    )


def _cases(remus100, ocean, simulation, sea, sea_td, gen, tensors):
    eta, nu, act, cmd, cur = tensors

    def eager():
        return remus100.step(eta, nu, act, cmd, cur, 0.05)

    def eager_with_current():
        state = ocean.step_ocean(sea_td, sea, 0.05, generator=gen)
        return simulation.step_in_ocean(eta, nu, act, cmd, state, 0.05)

    def compiled():
        return remus100.compiled_step(eta, nu, act, cmd, cur, 0.05)

    def compiled_with_current():
        state = ocean.step_ocean(sea_td, sea, 0.05, generator=gen)
        return simulation.compiled_step_in_ocean(eta, nu, act, cmd, state, 0.05)

    return eager, eager_with_current, compiled, compiled_with_current


if __name__ == "__main__":
    main()
