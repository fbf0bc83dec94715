"""Pretrain the diffusion proposer on a demonstrations dataset (the paper's offline stage).

    python -m recipes.pretrain_proposer --data demos/ --out runs/proposer/ [--steps 2000]

Reads a dataset written by ``python -m torchrl_auv.cli.demonstrations``, builds a
:class:`~torchrl_auv.modules.DiffusionProposer` for its keys and shapes, trains it with
:func:`~torchrl_auv.objectives.pretrain_proposer` and writes to ``--out`` (a new folder):
``proposer.pt`` (weights, config, schedule), ``loss.png`` (the paper's Fig. 4),
``candidates.png`` (K candidates of one held-out state at five denoising stages, Fig. 5),
``metrics.json`` (final training and held-out loss, sample counts) and the logger's files.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from torchrl_auv.training.run.seeding import configure_threads, seed_everything


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m recipes.pretrain_proposer")
    parser.add_argument("--data", required=True, help="demonstrations folder")
    parser.add_argument("--out", required=True, help="new output folder")
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--batch-size", type=int, default=32)
    parser.add_argument("--lr", type=float, default=1e-4)
    parser.add_argument("--noise-model", choices=("mlp", "unet"), default="mlp")
    parser.add_argument("--num-candidates", type=int, default=5)
    parser.add_argument("--num-inference-steps", type=int, default=50)
    parser.add_argument("--sampler", choices=("ddpm", "ddim"), default="ddpm")
    parser.add_argument("--schedule", choices=("linear", "cosine"), default="linear")
    parser.add_argument("--ema-decay", type=float, default=None)
    parser.add_argument("--heldout-fraction", type=float, default=0.1)
    parser.add_argument(
        "--keep-overridden",
        action="store_true",
        help="also train on decisions the env overrode (station keeping)",
    )
    parser.add_argument("--logger", default="csv", help="TorchRL logger backend or ''")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    out = Path(args.out)
    if out.exists() and any(out.iterdir()):
        parser.error(f"--out {out} exists and is not empty; choose a new folder")
    configure_threads(1)
    seed_everything(args.seed)

    import torch
    from torchrl.record.loggers import get_logger

    from torchrl_auv.envs.demonstrations import load_demonstrations
    from torchrl_auv.modules import DiffusionProposer
    from torchrl_auv.objectives import pretrain_proposer
    from torchrl_auv.report import plot_candidate_stages, plot_pretraining_loss

    try:
        buffer = load_demonstrations(args.data)
    except ValueError as err:
        parser.error(str(err))
    data = buffer.storage.get(torch.arange(len(buffer)))
    obs_dim = data["observation"].shape[-1]
    history, action_dim = data["history", "action"].shape[-2:]
    horizon = data["action_chunk"].shape[-2]
    proposer = DiffusionProposer(
        obs_dim + history * (obs_dim + action_dim + 1),
        action_dim,
        state_key="observation",
        history_key="history",
        num_candidates=args.num_candidates,
        horizon=horizon,
        num_inference_steps=args.num_inference_steps,
        sampler=args.sampler,
        noise_model=args.noise_model,
        schedule=args.schedule,
    )
    out.mkdir(parents=True, exist_ok=True)
    logger = (
        get_logger(args.logger, logger_name=str(out), experiment_name="pretrain_proposer")
        if args.logger
        else None
    )
    result = pretrain_proposer(
        proposer,
        data,
        steps=args.steps,
        batch_size=args.batch_size,
        lr=args.lr,
        heldout_fraction=args.heldout_fraction,
        ema_decay=args.ema_decay,
        logger=logger,
        seed=args.seed,
        log_every=max(1, args.steps // 100),
        eval_every=max(1, args.steps // 10),
        skip_overridden=not args.keep_overridden,
    )
    proposer.save(out / "proposer.pt")
    plot_pretraining_loss(
        result.steps,
        result.losses,
        out / "loss.png",
        heldout_steps=result.heldout_steps,
        heldout_losses=result.heldout_losses,
    )
    state = proposer.build_state(data[:1])
    _, stages = proposer.sample(
        state, generator=torch.Generator().manual_seed(args.seed), num_stages=5
    )
    plot_candidate_stages(stages[0], out / "candidates.png")
    metrics = {
        "samples": len(data),
        "overridden_samples": int(data["overridden"].sum()) if "overridden" in data.keys() else 0,
        "trained_on_overridden": bool(args.keep_overridden),
        "final_training_loss": result.losses[-1],
        "heldout_loss": result.heldout_loss,
        "steps": args.steps,
        "noise_model": args.noise_model,
    }
    (out / "metrics.json").write_text(json.dumps(metrics, indent=2))
    print(json.dumps(metrics))
    return 0


if __name__ == "__main__":
    sys.exit(main())
