"""Environment decision steps per second (each decision = 20 physics steps with controller,
ocean waves, sensors and Kalman filter), 1 thread.

Today this measures ``AUVTrackingEnv`` (one AUV per scene) in the ``es`` sea state at batch 1
and 256. Issue [4/9]'s targets are for the data-collection env: batch 1 <= 10 ms per decision,
batch 256 >= 20,000 AUV-decisions per second.
"""

from __future__ import annotations

from _runner import measure, print_summary, print_table, setup


def main() -> None:
    args = setup(__doc__)
    import torch

    from torchrl_auv.envs import AUVTrackingEnv

    rows, per_decision = [], {}
    for batch in (1, 256):
        env = AUVTrackingEnv(batch_size=[batch], sea_state="es", seed=0)
        td = env.reset()
        td["action"] = torch.zeros(batch, 3)

        def decide(env=env, td=td):
            return env.step(td)

        seconds = measure(decide, min_time=1.0 if args.quick else 3.0, repeats=3, warmup=2)
        per_decision[batch] = seconds.median
        rows.append(
            [
                batch,
                f"{seconds.median * 1e3:.2f}",
                f"{batch / seconds.median:,.0f}",
                f"{1000 * seconds.median:.1f}",
            ]
        )
    print_table(
        "AUVTrackingEnv decision step (20 physics steps), es, float32, eager",
        ["batch", "ms / decision", "AUV-decisions / s", "s per 1000-decision episode"],
        rows,
    )
    print_summary(
        "bench_envs",
        tracking_ms_per_decision_b1=per_decision[1] * 1e3,
        tracking_auv_decisions_per_s_b256=256 / per_decision[256],
        speedup_per_auv_b256_over_b1=(256 / per_decision[256]) / (1 / per_decision[1]),
    )


if __name__ == "__main__":
    main()
