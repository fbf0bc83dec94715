"""Diffusion proposer + Q-critic selection + SAC on the multi-AUV data-collection task
(Algorithm 1 without the Lyapunov parts).

    .venv/bin/python recipes/diffusion_rl/train.py --config-name=quick run_dir=runs/drl-quick

1. First stage (one cached artefact per first-stage values in ``proposer.cache_dir``, shared
   by the diffusion recipes and sweep jobs): scripted-expert demonstrations, proposer
   pretraining and DAgger rounds, or ``proposer.path``.
2. Acting: the proposer proposes K action chunks per AUV; the Q ensemble
   (``network.critics`` networks, ``QEnsembleCritic.from_loss``) scores their first actions
   (and, with ``selection.include_actor``, the actor's own action); the selection rule executes
   the medoid unless every critic prefers another candidate (``selection.anchor``,
   ``selection.dominance``), or the highest Q (``selection.anchor=null``, the paper).
   With ``finetune.steps > 0`` the proposer itself is fine-tuned after each batch's updates on
   its own candidates, weighted by their Q (``torchrl_auv.training.proposer_finetuning``).
   With ``residual.bound > 0`` instead: the proposer alone's action (the medoid of
   ``proposer.alone_candidates``) plus a bounded residual from the actor, which acts
   (``torchrl_auv.training.residual``; no selection, no "RL" or rank rows).
3. Training: TorchRL's ``SACLoss`` (actor, Q ensemble, temperature; the Q target on the
   candidate executed at the next state, ``selection.backup``; ``optim.n_steps``-step returns)
   from a ``TensorDictReplayBuffer`` filled by a ``Collector``, on the executed actions.
4. Evaluation on held-out seeds: the framework, each candidate rank on its own (OA, CA1, ...),
   the actor alone ("RL"), the proposer alone, the scripted expert and random actions.
"""

from __future__ import annotations

import copy

import hydra
from omegaconf import DictConfig

from torchrl_auv import report, training
from torchrl_auv.objectives import QEnsembleCritic


@hydra.main(config_path=".", config_name="paper", version_base="1.3")
def main(cfg: DictConfig) -> None:
    run = training.Run(cfg)  # checks every value before any work; folder, logger

    # 1. first stage: a pretrained proposer (one cached artefact per first-stage values in
    #    proposer.cache_dir, shared by every recipe and sweep job; or proposer.path)
    stage = training.first_stage_from_config(cfg, plot_loss=report.plot_pretraining_loss)
    proposer = stage.proposer.to(cfg.device)

    # 2. env, actor, SAC learner, the policy that acts: the proposer-selector ranking with the
    #    live Q ensemble, or (residual.bound > 0) a residual actor on the proposer alone's choice
    env = training.env_from_config(cfg)  # with the proposer's history (env.history)
    bound = training.residual_bound(cfg)
    if bound:  # the actor acts: SAC's own backup on it, no selection
        actor = training.make_residual_actor(env, cfg.network.hidden, bound=bound)
        learner = training.sac_from_config(cfg, env, actor.to(cfg.device))
        policy = training.residual_policy(
            proposer,
            actor,
            pick=cfg.proposer.alone_pick,
            num_candidates=cfg.proposer.alone_candidates,
        )
    else:
        actor = training.make_actor(env, cfg.network.hidden).to(cfg.device)
        #    the rule (argmax, or anchored on the medoid) is shared by the selector and the
        #    critics' backup (selection.backup=candidates: on the next state's candidates)
        rule = training.selection_rule_from_config(cfg)
        learner = training.sac_from_config(cfg, env, actor, rule=rule)
        q_critic = QEnsembleCritic.from_loss(learner.loss)  # the min over the Q ensemble
        competing = actor if cfg.selection.include_actor else None  # the actor's own action
        policy = training.make_selection_policy(
            proposer,
            q_critic,
            mode="q",
            actor=competing,
            critic_out_key=q_critic.out_keys[0],
            rule=rule,
        )
    #    finetune.steps > 0: the proposer learns too; the first stage's stays the prior's row
    finetune = training.finetuning_from_config(cfg, proposer, first_stage=stage.folder)
    prior = copy.deepcopy(proposer) if finetune else proposer
    buffer = training.buffer_from_config(cfg, run.dir)
    tuned = {"proposer": proposer, "finetune": finetune} if finetune else None
    remaining = run.restore(learner, buffer, modules=tuned)  # resume: the newest checkpoint
    next_keys = training.next_state_keys(cfg)  # what the critics' backup reads of s'
    n_step = training.n_step_from_config(cfg)  # optim.n_steps > 1: n-step returns
    if not bound:
        training.start_deviating(rule, run.progress.frames, cfg)  # after selection.warmup_frames

    # 3. collect with the policy, train from the buffer
    collector = training.collector_from_config(cfg, policy, env=env, total_frames=max(remaining, 1))
    for data in run.collect(collector, eval_policy=policy):  # counts the batch's frames
        if bound:  # the prior's action at the next state, for the actor's next action
            training.with_next_prior(data, policy[0])
        elif next_keys:  # the next state's candidates, for the critics' backup
            training.with_next_candidates(data, proposer)
        stored = training.select_for_replay(data, next_keys, n_step=n_step)
        if stored is None:  # n-step returns need n_steps + 1 decisions per scene first
            continue
        buffer.extend(stored)
        for _ in range(cfg.optim.updates_per_batch):
            out = learner.step(buffer.sample().to(cfg.device))
        metrics = learner.metrics(out)
        if finetune:  # the proposer toward the candidates its critics prefer
            metrics.update(finetune.step(data, run.progress.frames))
        if not bound:
            training.start_deviating(rule, run.progress.frames, cfg)
        collector.update_policy_weights_()  # worker processes / Ray act with the new weights
        run.log(metrics)
    facts = {**stage.facts, **run.finish(collector)}

    # 4. evaluation on held-out seeds: the framework, each rank alone (OA, CA1, ...), the actor
    #    alone, the proposer alone, the expert and random actions
    policies = training.evaluation_policies_from_config(
        cfg, "diffusion_rl", policy, None if bound else actor, prior
    )
    title = "Diffusion + residual SAC" if bound else "Diffusion + Q selection + SAC"
    print(run.evaluate(policies, title=title, facts=facts).read_text())


if __name__ == "__main__":
    main()
