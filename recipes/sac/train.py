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

import logging

import hydra
from omegaconf import DictConfig

from torchrl_auv import training

log = logging.getLogger(__name__)
LOGGED_LOSS_KEYS = ("loss_actor", "loss_qvalue", "alpha", "entropy")


@hydra.main(config_path=".", config_name="paper", version_base="1.3")
def main(cfg: DictConfig) -> None:
    run_dir = training.start_run(cfg)  # checks every value before any work

    # env, model, loss
    env = training.env_from_config(cfg)
    actor = training.make_actor(env, cfg.network.hidden).to(cfg.device)
    critic = training.make_q_critic(env, cfg.network.hidden).to(cfg.device)
    loss, target_updater = training.make_sac_loss(
        actor, critic, env, gamma=cfg.optim.gamma, alpha_init=cfg.optim.alpha_init,
        tau=cfg.optim.tau, loss_function=cfg.optim.loss_function,
    )  # fmt: skip
    optimisers = training.sac_optimisers(loss, cfg.optim)
    buffer = training.buffer_from_config(cfg, run_dir)

    # checkpoint (resume: load the newest), logger
    progress = {"frames": 0, "updates": 0}
    checkpoint, rotation, remaining = training.prepare_resume(
        cfg, run_dir, {"loss": loss, **optimisers}, progress, buffer
    )
    logger = training.logger_from_config(cfg, run_dir)

    # collector: the frames still to go
    random_frames = max(0, cfg.collector.init_random_frames - progress["frames"])
    collector = training.collector_from_config(cfg, actor, env=env, total_frames=max(remaining, 1),
                                               init_random_frames=random_frames)  # fmt: skip

    tracker = training.RunTracker(cfg, run_dir, logger, progress, checkpoint, rotation,
                                  eval_policy=actor)  # fmt: skip
    stored_bytes = None
    for data in collector if remaining > 0 else ():
        stored = training.select_for_replay(data)
        stored_bytes = stored_bytes or training.bytes_per_frame(stored[0])
        buffer.extend(stored)
        progress["frames"] += data.numel()
        metrics = {}
        if progress["frames"] >= cfg.collector.init_random_frames:
            for _ in range(cfg.optim.updates_per_batch):
                out = training.gradient_step(loss, optimisers, target_updater,
                                             buffer.sample().to(cfg.device))  # fmt: skip
                progress["updates"] += 1
            metrics.update({f"train/{k}": out[k].item() for k in LOGGED_LOSS_KEYS})
            collector.update_policy_weights_()  # worker processes / Ray act with the new weights
        tracker.step(data, metrics)
    facts = tracker.finish(collector)

    # evaluation on held-out seeds: the trained actor next to the expert and random actions
    facts["gradient updates"] = progress["updates"]
    facts["bytes per stored frame"] = stored_bytes or 0
    policies = {"sac": lambda _: actor, **training.reference_policies()}
    summary = training.finish_run(cfg, run_dir, logger, policies, title="SAC on data collection",
                                  facts=facts, step=progress["frames"])  # fmt: skip
    print(summary.read_text())


if __name__ == "__main__":
    main()
