"""Sample and plot the diffusion proposer's K candidates for one state (paper Fig. 5).

    .venv/bin/python examples/proposer_candidates.py --pretrain-steps 300 --out candidates.png

Collects a few scripted-expert demonstrations on the tracking env, pretrains a small proposer on
them, then draws the K = 5 candidate action chunks of one held-out state at five denoising
stages, as the depth and heading setpoint paths they command.
"""

from __future__ import annotations

import argparse

import torch

from torchrl_auv.envs.demonstrations import collect_demonstrations
from torchrl_auv.modules import DiffusionProposer
from torchrl_auv.objectives import pretrain_proposer
from torchrl_auv.report import plot_candidate_stages


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pretrain-steps", type=int, default=300)
    parser.add_argument("--out", default="candidates.png")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)

    data = collect_demonstrations("tracking", episodes=4, max_steps=100, horizon=8, history=10)
    obs, act = data["observation"].shape[-1], data["action"].shape[-1]
    proposer = DiffusionProposer(
        obs + 10 * (obs + act + 1),
        act,
        history_key="history",
        num_candidates=5,
        horizon=8,
        num_inference_steps=20,
        sampler="ddim",
    )
    every = max(1, args.pretrain_steps // 10)
    result = pretrain_proposer(
        proposer,
        data,
        steps=args.pretrain_steps,
        batch_size=64,
        lr=1e-3,
        log_every=every,
        eval_every=args.pretrain_steps,
    )
    print(f"pretraining loss {result.losses[0]:.3f} -> {result.losses[-1]:.3f}")
    state = proposer.build_state(data[-1:])  # one held-out-like state (the last sample)
    candidates, stages = proposer.sample(
        state, generator=torch.Generator().manual_seed(0), num_stages=5
    )
    print(f"candidates {tuple(candidates.shape)}: first actions {candidates[0, :, 0].tolist()}")
    print(f"plot: {plot_candidate_stages(stages[0], args.out)}")


if __name__ == "__main__":
    main()
