"""Diffusion proposer + Q-critic selection + SAC on the multi-AUV data-collection task
(Algorithm 1 without the Lyapunov parts).

    .venv/bin/python recipes/diffusion_rl/train.py --config-name=quick run_dir=runs/drl-quick

1. First stage (one cached artefact per first-stage values in ``proposer.cache_dir``, shared
   by the diffusion recipes and sweep jobs): scripted-expert demonstrations, proposer
   pretraining and DAgger rounds, or ``proposer.path``.
2. Acting: the proposer proposes K action chunks per AUV; the Q critic (the min over SAC's twin
   Q networks, ``QEnsembleCritic.from_loss``) scores their first actions and the actor's own
   action; the highest Q is executed.
3. Training: TorchRL's ``SACLoss`` (actor, twin Q, temperature) from a
   ``TensorDictReplayBuffer`` filled by a ``Collector``, on the executed actions.
4. Evaluation on held-out seeds: the framework, each candidate rank on its own (OA, CA1, ...),
   the actor alone ("RL"), the proposer alone, the scripted expert and random actions.
"""

from __future__ import annotations

import hydra
from omegaconf import DictConfig

from torchrl_auv import report, training
from torchrl_auv.objectives import QEnsembleCritic
from torchrl_auv.training import diffusion

LOGGED_LOSS_KEYS = ("loss_actor", "loss_qvalue", "alpha", "entropy")


@hydra.main(config_path=".", config_name="paper", version_base="1.3")
def main(cfg: DictConfig) -> None:
    run_dir = training.start_run(cfg)  # checks every value before any work

    # 1. first stage: a pretrained proposer (one cached artefact per first-stage values in
    #    proposer.cache_dir, shared by every recipe and sweep job; or proposer.path)
    stage = training.first_stage_from_config(cfg, plot_loss=report.plot_pretraining_loss)
    proposer = stage.proposer.to(cfg.device)

    # 2. env, actor, twin Q critics, SAC loss, the proposer-selector policy
    env = training.env_from_config(cfg, history=cfg.proposer.history)
    actor = training.make_actor(env, cfg.network.hidden).to(cfg.device)
    critic = training.make_q_critic(env, cfg.network.hidden).to(cfg.device)
    loss, target_updater = training.make_sac_loss(
        actor, critic, env, gamma=cfg.optim.gamma, alpha_init=cfg.optim.alpha_init,
        tau=cfg.optim.tau, loss_function=cfg.optim.loss_function,
    )  # fmt: skip
    q_critic = QEnsembleCritic.from_loss(loss)  # the live twin Q, reduced by min
    policy = diffusion.make_selection_policy(proposer, q_critic, mode="q",
                                             actor=actor if cfg.selection.include_actor else None,
                                             critic_out_key=q_critic.out_keys[0])  # fmt: skip
    optimisers = training.sac_optimisers(loss, cfg.optim)
    buffer = training.buffer_from_config(cfg, run_dir)

    # checkpoint (resume: the newest), logger
    progress = {"frames": 0, "updates": 0}
    checkpoint, rotation, remaining = training.prepare_resume(
        cfg, run_dir, {"loss": loss, **optimisers}, progress, buffer
    )
    logger = training.logger_from_config(cfg, run_dir)

    # 3. collect with the policy, train from the buffer
    collector = training.collector_from_config(cfg, policy, env=env, history=cfg.proposer.history,
                                               total_frames=max(remaining, 1))  # fmt: skip
    tracker = training.RunTracker(cfg, run_dir, logger, progress, checkpoint, rotation,
                                  eval_policy=policy, history=cfg.proposer.history)  # fmt: skip
    for data in collector if remaining > 0 else ():
        buffer.extend(training.select_for_replay(data))
        progress["frames"] += data.numel()
        for _ in range(cfg.optim.updates_per_batch):
            out = training.gradient_step(loss, optimisers, target_updater,
                                         buffer.sample().to(cfg.device))  # fmt: skip
            progress["updates"] += 1
        collector.update_policy_weights_()  # worker processes / Ray act with the new weights
        metrics = {f"train/{k}": out[k].item() for k in LOGGED_LOSS_KEYS}
        tracker.step(data, metrics)
    facts = {**stage.facts, **tracker.finish(collector)}

    # 4. evaluation on held-out seeds
    policies = diffusion.evaluation_policies(
        "diffusion_rl",
        policy,
        actor,
        proposer,
        pick=cfg.proposer.alone_pick,
        alone_candidates=cfg.proposer.alone_candidates,
        alone_replan_every=cfg.proposer.alone_replan_every,
        ranks=cfg.eval.ranks,
    )
    policies.update(training.reference_policies())
    facts["gradient updates"] = progress["updates"]
    summary = training.finish_run(
        cfg, run_dir, logger, policies, title="Diffusion + Q selection + SAC", facts=facts,
        step=progress["frames"], history=cfg.proposer.history,
    )  # fmt: skip
    print(summary.read_text())


if __name__ == "__main__":
    main()
