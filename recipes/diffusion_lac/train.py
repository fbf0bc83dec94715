"""The full framework on the multi-AUV data-collection task (paper Algorithm 1).

    .venv/bin/python recipes/diffusion_lac/train.py --config-name=quick run_dir=runs/dlac-quick

1. First stage (one cached artefact per first-stage values in ``proposer.cache_dir``, shared
   by the diffusion recipes and sweep jobs): scripted-expert demonstrations, proposer
   pretraining and DAgger rounds, or ``proposer.path``.
2. Acting: the proposer proposes K action chunks per AUV; the Lyapunov critic scores their
   first actions and the actor's own action; the lowest L is executed.
3. Training: ``LyapunovActorCriticLoss`` (actor, Lyapunov critic, dual variables lambda and
   beta) from a ``TensorDictReplayBuffer`` filled by a ``Collector``; the advisor (rule-based
   by default, or any OpenAI-compatible endpoint) picks the Lyapunov form and weight at the
   start and when the feedback crosses a threshold, logging each decision to
   ``run_dir/advisor.jsonl``.
4. Evaluation on held-out seeds: the framework, each candidate rank executed on its own
   (OA = rank 0, CA1-CA4), the actor alone ("RL (LAC)"), the proposer alone, the scripted
   expert and random actions: ``eval.csv``, ``summary.md``.
"""

from __future__ import annotations

import logging

import hydra
import torch
from omegaconf import DictConfig
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.objectives import SoftUpdate

from torchrl_auv import advisor as advisors
from torchrl_auv import report, training
from torchrl_auv.training import diffusion

log = logging.getLogger(__name__)
LOGGED_LOSS_KEYS = ("loss_actor", "loss_lyapunov", "lambda", "beta", "violation_rate", "delta_l")
TASK_CRITIC_KEYS = ("loss_qvalue", "qvalue")  # with lyapunov.cost=stability


def make_advisor(cfg: DictConfig):
    if cfg.backend == "rules":
        return advisors.RuleBasedAdvisor()
    if cfg.backend == "fixed":  # the form and weight stay as configured (alpha/form studies)
        return advisors.FixedAdvisor()
    if cfg.backend == "openai":
        return advisors.OpenAICompatibleAdvisor(
            cfg.base_url, cfg.model, api_key_env=cfg.api_key_env
        )
    raise ValueError(f"advisor.backend must be 'rules', 'fixed' or 'openai', got {cfg.backend!r}")


