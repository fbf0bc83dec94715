"""SAC on the multi-AUV data-collection task: the paper's RL baseline (no proposer).

    .venv/bin/python recipes/sac/train.py --config-name=quick run_dir=runs/sac-quick

TorchRL's ``SACLoss`` trains a per-AUV TanhNormal actor and twin Q critics (weights shared by
the AUVs) on ``reward == -cost`` from a ``Collector`` and a ``TensorDictReplayBuffer`` holding only
what the loss reads. Writes under ``run_dir``: ``checkpoints/`` (``torchrl.checkpoint``,
rotated; ``resume=RUN_DIR`` continues a run), the logger's files (wandb offline by default),
``eval.csv`` and ``summary.md`` (the trained actor, the scripted expert and random actions on
held-out seeds). Metrics: see ``recipes/README.md``.
"""

from __future__ import annotations

import hydra
from omegaconf import DictConfig

from torchrl_auv import training


@hydra.main(config_path=".", config_name="paper", version_base="1.3")
def main(cfg: DictConfig) -> None:
    run = training.Run(cfg)  # checks every value before any work; folder, logger

    # env, actor, learner (SACLoss, target updater, optimisers), replay buffer
    env = training.env_from_config(cfg)
    actor = training.make_actor(env, cfg.network.hidden).to(cfg.device)
    learner = training.sac_from_config(cfg, env, actor)
    buffer = training.buffer_from_config(cfg, run.dir)
    remaining = run.restore(learner, buffer)  # resume: the newest; the learner counts updates
    # the update's batches: the online buffer, or half of each from the scripted expert's
    # demonstrations (demonstrations.frames > 0: RLPD's symmetric sampling)
    sample, demonstration_frames = training.sampler_from_config(cfg, buffer)

    # collector: the frames still to go, random actions first
    random_frames = max(0, cfg.collector.init_random_frames - run.progress.frames)
    collector = training.collector_from_config(
        cfg, actor, env=env, total_frames=max(remaining, 1), init_random_frames=random_frames
    )
    n_step = training.n_step_from_config(cfg)  # optim.n_steps > 1: n-step returns
    stored_bytes = None
    for data in run.collect(collector, eval_policy=actor):  # counts the batch's frames
        stored = training.select_for_replay(data, n_step=n_step)
        if stored is None:  # n-step returns need n_steps + 1 decisions per scene first
            continue
        stored_bytes = stored_bytes or training.bytes_per_frame(stored[0])
        buffer.extend(stored)
        if run.progress.frames >= cfg.collector.init_random_frames:
            for _ in range(cfg.optim.updates_per_batch):
                out = learner.step(sample().to(cfg.device))
            run.log(learner.metrics(out))
            collector.update_policy_weights_()  # worker processes / Ray act with the new weights
    facts = run.finish(collector)

    # evaluation on held-out seeds: the trained actor next to the expert and random actions
    facts["bytes per stored frame"] = stored_bytes or 0
    facts["demonstration frames"] = demonstration_frames
    policies = {"sac": actor, **training.reference_policies()}
    print(run.evaluate(policies, title="SAC on data collection", facts=facts).read_text())


if __name__ == "__main__":
    main()
