"""LyapunovActorCriticLoss next to TorchRL's SACLoss in a plain TorchRL off-policy loop.

Nothing in the loop is ours except the loss: TorchRL's ``Collector``,
``TensorDictReplayBuffer``, ``SoftUpdate`` and a ``ProbabilisticActor`` with a ``TanhNormal``;
``--loss sac`` runs TorchRL's ``SACLoss`` on the same networks, budget and seed. Two envs:

- ``pendulum``: TorchRL's own ``torchrl.envs.PendulumEnv`` (cost = -reward >= 0), 200-step
  episodes; about 10 min per 40,000 frames on one core.
- ``tracking``: our ``AUVTrackingEnv`` (``--sea es`` by default), 16 envs in a batch. After
  training it runs deterministic closed-loop step responses (one reference per episode) and
  reports the reference tracking errors and, for LAC, the learned Lyapunov value along them.

Run::

    python examples/lac_vs_sac.py --env pendulum --loss lac --seed 0 --frames 40000
    python examples/lac_vs_sac.py --env tracking --loss sac --frames 40000

It prints one JSON line: the mean return of the last ten (stochastic, training) episodes, the
episode count, the wall time, the loss's last metadata (LAC: lambda, beta, violation rate) and
the evaluation (tracking).
"""

from __future__ import annotations

import argparse
import json
import time

import torch
from tensordict import TensorDictBase
from tensordict.nn import NormalParamExtractor, TensorDictModule
from torch import nn
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer, Unbounded
from torchrl.envs import Compose, PendulumEnv, RewardSum, StepCounter, Transform, TransformedEnv
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.modules import MLP, ProbabilisticActor, TanhNormal, ValueOperator
from torchrl.objectives import SACLoss, SoftUpdate

from torchrl_auv.control import wrap_angle
from torchrl_auv.envs import AUVTrackingEnv
from torchrl_auv.objectives import LyapunovActorCriticLoss, lyapunov_value

HIDDEN = [128, 128]


class PendulumObservation(Transform):
    """Writes ``observation = [cos th, sin th, thdot]`` (the env itself exposes th, thdot)."""

    def __init__(self):
        super().__init__(in_keys=["th", "thdot"], out_keys=["observation"])

    def _call(self, td: TensorDictBase) -> TensorDictBase:
        th, thdot = td.get("th"), td.get("thdot")
        return td.set("observation", torch.stack([th.cos(), th.sin(), thdot], -1))

    def _reset(self, td: TensorDictBase, td_reset: TensorDictBase) -> TensorDictBase:
        return self._call(td_reset)

    def transform_observation_spec(self, spec):
        spec["observation"] = Unbounded(shape=(*spec.shape, 3), dtype=torch.float32)
        return spec


def make_env(name: str, seed: int, sea: str = "es", **tracking) -> TransformedEnv:
    """``pendulum`` (200-step episodes) or ``tracking`` (16 AUVTrackingEnvs)."""
    if name == "pendulum":
        env = TransformedEnv(PendulumEnv(), Compose(PendulumObservation(), StepCounter(200)))
    else:
        tracking.setdefault("batch_size", [16])
        env = TransformedEnv(AUVTrackingEnv(sea_state=sea, seed=seed, **tracking))
    env.append_transform(RewardSum())
    env.set_seed(seed)
    return env


def make_actor(env) -> ProbabilisticActor:
    obs, act = env.observation_spec["observation"].shape[-1], env.action_spec.shape[-1]
    net = nn.Sequential(
        MLP(in_features=obs, out_features=2 * act, num_cells=HIDDEN), NormalParamExtractor()
    )
    module = TensorDictModule(net, in_keys=["observation"], out_keys=["loc", "scale"])
    space = env.action_spec.space
    return ProbabilisticActor(
        module,
        in_keys=["loc", "scale"],
        spec=env.action_spec,
        distribution_class=TanhNormal,
        distribution_kwargs={"low": space.low, "high": space.high},
        return_log_prob=True,
    )


def make_critic(env, out_features: int = 1) -> ValueOperator:
    obs, act = env.observation_spec["observation"].shape[-1], env.action_spec.shape[-1]
    return ValueOperator(
        MLP(in_features=obs + act, out_features=out_features, num_cells=HIDDEN),
        in_keys=["observation", "action"],
    )


def make_loss(name: str, actor, env, form: str, alpha: float, gamma: float):
    """The loss and one Adam optimiser with a parameter group per term (3e-4 each)."""
    if name == "lac":
        out = 1 if form == "softplus" else 64  # softplus reads one output, the others a vector
        loss = LyapunovActorCriticLoss(
            actor,
            make_critic(env, out),
            form=form,
            stability_weight=alpha,
            action_spec=env.action_spec,
        )
        parts = [loss.actor_network_params, loss.lyapunov_network_params]
        groups = [{"params": list(p.values(True, True))} for p in parts]
        groups += [{"params": [loss.log_lambda]}, {"params": [loss.log_beta]}]
    else:
        loss = SACLoss(actor, make_critic(env), num_qvalue_nets=2, action_spec=env.action_spec)
        groups = [{"params": list(loss.parameters())}]
    loss.make_value_estimator(gamma=gamma)
    return loss, torch.optim.Adam(groups, lr=3e-4)


