"""Environment decision steps per second (each decision = 20 physics steps with controller,
ocean waves, sensors and Kalman filter), 1 thread, float32, ``es`` sea state.

Measures ``DataCollectionEnv`` (2 AUVs per scene) at batch 1 and 256, eager and with
``compile_physics=True`` (the decision through ``torch.compile``; the first two decisions of
each batch shape compile, the physics at the first and the code around it at the second, their
time is printed separately), and ``AUVTrackingEnv`` (eager) for
comparison. Issue [4/9]'s targets for the data-collection env: batch 1 <= 10 ms per decision,
batch 256 >= 20,000 AUV-decisions per second.
"""

from __future__ import annotations

import time

from _runner import measure, print_summary, print_table, setup


def main() -> None:
    args = setup(__doc__)
    from torchrl_auv.envs import AUVTrackingEnv, DataCollectionEnv

    cases = [
        ("DataCollectionEnv", False),
        ("DataCollectionEnv", True),
        ("AUVTrackingEnv", False),
    ]
    rows, per_decision = [], {}
    for name, compiled in cases:
        for batch in (1, 256):
            if name == "DataCollectionEnv":
                env = DataCollectionEnv(
                    batch_size=[batch], sea_state="es", seed=0, compile_physics=compiled
                )
            else:
                env = AUVTrackingEnv(batch_size=[batch], sea_state="es", seed=0)
            auvs = getattr(env, "num_auvs", 1)
            td = env.rand_action(env.reset())
            start = time.perf_counter()
            for _ in range(2):
                env.step(td).pop("next")
            first = time.perf_counter() - start

            def decide(env=env, td=td):  # "next" popped: a rollout never steps with one
                return env.step(td).pop("next")

            seconds = measure(decide, min_time=1.0 if args.quick else 3.0, repeats=3, warmup=2)
            per_decision[name, compiled, batch] = (seconds.median, auvs)
            rows.append(
                [
                    name,
                    "compiled" if compiled else "eager",
                    batch,
                    f"{first:.1f}",
                    f"{seconds.median * 1e3:.2f}",
                    f"{batch * auvs / seconds.median:,.0f}",
                    f"{1000 * seconds.median:.1f}",
                ]
            )
    print_table(
        "decision step (20 physics steps per AUV), es, float32, 1 thread",
        [
            "env",
            "physics",
            "batch",
            "first two steps (s)",
            "ms / decision",
            "AUV-decisions / s",
            "s per 1000-decision episode",
        ],
        rows,
    )

    def rate(name, compiled, batch):
        seconds, auvs = per_decision[name, compiled, batch]
        return batch * auvs / seconds

    print_summary(
        "bench_envs",
        collection_ms_per_decision_b1_eager=per_decision["DataCollectionEnv", False, 1][0] * 1e3,
        collection_ms_per_decision_b1_compiled=per_decision["DataCollectionEnv", True, 1][0] * 1e3,
        collection_auv_decisions_per_s_b256_eager=rate("DataCollectionEnv", False, 256),
        collection_auv_decisions_per_s_b256_compiled=rate("DataCollectionEnv", True, 256),
        collection_speedup_per_auv_b256_over_b1_compiled=rate("DataCollectionEnv", True, 256)
        / rate("DataCollectionEnv", True, 1),
        tracking_ms_per_decision_b1=per_decision["AUVTrackingEnv", False, 1][0] * 1e3,
    )


if __name__ == "__main__":
    main()
