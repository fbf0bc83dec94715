"""One optimisation step of LyapunovActorCriticLoss vs TorchRL's SACLoss, and the selector.

Same networks for both (actor: TanhNormal policy, MLP 128-128; critic: MLP 128-128 on
observation and action, 16 raw outputs for the Lyapunov critic, 1 for SAC's Q), batch 256,
observation 16 and action 3 (the tracking env's sizes), 1 thread. A step is forward, backward
over the sum of the loss terms, Adam step and soft target update. Issue [6/9]'s target: the
Lyapunov step costs no more than 1.5x the SAC step. Also: CandidateSelector over K = 5
candidates at batch 1 and 256.
"""

from __future__ import annotations

from _runner import measure, print_summary, print_table, setup


def main() -> None:
    args = setup(__doc__)
    import torch
    from tensordict import TensorDict
    from tensordict.nn import NormalParamExtractor, TensorDictModule
    from torch import nn
    from torchrl.modules import MLP, ProbabilisticActor, TanhNormal, ValueOperator
    from torchrl.objectives import SACLoss, SoftUpdate

    from torchrl_auv.objectives import CandidateSelector, LyapunovActorCriticLoss

    obs, act, batch = 16, 3, 256

    def actor():
        net = nn.Sequential(
            MLP(in_features=obs, out_features=2 * act, num_cells=[128, 128]), NormalParamExtractor()
        )
        return ProbabilisticActor(
            TensorDictModule(net, in_keys=["observation"], out_keys=["loc", "scale"]),
            in_keys=["loc", "scale"],
            distribution_class=TanhNormal,
            distribution_kwargs={"low": -1.0, "high": 1.0},
            return_log_prob=True,
        )

    def critic(out):
        return ValueOperator(
            MLP(in_features=obs + act, out_features=out, num_cells=[128, 128]),
            in_keys=["observation", "action"],
        )

    g = torch.Generator().manual_seed(0)
    data = TensorDict(
        {
            "observation": torch.randn(batch, obs, generator=g),
            "action": torch.rand(batch, act, generator=g) * 2 - 1,
            "next": {
                "observation": torch.randn(batch, obs, generator=g),
                "reward": -torch.rand(batch, 1, generator=g),
                "done": torch.zeros(batch, 1, dtype=torch.bool),
                "terminated": torch.zeros(batch, 1, dtype=torch.bool),
            },
        },
        batch_size=[batch],
    )
    losses = {
        "LyapunovActorCriticLoss": LyapunovActorCriticLoss(actor(), critic(16), form="squared"),
        "SACLoss (TorchRL)": SACLoss(
            actor(), critic(1), num_qvalue_nets=2, target_entropy=-float(act)
        ),
    }
    rows, per_step = [], {}
    for name, loss in losses.items():
        updater = SoftUpdate(loss, tau=0.005)
        optim = torch.optim.Adam(loss.parameters(), lr=3e-4)

        def step(loss=loss, optim=optim, updater=updater):
            out = loss(data)
            total = sum(v for k, v in out.items() if k.startswith("loss"))
            optim.zero_grad()
            total.backward()
            optim.step()
            updater.step()

        seconds = measure(step, min_time=1.0 if args.quick else 3.0, repeats=3, warmup=3)
        per_step[name] = seconds.median
        rows.append([name, f"{seconds.median * 1e3:.2f}", f"{1 / seconds.median:,.0f}"])
    print_table(
        "one optimisation step, batch 256, hidden 128, 1 thread",
        ["loss", "ms / step", "steps / s"],
        rows,
    )
    selector = CandidateSelector(critic(1), mode="q")
    sel_rows = {}
    for b in (1, 256):
        td = TensorDict(
            {
                "observation": torch.randn(b, obs),
                ("proposer", "candidates"): torch.rand(b, 5, 8, act),
            },
            batch_size=[b],
        )
        seconds = measure(lambda td=td: selector(td.clone()), min_time=1.0, repeats=3, warmup=3)
        sel_rows[b] = seconds.median
    print_table(
        "CandidateSelector, K = 5",
        ["batch", "ms / selection"],
        [[b, f"{s * 1e3:.3f}"] for b, s in sel_rows.items()],
    )
    ratio = per_step["LyapunovActorCriticLoss"] / per_step["SACLoss (TorchRL)"]
    print_summary(
        "bench_losses",
        lac_ms=per_step["LyapunovActorCriticLoss"] * 1e3,
        sac_ms=per_step["SACLoss (TorchRL)"] * 1e3,
        lac_over_sac=ratio,
        selector_ms_b1=sel_rows[1] * 1e3,
        selector_ms_b256=sel_rows[256] * 1e3,
    )


if __name__ == "__main__":
    main()