@hydra.main(config_path=".", config_name="paper", version_base="1.3")
def main(cfg: DictConfig) -> None:
    run_dir = training.start_run(cfg)  # checks every value before any work
    advisor = make_advisor(cfg.advisor)

    # 1. first stage: a pretrained proposer (one cached artefact per first-stage values in
    #    proposer.cache_dir, shared by every recipe and sweep job; or proposer.path)
    stage = training.first_stage_from_config(cfg, plot_loss=report.plot_pretraining_loss)
    proposer = stage.proposer.to(cfg.device)

    # 2. env, actor, Lyapunov critic, loss, the proposer-selector policy
    env = training.env_from_config(cfg, history=cfg.proposer.history)
    actor = training.make_actor(env, cfg.network.hidden).to(cfg.device)
    critic = diffusion.make_lyapunov_critic(env, cfg.network.hidden).to(cfg.device)
    loss = diffusion.make_lac_loss(actor, critic, env, gamma=cfg.optim.gamma,
                                   form=cfg.advisor.form,
                                   stability_weight=cfg.advisor.stability_weight,
                                   lambda_max=cfg.optim.lambda_max,
                                   loss_function=cfg.optim.loss_function,
                                   cost=cfg.lyapunov.cost, hidden=cfg.network.hidden)  # fmt: skip
    target_updater = SoftUpdate(loss, tau=cfg.optim.tau)
    policy = diffusion.make_selection_policy(proposer, critic, mode="lyapunov",
                                             actor=actor if cfg.selection.include_actor else None,
                                             critic_out_key=diffusion.LYAPUNOV_RAW,
                                             loss=loss)  # the loss owns the spec  # fmt: skip
    optimisers = diffusion.lac_optimisers(loss, cfg.optim)
    buffer = training.buffer_from_config(cfg, run_dir)

    # checkpoint (resume: the newest), logger, advisor trigger
    logger = training.logger_from_config(cfg, run_dir)
    trigger = advisors.AdvisorTrigger(advisor, cfg.advisor.task, log_path=run_dir / "advisor.jsonl",
                                      cooldown=cfg.advisor.cooldown, logger=logger)  # fmt: skip
    progress = {"frames": 0, "updates": 0}
    modules = {"loss": loss, "spec": training.SpecState(loss), "advisor": trigger, **optimisers}
    checkpoint, rotation, remaining = training.prepare_resume(cfg, run_dir, modules, progress,
                                                              buffer)  # fmt: skip

    collector = training.collector_from_config(cfg, policy, env=env, history=cfg.proposer.history,
                                               total_frames=max(remaining, 1))  # fmt: skip
    tracker = training.RunTracker(cfg, run_dir, logger, progress, checkpoint, rotation,
                                  eval_policy=policy, history=cfg.proposer.history)  # fmt: skip
    window, outputs = [], []
    for data in collector if remaining > 0 else ():
        buffer.extend(training.select_for_replay(data))
        progress["frames"] += data.numel()
        for _ in range(cfg.optim.updates_per_batch):
            out = training.gradient_step(loss, optimisers, target_updater,
                                         buffer.sample().to(cfg.device))  # fmt: skip
            progress["updates"] += 1
        # the advisor: feedback over the last `window` batches; its new spec reaches the
        # selector through the loss (its owner)
        window = [*window, diffusion.feedback_batch(data)][-cfg.advisor.window :]
        outputs = [*outputs, out.detach()][-cfg.advisor.window :]
        feedback = advisors.feedback_from_training(
            window, outputs, position_indices=cfg.advisor.position_indices,
            velocity_indices=cfg.advisor.velocity_indices,
        )  # fmt: skip
        trigger.step(progress["frames"], feedback, loss)
        collector.update_policy_weights_()  # workers: new weights and Lyapunov form
        metrics = {f"train/{k}": out[k].item() for k in LOGGED_LOSS_KEYS + TASK_CRITIC_KEYS
                   if k in out.keys()}  # fmt: skip
        metrics["train/form_index"] = advisors.FORM_ORDER.index(loss.spec.form)
        tracker.step(data, metrics, loss.spec)
    facts = {**stage.facts, **tracker.finish(collector)}

    # 4. evaluation on held-out seeds
    policies = diffusion.evaluation_policies(
        "diffusion_lac",
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
    facts["Lyapunov spec at the end"] = f"{loss.spec.form}, alpha {loss.spec.alpha:g}"
    facts["advisor consultations"] = len(trigger.records)
    summary = training.finish_run(
        cfg, run_dir, logger, policies, title="Diffusion + LAC", facts=facts,
        step=progress["frames"], history=cfg.proposer.history,
    )  # fmt: skip
    # plots: the learning curve and one held-out evaluation episode of the framework
    eval_env = diffusion.make_history_env(
        cfg.eval.sea_states[0], history=cfg.proposer.history, seed=cfg.eval.seed, num_envs=1,
        controller=cfg.env.controller, rate_model=cfg.env.rate_model, max_steps=cfg.eval.steps,
    )  # fmt: skip
    with set_exploration_type(ExplorationType.DETERMINISTIC), torch.no_grad():
        episode = eval_env.rollout(cfg.eval.steps, policy, break_when_any_done=False)
    done = episode["next", "done"][0, :, 0]
    end = int(done.nonzero()[0, 0]) + 1 if done.any() else done.numel()  # its first episode
    curve = run_dir / "train_curve.csv"
    plots = [report.plot_learning_curve(curve, run_dir / "learning_curve.png"),
             report.plot_episode(episode[:, :end], run_dir / "eval_episode.png")]  # fmt: skip
    print(summary.read_text())
    print("\n".join(f"plot: {path}" for path in plots))


if __name__ == "__main__":
    main()
