"""What the rule-based advisor adds to a short LAC training run (issue [7/9]: <= 2 %).

The loop: AUVTrackingEnv (8 envs, ``es``), TorchRL ``Collector`` (200 frames per batch),
``TensorDictReplayBuffer``, LyapunovActorCriticLoss (hidden 128, batch 256, 100 updates per
batch), 1 thread. With the advisor, every batch also builds a ``TrainingFeedback`` from the batch
and the batch's loss outputs and calls ``AdvisorTrigger.step`` (cooldown 0: it consults whenever
a threshold is crossed, the most expensive setting). Printed: the time inside the advisor code
over the loop's wall time (the direct measure), and the two runs' wall times.
"""

from __future__ import annotations

import tempfile
import time

from _runner import print_summary, print_table, setup


def main() -> None:
    args = setup(__doc__)
    import torch
    from tensordict.nn import NormalParamExtractor, TensorDictModule
    from torch import nn
    from torchrl.collectors import Collector
    from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
    from torchrl.modules import MLP, ProbabilisticActor, TanhNormal, ValueOperator

    from torchrl_auv.advisor import AdvisorTrigger, RuleBasedAdvisor, feedback_from_training
    from torchrl_auv.envs import AUVTrackingEnv
    from torchrl_auv.objectives import LyapunovActorCriticLoss

    batches = 4 if args.quick else 10

    def run(with_advisor: bool) -> tuple[float, float, int]:
        torch.manual_seed(0)
        env = AUVTrackingEnv(batch_size=[8], sea_state="es", seed=0)
        net = nn.Sequential(
            MLP(in_features=16, out_features=6, num_cells=[128, 128]), NormalParamExtractor()
        )
        actor = ProbabilisticActor(
            TensorDictModule(net, in_keys=["observation"], out_keys=["loc", "scale"]),
            in_keys=["loc", "scale"],
            spec=env.action_spec,
            distribution_class=TanhNormal,
            distribution_kwargs={"low": -1.0, "high": 1.0},
            return_log_prob=True,
        )
        critic = ValueOperator(
            MLP(in_features=19, out_features=16, num_cells=[128, 128]),
            in_keys=["observation", "action"],
        )
        loss = LyapunovActorCriticLoss(actor, critic, form="squared")
        optim = torch.optim.Adam(loss.parameters(), lr=3e-4)
        buffer = TensorDictReplayBuffer(storage=LazyTensorStorage(10_000), batch_size=256)
        folder = tempfile.mkdtemp()
        trigger = AdvisorTrigger(
            RuleBasedAdvisor(),
            "hold heading and depth in extreme seas",
            log_path=f"{folder}/advisor.jsonl",
            cooldown=0,
        )
        collector = Collector(
            env,
            actor,
            frames_per_batch=200,
            total_frames=200 * batches,
            auto_register_policy_transforms=False,
        )
        advisor_seconds, frames, consultations = 0.0, 0, 0
        start = time.perf_counter()
        if with_advisor:
            trigger.step(0, None, loss)
        for batch in collector:
            frames += batch.numel()
            buffer.extend(batch.reshape(-1))
            outputs = []
            for _ in range(100):
                out = loss(buffer.sample())
                optim.zero_grad()
                sum(v for k, v in out.items() if k.startswith("loss")).backward()
                optim.step()
                outputs.append(out.detach())
            if with_advisor:
                t0 = time.perf_counter()
                feedback = feedback_from_training(batch, outputs)
                trigger.step(frames, feedback, loss)
                advisor_seconds += time.perf_counter() - t0
        wall = time.perf_counter() - start
        collector.shutdown()
        consultations = len(trigger.records)
        return wall, advisor_seconds, consultations

    base_wall, _, _ = run(False)
    wall, advisor_seconds, consultations = run(True)
    print_table(
        f"short LAC training run, {batches} batches x (200 frames + 100 updates)",
        ["run", "wall s", "advisor s", "consultations"],
        [
            ["without advisor", base_wall, 0.0, 0],
            ["with RuleBasedAdvisor", wall, advisor_seconds, consultations],
        ],
    )
    print_summary(
        "bench_advisor",
        advisor_share_percent=100 * advisor_seconds / wall,
        wall_ratio=wall / base_wall,
        consultations=consultations,
    )


if __name__ == "__main__":
    main()
