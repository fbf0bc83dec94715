"""A user's own TorchRL loop on the data-collection env: rollout -> ReplayBuffer -> SACLoss.

    .venv/bin/python examples/plain_torchrl_sac.py --iterations 3

Nothing here comes from ``torchrl_auv`` but the env: TorchRL's ``MLP``, ``ProbabilisticActor``
with a ``TanhNormal``, ``ValueOperator``, ``SACLoss``, ``SoftUpdate`` and a
``TensorDictReplayBuffer``, on the single-agent layout (``flatten_agents=True``: one
observation of 37 features per AUV side by side, one action of 3 per AUV, the summed reward).
The env keeps its simulator state (true state, filters, ocean, sensor network, about 30 KB
per frame) under one key, ``"sim"``; the buffer stores the rollout without it, under 1 KB per
frame, with no key list from the library.
"""

from __future__ import annotations

import argparse

import torch
from tensordict.nn import NormalParamExtractor, TensorDictModule
from torch import nn
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.modules import MLP, ProbabilisticActor, TanhNormal, ValueOperator
from torchrl.objectives import SACLoss, SoftUpdate

from torchrl_auv.envs import DataCollectionEnv


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=20, help="rollouts to learn from")
    parser.add_argument("--steps", type=int, default=50, help="decisions per rollout")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    torch.manual_seed(0)

    env = DataCollectionEnv(batch_size=[4], sea_state="es", seed=0, flatten_agents=True)
    obs_dim = env.observation_spec["observation"].shape[-1]
    act_dim = env.action_spec.shape[-1]
    net = nn.Sequential(
        MLP(in_features=obs_dim, out_features=2 * act_dim, num_cells=[64, 64]),
        NormalParamExtractor(),
    )
    actor = ProbabilisticActor(
        TensorDictModule(net, in_keys=["observation"], out_keys=["loc", "scale"]),
        in_keys=["loc", "scale"],
        distribution_class=TanhNormal,
        distribution_kwargs={"low": -1.0, "high": 1.0},
        spec=env.action_spec,
    )
    qvalue = ValueOperator(
        MLP(in_features=obs_dim + act_dim, out_features=1, num_cells=[64, 64]),
        in_keys=["observation", "action"],
    )
    loss = SACLoss(actor, qvalue, action_spec=env.action_spec)
    loss.make_value_estimator(gamma=0.99)
    updater = SoftUpdate(loss, eps=0.995)
    optimiser = torch.optim.Adam(loss.parameters(), lr=3e-4)
    buffer = TensorDictReplayBuffer(storage=LazyTensorStorage(100_000), batch_size=128)

    td = env.reset()
    for i in range(args.iterations):
        with torch.no_grad(), set_exploration_type(ExplorationType.RANDOM):  # sample actions
            rollout = env.rollout(
                args.steps, actor, tensordict=td, auto_reset=False, break_when_any_done=False
            )
        td = env.step_mdp(rollout[..., -1])
        td = env.reset(td) if td["done"].any() else td  # resets the scenes that ended
        frames = rollout.exclude("sim", ("next", "sim")).reshape(-1)  # the one key to drop
        buffer.extend(frames)
        out = {}
        for _ in range(args.steps):
            out = loss(buffer.sample())
            total = out["loss_actor"] + out["loss_qvalue"] + out["loss_alpha"]
            optimiser.zero_grad()
            total.backward()
            optimiser.step()
            updater.step()
        full = rollout[..., 0].bytes() // rollout.batch_size[0]
        print(
            f"iteration {i}: {frames[0].bytes()} bytes per frame (the full rollout: {full}), "
            f"buffer {len(buffer)} frames, mean reward "
            f"{rollout['next', 'reward'].mean().item():.2f}, loss_qvalue "
            f"{out['loss_qvalue'].item():.3f}, alpha {out['alpha'].item():.3f}"
        )


if __name__ == "__main__":
    main()
