"""LyapunovActorCriticLoss in a plain TorchRL off-policy loop on the data-collection task.

    .venv/bin/python examples/lac_in_a_torchrl_loop.py --frames 1000

Everything but the loss is TorchRL's: ``Collector``, ``TensorDictReplayBuffer``, ``SoftUpdate``,
a ``ProbabilisticActor``. The loss trains on the per-AUV ``("agents", "cost")`` (>= 0) and
reports its dual variables: lambda (the Lyapunov decrease constraint's multiplier) and beta
(the entropy temperature).
"""

from __future__ import annotations

import argparse

import torch
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.objectives import SoftUpdate

from torchrl_auv.training import (
    make_actor,
    make_env,
    make_lac_loss,
    make_lyapunov_critic,
    select_for_replay,
)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1000, help="scene-decisions to collect")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    torch.manual_seed(0)

    env = make_env("ideal", seed=0, num_envs=2, max_steps=200)
    actor = make_actor(env, hidden=(64, 64))
    loss = make_lac_loss(actor, make_lyapunov_critic(env, hidden=(64, 64)), env, gamma=0.97)
    updater = SoftUpdate(loss, tau=0.005)
    optimiser = torch.optim.Adam(loss.parameters(), lr=3e-4)
    buffer = TensorDictReplayBuffer(storage=LazyTensorStorage(100_000), batch_size=64)
    collector = Collector(
        env,
        actor,
        frames_per_batch=100,
        total_frames=args.frames,
        auto_register_policy_transforms=False,
    )
    for i, batch in enumerate(collector):
        buffer.extend(select_for_replay(batch))  # only what the loss reads
        for _ in range(10):
            out = loss(buffer.sample())
            total = sum(v for k, v in out.items() if k.startswith("loss_"))
            optimiser.zero_grad()
            total.backward()
            optimiser.step()
            updater.step()
        print(
            f"batch {i}: cost {batch['next', 'agents', 'cost'].mean().item():.3f}, "
            f"lambda {out['lambda'].item():.3f}, beta {out['beta'].item():.3f}, "
            f"violation rate {out['violation_rate'].item():.2f}"
        )
    collector.shutdown()


if __name__ == "__main__":
    main()
