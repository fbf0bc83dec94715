"""The pretrained diffusion proposer acting alone on the data-collection task (no RL).

    .venv/bin/python recipes/diffusion/train.py --config-name=quick run_dir=runs/diffusion-quick

1. First stage (shared by the diffusion recipes, cached in ``run_dir/proposer``): scripted-
   expert demonstrations and proposer pretraining, or ``proposer.path``.
2. Acting: every decision the proposer proposes K chunks per AUV and executes candidate 0's
   first action (the K candidates are i.i.d. draws, so this is one sample of the proposer),
   re-planned every decision. A ``Collector`` runs it for ``collector.total_frames`` frames:
   its training-time metrics and frames/s (nothing is trained after the first stage).
3. Evaluation on held-out seeds: the proposer next to the scripted expert and random actions.
"""

from __future__ import annotations

import hydra
from omegaconf import DictConfig

from torchrl_auv import training
from torchrl_auv.training import diffusion


@hydra.main(config_path=".", config_name="paper", version_base="1.3")
def main(cfg: DictConfig) -> None:
    run_dir = training.start_run(cfg)  # checks every value before any work

    # 1. first stage: a pretrained proposer (cached in run_dir/proposer, or proposer.path)
    proposer = diffusion.proposer_from_config(run_dir, cfg).to(cfg.device)
    policy = diffusion.ProposerAlone(proposer)

    # 2. run it (checkpoint: the frame count; the proposer itself is cached by the first stage)
    env = training.env_from_config(cfg, history=cfg.proposer.history)
    progress = {"frames": 0}
    checkpoint, rotation, remaining = training.prepare_resume(cfg, run_dir, {}, progress)
    logger = training.logger_from_config(cfg, run_dir)
    collector = training.collector_from_config(cfg, policy, env=env, history=cfg.proposer.history,
                                               total_frames=max(remaining, 1))  # fmt: skip
    tracker = training.RunTracker(cfg, run_dir, logger, progress, checkpoint, rotation)
    for data in collector if remaining > 0 else ():
        progress["frames"] += data.numel()
        tracker.step(data, {})
    facts = tracker.finish(collector)

    # 3. evaluation on held-out seeds
    policies = {"diffusion": lambda _: policy, **training.reference_policies()}
    summary = training.finish_run(
        cfg, run_dir, logger, policies, title="Diffusion proposer alone", facts=facts,
        step=progress["frames"], history=cfg.proposer.history,
    )  # fmt: skip
    print(summary.read_text())


if __name__ == "__main__":
    main()
