"""The pretrained diffusion proposer acting alone on the data-collection task (no RL).

    .venv/bin/python recipes/diffusion/train.py --config-name=quick run_dir=runs/diffusion-quick

1. First stage (shared by the diffusion recipes and sweep jobs: one cached artefact per
   first-stage values in ``proposer.cache_dir``, ``torchrl_auv.training.first_stage``):
   scripted-expert demonstrations, proposer pretraining and DAgger rounds; or ``proposer.path``.
2. Acting: every decision the proposer proposes ``proposer.alone_candidates`` chunks per AUV
   and executes the first action of their medoid (``proposer.alone_pick=medoid``; ``first``:
   candidate 0, one sample of the proposer), re-planned every decision. A ``Collector`` runs it for
   ``collector.total_frames`` frames: its training-time metrics and frames/s (nothing is
   trained after the first stage).
3. Evaluation on held-out seeds: the proposer next to the scripted expert and random actions.
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
    policy = training.proposer_alone(
        proposer,
        cfg.proposer.alone_pick,
        num_candidates=cfg.proposer.alone_candidates,
        replan_every=cfg.proposer.alone_replan_every,
    )

    # 2. run it (checkpoint: the frame count; the proposer itself is cached by the first stage)
    env = training.env_from_config(cfg)  # with the proposer's history (env.history)
    remaining = run.restore()
    collector = training.collector_from_config(cfg, policy, env=env, total_frames=max(remaining, 1))
    for _ in run.collect(collector, eval_policy=policy):  # counted, curve, checkpoints
        pass
    facts = {**stage.facts, **run.finish(collector)}

    # 3. evaluation on held-out seeds
    policies = {"diffusion": policy, **training.reference_policies()}
    print(run.evaluate(policies, title="Diffusion proposer alone", facts=facts).read_text())


if __name__ == "__main__":
    main()
