"""Diffusion proposer latency and throughput, 1 thread, float32.

One proposal = K = 5 candidate chunks of H = 8 actions for one AUV of the tracking env
(state 216 = 16 + 10 x (16 + 3 + 1)). Measured per noise model, eager and through
``torch.compile`` (``compile=True``; the compilation time is printed separately): latency with
50 strided-DDPM steps and with 10 DDIM steps, and proposals per second at batch 256 with 10
DDIM steps. Issue [5/9]'s targets for the default noise model: 50 steps <= 25 ms, 10 DDIM
steps <= 5 ms, batch 256 >= 2,000 proposals/s. Also printed: the proposal cost per
1000-decision episode and its ratio to the 50 ms control period and the 1 s decision period.
"""

from __future__ import annotations

import time

from _runner import measure, print_summary, print_table, setup

MODELS = {
    "mlp-128 (default)": ("mlp", {"hidden": 128, "depth": 3, "cond_dim": 64}),
    "mlp-256": ("mlp", {"hidden": 256, "depth": 3, "cond_dim": 128}),
    "unet-32/64": ("unet", {"channels": (32, 64), "cond_dim": 64}),
    "unet-256/256 (paper width)": ("unet", {"channels": (256, 256), "cond_dim": 128}),
}


def main() -> None:
    args = setup(__doc__)
    import torch

    from torchrl_auv.modules import DiffusionProposer

    min_time = 0.5 if args.quick else 2.0
    rows, summary = [], {}
    for name, (kind, kwargs) in MODELS.items():
        for compiled in (False, True):
            results = {}
            compile_time = 0.0
            for label, sampler, steps, batch in (
                ("ddpm50_b1", "ddpm", 50, ()),
                ("ddim10_b1", "ddim", 10, ()),
                ("ddim10_b256", "ddim", 10, (256,)),
            ):
                proposer = DiffusionProposer(
                    216,
                    3,
                    horizon=8,
                    num_candidates=5,
                    num_inference_steps=steps,
                    sampler=sampler,
                    noise_model=kind,
                    noise_model_kwargs=kwargs,
                    compile=compiled,
                )
                state = torch.zeros(*batch, 216)
                start = time.perf_counter()
                proposer.sample(state)
                compile_time += time.perf_counter() - start

                def propose(proposer=proposer, state=state):
                    return proposer.sample(state)

                seconds = measure(propose, min_time=min_time, repeats=3, warmup=1)
                results[label] = seconds.median
            ms50 = results["ddpm50_b1"] * 1e3
            per_episode = results["ddpm50_b1"] * 1000
            rows.append(
                [
                    name,
                    "compiled" if compiled else "eager",
                    f"{compile_time:.1f}" if compiled else "-",
                    f"{ms50:.1f}",
                    f"{results['ddim10_b1'] * 1e3:.2f}",
                    f"{256 / results['ddim10_b256']:,.0f}",
                    f"{per_episode:.1f}",
                    f"{results['ddpm50_b1'] / 0.05:.2f}",
                    f"{results['ddpm50_b1'] / 1.0:.3f}",
                ]
            )
            tag = f"{kind}{'_compiled' if compiled else ''}_{name.split()[0].split('-')[1]}"
            summary[f"{tag}_ddpm50_ms"] = ms50
            summary[f"{tag}_ddim10_ms"] = results["ddim10_b1"] * 1e3
            summary[f"{tag}_b256_per_s"] = 256 / results["ddim10_b256"]
    print_table(
        "one proposal (K=5, H=8, state 216), 1 thread, float32",
        [
            "noise model",
            "mode",
            "compile (s)",
            "50 DDPM (ms)",
            "10 DDIM (ms)",
            "b256 10 DDIM / s",
            "s per 1000-decision ep. (50 DDPM)",
            "/ 50 ms control",
            "/ 1 s decision",
        ],
        rows,
    )
    print_summary("bench_proposer", **summary)


if __name__ == "__main__":
    main()
