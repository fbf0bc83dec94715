"""The full framework on the multi-AUV data-collection task (paper Algorithm 1).

    .venv/bin/python recipes/diffusion_lac/train.py --config-name=quick run_dir=runs/dlac-quick

1. First stage (one cached artefact per first-stage values in ``proposer.cache_dir``, shared
   by the diffusion recipes and sweep jobs): scripted-expert demonstrations, proposer
   pretraining and DAgger rounds, or ``proposer.path``.
2. Acting: the proposer proposes K action chunks per AUV; the Lyapunov critic scores their
   first actions and the actor's own action; the lowest L is executed. With
   ``residual.bound > 0`` instead: the proposer alone's action (the medoid of
   ``proposer.alone_candidates``) plus a bounded residual from the actor, which acts and which
   L constrains (``torchrl_auv.training.residual``; no selection, no "RL" or rank rows).
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

import hydra
from omegaconf import DictConfig

from torchrl_auv import report, training


@hydra.main(config_path=".", config_name="paper", version_base="1.3")
def main(cfg: DictConfig) -> None:
    run = training.Run(cfg)  # checks every value before any work; folder, logger

    # 1. first stage: a pretrained proposer (one cached artefact per first-stage values in
    #    proposer.cache_dir, shared by every recipe and sweep job; or proposer.path)
    stage = training.first_stage_from_config(cfg, plot_loss=report.plot_pretraining_loss)
    proposer = stage.proposer.to(cfg.device)

    # 2. env, actor, Lyapunov critic, LAC learner, the proposer-selector policy (ranking with
    #    the live critic through the spec the loss owns), the advisor loop
    env = training.env_from_config(cfg)  # with the proposer's history (env.history)
    critic = training.lyapunov_critic_from_config(cfg, env)  # lyapunov.inputs: what it reads
    bound = training.residual_bound(cfg)
    if bound:  # the actor acts: L bootstraps on it and constrains it; no selection
        actor = training.make_residual_actor(env, cfg.network.hidden, bound=bound)
        learner = training.lac_from_config(cfg, env, actor.to(cfg.device), critic)
        #    the executed action scored with L too (the Lyapunov trace reads it)
        policy = training.residual_policy(
            proposer,
            actor,
            pick=cfg.proposer.alone_pick,
            num_candidates=cfg.proposer.alone_candidates,
            lyapunov=(critic, learner.loss),
        )
    else:
        actor = training.make_actor(env, cfg.network.hidden).to(cfg.device)
        #    the rule (argmin, or anchored on the medoid) is shared by the selector and the
        #    critics' backup (selection.backup=candidates: on the next state's candidates)
        rule = training.selection_rule_from_config(cfg)
        learner = training.lac_from_config(cfg, env, actor, critic, rule=rule)
        competing = actor if cfg.selection.include_actor else None  # the actor's own action
        #    lyapunov.filter: the task critic's choice among the candidates that keep the
        #    decrease condition (veto: the medoid where it does; else the least L); off: argmin L
        mode = training.filter_mode(cfg)
        screen = training.lyapunov_filter(learner.loss, critic, mode) if mode else None
        policy = training.make_selection_policy(
            proposer,
            critic if screen is None else learner.loss.qvalue_network,
            mode="lyapunov" if screen is None else "cost",
            loss=learner.loss,
            actor=competing,
            critic_out_key=training.LYAPUNOV_RAW if screen is None else training.Q_VALUE,
            rule=rule,
            constraint=screen,
        )
    advising = training.AdvisorLoop(cfg, run.dir, run.logger, learner.loss)
    buffer = training.buffer_from_config(cfg, run.dir)
    remaining = run.restore(learner, buffer, modules=advising.checkpoint_modules())  # resume
    next_keys = training.next_state_keys(cfg)  # what the critics' backup reads of s'
    leg_keys = training.leg_keys(cfg)  # lyapunov.legs / filter: the approach-leg flags
    if not bound:
        training.start_deviating(rule, run.progress.frames, cfg)  # after selection.warmup_frames

    # 3. collect with the policy, train from the buffer, consult the advisor
    collector = training.collector_from_config(cfg, policy, env=env, total_frames=max(remaining, 1))
    for data in run.collect(collector, eval_policy=policy):  # counts the batch's frames
        if bound:  # the prior's action at the next state, for the actor's next action
            training.with_next_prior(data, policy[0])
        elif next_keys:  # the next state's candidates, for the critics' backup
            training.with_next_candidates(data, proposer)
        buffer.extend(training.select_for_replay(data, (*next_keys, *leg_keys)))
        for _ in range(cfg.optim.updates_per_batch):
            out = learner.step(buffer.sample().to(cfg.device))
        metrics = {**learner.metrics(out), **advising.step(run.progress.frames, data, out)}
        if not bound:
            training.start_deviating(rule, run.progress.frames, cfg)
        collector.update_policy_weights_()  # workers: new weights and Lyapunov form
        run.log(metrics, learner.loss.spec)
    facts = {**stage.facts, **run.finish(collector)}

    # 4. evaluation on held-out seeds: the framework, each rank alone (OA, CA1, ...), the actor
    #    alone, the proposer alone, the expert and random actions; plots
    spec = learner.loss.spec
    facts["Lyapunov spec at the end"] = f"{spec.form}, alpha {spec.alpha:g}"
    facts["advisor consultations"] = advising.trigger.consultations  # resumed sessions too
    facts["advisor failures"] = advising.trigger.failure_summary()  # also said on the console
    #    (plots and the Lyapunov trace first: eval.csv, written last, marks a finished run)
    print("\n".join(f"plot: {path}" for path in report.plot_run(cfg, run.dir, policy)))
    # the executed candidate's Lyapunov value along held-out episodes (Fig. 10-11)
    print(f"Lyapunov trace: {report.write_lyapunov_trace(cfg, run.dir, policy)}")
    policies = training.evaluation_policies_from_config(
        cfg, "diffusion_lac", policy, None if bound else actor, proposer
    )
    title = "Diffusion + residual LAC" if bound else "Diffusion + LAC"
    #    and the decrease condition on every row's executed approach transitions
    certificate = training.lyapunov_certificate(learner.loss, critic)
    print(run.evaluate(policies, title=title, facts=facts, certificate=certificate).read_text())


if __name__ == "__main__":
    main()
