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
import time
from pathlib import Path

import hydra
import torch
import tqdm
from omegaconf import DictConfig, OmegaConf

from torchrl_auv import training

log = logging.getLogger(__name__)


def make_eval_env(cfg: DictConfig):
    return lambda sea, seed: training.make_env(
        sea, seed=seed, num_envs=cfg.eval.num_envs, controller=cfg.env.controller,
        rate_model=cfg.env.rate_model, max_steps=cfg.eval.steps,
    )  # fmt: skip


@hydra.main(config_path=".", config_name="config", version_base="1.3")
def main(cfg: DictConfig) -> None:
    training.check_choices(OmegaConf.to_container(cfg, resolve=True))
    torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    run_dir = Path(cfg.resume or cfg.run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)

    # env, model, loss
    env = training.make_env(cfg.env.sea_state, seed=cfg.seed, num_envs=cfg.env.num_envs,
                            controller=cfg.env.controller, rate_model=cfg.env.rate_model,
                            max_steps=cfg.env.max_steps, device=cfg.device)  # fmt: skip
    actor = training.make_actor(env, cfg.network.hidden).to(cfg.device)
    critic = training.make_q_critic(env, cfg.network.hidden).to(cfg.device)
    loss, target_updater = training.make_sac_loss(actor, critic, env, gamma=cfg.optim.gamma,
                                                  alpha_init=cfg.optim.alpha_init,
                                                  tau=cfg.optim.tau)  # fmt: skip
    optimisers = {
        "actor_optim": torch.optim.Adam(loss.actor_network_params.parameters(),
                                        lr=cfg.optim.actor_lr),
        "critic_optim": torch.optim.Adam(loss.qvalue_network_params.parameters(),
                                         lr=cfg.optim.critic_lr),
        "alpha_optim": torch.optim.Adam([loss.log_alpha], lr=cfg.optim.alpha_lr),
    }  # fmt: skip
    buffer = training.make_replay_buffer(cfg.replay_buffer.size,
                                         batch_size=cfg.replay_buffer.batch_size,
                                         storage=cfg.replay_buffer.storage,
                                         scratch_dir=run_dir / "replay")  # fmt: skip

    # checkpoint (resume: load the newest), logger
    progress = {"frames": 0, "log_step": 0, "updates": 0}
    modules = {"loss": loss, **optimisers}
    if cfg.checkpoint.replay_buffer:
        modules["replay_buffer"] = buffer
    checkpoint, rotation = training.make_checkpoint(run_dir, modules=modules, progress=progress,
                                                    keep_last=cfg.checkpoint.keep_last)  # fmt: skip
    if cfg.resume:
        training.resume_latest(run_dir, checkpoint, progress)
        log.info("resumed %s at %d frames", run_dir, progress["frames"])
    logger = training.make_logger(cfg.logger.backend, run_dir, exp_name=cfg.logger.exp_name,
                                  project=cfg.logger.project, offline=cfg.logger.offline,
                                  config=OmegaConf.to_container(cfg, resolve=True))  # fmt: skip

    # collector: the frames still to go
    remaining = cfg.collector.total_frames - progress["frames"]
    random_frames = max(0, cfg.collector.init_random_frames - progress["frames"])
    collector = training.make_collector(env, actor, frames_per_batch=cfg.collector.frames_per_batch,
                                        total_frames=max(remaining, 1),
                                        init_random_frames=random_frames,
                                        device=cfg.device)  # fmt: skip

    bar = tqdm.tqdm(total=cfg.collector.total_frames, initial=progress["frames"], unit="frame")
    start, frames_at_start, last_saved = time.perf_counter(), progress["frames"], progress["frames"]
    stored_bytes = None
    for data in collector if remaining > 0 else ():
        stored = training.select_for_replay(data)
        stored_bytes = stored_bytes or training.bytes_per_frame(stored[0])
        buffer.extend(stored)
        progress["frames"] += data.numel()
        metrics = {}
        if progress["frames"] >= cfg.collector.init_random_frames:
            for _ in range(cfg.optim.updates_per_batch):
                out = loss(buffer.sample().to(cfg.device))
                total = out["loss_actor"] + out["loss_qvalue"] + out["loss_alpha"]
                for opt in optimisers.values():
                    opt.zero_grad()
                total.backward()
                for opt in optimisers.values():
                    opt.step()
                target_updater.step()
                progress["updates"] += 1
            metrics.update({f"train/{k}": out[k].item() for k in ("loss_actor", "loss_qvalue",
                                                                  "alpha", "entropy")})  # fmt: skip
        metrics["train/cost_mean"] = data["next", "agents", "cost"].mean().item()
        ended = data["next", "done"][..., 0]
        if ended.any():
            for name in ("sdr", "ssn", "collisions", "violations"):
                metrics[f"train/episode_{name}"] = (
                    data["next", "metrics", name][ended].float().mean().item()
                )
        elapsed = time.perf_counter() - start
        metrics["time/frames_per_s"] = (progress["frames"] - frames_at_start) / elapsed
        metrics["time/elapsed_s"] = elapsed
        progress["log_step"] += 1
        if logger is not None:
            for key, value in metrics.items():
                logger.log_scalar(key, value, step=progress["frames"])
        bar.update(data.numel())
        bar.set_postfix(cost=f"{metrics['train/cost_mean']:.3f}",
                        ssn=f"{metrics.get('train/episode_ssn', float('nan')):.1f}")  # fmt: skip
        if progress["frames"] - last_saved >= cfg.checkpoint.every_frames:
            rotation.save(checkpoint, step=progress["frames"])
            last_saved = progress["frames"]
    collector.shutdown()
    bar.close()
    rotation.save(checkpoint, step=progress["frames"])
    wall = time.perf_counter() - start

    # evaluation on held-out seeds: the trained actor next to the expert and random actions
    policies = {"sac": lambda _: actor, **training.reference_policies()}
    rows = training.evaluate(make_eval_env(cfg), policies, cfg.eval.sea_states,
                             seed=cfg.eval.seed, steps=cfg.eval.steps)  # fmt: skip
    training.write_eval(rows, run_dir)
    if logger is not None:
        for row in rows:
            for key in training.summary.SUMMARY_COLUMNS:
                logger.log_scalar(f"eval/{row['sea_state']}/{row['policy']}/{key}", row[key],
                                  step=progress["frames"])  # fmt: skip
    facts = {"frames": progress["frames"], "gradient updates": progress["updates"],
             "wall time this session (s)": wall,
             "training frames/s": (progress["frames"] - frames_at_start) / max(wall, 1e-9),
             "bytes per stored frame": stored_bytes or 0}  # fmt: skip
    summary = training.write_summary(
        run_dir, title="SAC on data collection", rows=rows, facts=facts
    )
    if logger is not None and hasattr(logger, "experiment"):
        logger.experiment.finish()
    print(summary.read_text())


if __name__ == "__main__":
    main()