def train(
    env_name="pendulum",
    loss_name="lac",
    seed=0,
    frames=40_000,
    form="softplus",
    alpha=0.1,
    gamma=0.99,
    sea="es",
    utd=1.0,
    batch_size=256,
    init_random_frames=1_000,
):
    """Train one seed; returns ``(summary, actor, loss)``."""
    torch.manual_seed(seed)
    env = make_env(env_name, seed, sea)
    actor = make_actor(env)
    loss, optim = make_loss(loss_name, actor, env, form, alpha, gamma)
    updater = SoftUpdate(loss, tau=0.005)
    frames_per_batch = 100 if env_name == "pendulum" else 16 * 25
    collector = Collector(
        env,
        actor,
        frames_per_batch=frames_per_batch,
        total_frames=frames,
        init_random_frames=init_random_frames,
        auto_register_policy_transforms=False,
    )
    buffer = TensorDictReplayBuffer(storage=LazyTensorStorage(frames), batch_size=batch_size)
    returns, last, updates = [], {}, 0
    start = time.perf_counter()
    for data in collector:
        done = data["next", "done"].squeeze(-1)
        returns += data["next", "episode_reward"][done].squeeze(-1).tolist()
        buffer.extend(data.reshape(-1))
        if len(buffer) < init_random_frames:
            continue
        for _ in range(round(utd * data.numel())):
            out = loss(buffer.sample())
            total = sum(v for k, v in out.items() if k.startswith("loss"))
            optim.zero_grad()
            total.backward()
            optim.step()
            updater.step()
            updates += 1
        last = {k: round(float(v), 4) for k, v in out.items() if not k.startswith("loss")}
    collector.shutdown()
    tail = returns[-10:]
    summary = {
        "env": env_name,
        "loss": loss_name,
        "seed": seed,
        "frames": frames,
        "form": form,
        "alpha": alpha,
        "episodes": len(returns),
        "updates": updates,
        "last10_mean_return": round(sum(tail) / max(len(tail), 1), 1),
        "returns": [round(r, 1) for r in returns],
        "train_seconds": round(time.perf_counter() - start),
        **last,
    }
    return summary, actor, loss


def evaluate_tracking(
    actor, loss, seed: int, sea: str = "es", episodes: int = 16, steps: int = 120
) -> dict:
    """Deterministic step responses on ``AUVTrackingEnv`` (one reference per episode).

    Reports mean |heading - reference| (rad) and |depth - reference| (m) on the true state, and
    for LAC the learned ``L(s_t, a_t)`` along the episodes: its mean over the first and last
    ten steps, the fraction of episodes where it ends lower than it starts, and the fraction of
    steps with ``Delta L = L(s_{t+1}, a_{t+1}) - L(s_t, a_t) + alpha c <= 0``.
    """
    env = AUVTrackingEnv(
        batch_size=[episodes],
        sea_state=sea,
        seed=10_000 + seed,
        max_steps=steps,
        segment_seconds=steps + 1.0,
    )
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        td = env.rollout(steps, actor, break_when_any_done=False)
    eta, ref = td["next", "truth", "eta"], td["reference"][:, :, 0]  # [E, T, 6], [E, T, 3]
    result = {
        "eval_heading_error_rad": wrap_angle(ref[..., 1] - eta[..., 5]).abs().mean().item(),
        "eval_depth_error_m": (ref[..., 0] - eta[..., 2]).abs().mean().item(),
        "eval_speed_error_mps": (ref[..., 2] - td["next", "truth", "nu"][..., 0])
        .abs()
        .mean()
        .item(),
        "eval_return": td["next", "reward"].sum(1).mean().item(),
        "eval_diverged": td["next", "terminated"].any(1).float().mean().item(),
    }
    if isinstance(loss, LyapunovActorCriticLoss):
        with torch.no_grad():  # the critic module shares its parameters with the loss
            raw = loss.lyapunov_network(td.select("observation", "action"))["state_action_value"]
        lyap = lyapunov_value(raw, loss.spec, td["observation"])[..., 0]  # [E, T]
        delta = lyap[:, 1:] - lyap[:, :-1] + loss.spec.alpha * td["next", "cost"][:, :-1, 0]
        result.update(
            eval_lyapunov_first10=lyap[:, :10].mean().item(),
            eval_lyapunov_last10=lyap[:, -10:].mean().item(),
            eval_lyapunov_decreased_fraction=(lyap[:, -10:].mean(1) < lyap[:, :10].mean(1))
            .float()
            .mean()
            .item(),
            eval_delta_l_nonpositive_fraction=(delta <= 0).float().mean().item(),
        )
    return {k: round(v, 4) for k, v in result.items()}


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", choices=["pendulum", "tracking"], default="pendulum")
    parser.add_argument("--loss", choices=["lac", "sac"], default="lac")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--frames", type=int, default=40_000)
    parser.add_argument("--form", default="softplus", help="Lyapunov form (LAC only)")
    parser.add_argument("--alpha", type=float, default=0.1, help="stability weight (LAC only)")
    parser.add_argument("--sea", default="es", help="sea state (tracking only)")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    summary, actor, loss = train(
        args.env, args.loss, args.seed, args.frames, args.form, args.alpha, sea=args.sea
    )
    if args.env == "tracking":
        summary.update(evaluate_tracking(actor, loss, args.seed, args.sea))
    summary["returns"] = summary["returns"][-20:]
    print(json.dumps(summary))
    return summary


if __name__ == "__main__":
    main()
