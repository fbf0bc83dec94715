"""The pretraining recipe: demonstrations in, checkpoint, loss curve, candidates and metrics out."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import torch

from torchrl_auv.envs.demonstrations import collect_demonstrations, save_demonstrations
from torchrl_auv.modules import DiffusionProposer

REPO = Path(__file__).resolve().parents[2]


def main(argv):
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    return subprocess.run(
        [sys.executable, "-m", "recipes.pretrain_proposer", *argv],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )


def test_pretraining_writes_a_checkpoint_that_loads_and_a_falling_loss(tmp_path):
    data = collect_demonstrations("tracking", episodes=2, max_steps=40, seed=0)
    save_demonstrations(data, tmp_path / "demos")
    out = tmp_path / "run"
    assert (
        main(
            [
                "--data",
                str(tmp_path / "demos"),
                "--out",
                str(out),
                "--steps",
                "200",
                "--batch-size",
                "64",
                "--lr",
                "1e-3",
                "--num-inference-steps",
                "5",
                "--logger",
                "csv",
            ]
        ).returncode
        == 0
    )
    for name in ("proposer.pt", "loss.png", "candidates.png", "metrics.json"):
        assert (out / name).stat().st_size > 0, name
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["samples"] == 80 and metrics["heldout_loss"] > 0
    proposer = DiffusionProposer.load(out / "proposer.pt")
    candidates, _ = proposer.sample(proposer.build_state(data[:3]))
    assert candidates.shape == (3, 5, 8, 3) and candidates.abs().max() <= 1.0
    again = main(["--data", str(tmp_path / "demos"), "--out", str(out)])
    assert again.returncode != 0 and "not empty" in again.stderr  # never overwrites


def test_the_pretraining_loss_falls():
    from torchrl_auv.objectives import pretrain_proposer

    data = collect_demonstrations("tracking", episodes=2, max_steps=40, seed=0)
    proposer = DiffusionProposer(16 + 10 * 20, 3, history_key="history")
    torch.manual_seed(0)
    result = pretrain_proposer(
        proposer, data, steps=300, batch_size=64, lr=1e-3, log_every=50, eval_every=100
    )
    assert result.losses[-1] < 0.75 * result.losses[0]
    assert result.heldout_losses[-1] < result.heldout_losses[0]


def test_pretraining_leaves_the_overridden_decisions_out_by_default():
    """Demonstrated actions of overridden decisions (never executed) must not be imitated:
    half the samples say +0.9 but are overridden, the other half say -0.9; trained with the
    default the proposer proposes -0.9, with ``skip_overridden=False`` both modes."""
    from tensordict import TensorDict

    from torchrl_auv.objectives import pretrain_proposer

    n = 512
    overridden = torch.arange(n) % 2 == 0
    chunk = torch.where(overridden, 0.9, -0.9)[:, None, None].expand(n, 4, 2).clone()
    data = TensorDict(
        {"observation": torch.zeros(n, 3), "action_chunk": chunk, "overridden": overridden},
        batch_size=[n],
    )
    means = {}
    for skip in (True, False):
        torch.manual_seed(0)
        proposer = DiffusionProposer(3, 2, horizon=4, num_inference_steps=10, num_candidates=200)
        pretrain_proposer(
            proposer,
            data,
            steps=300,
            batch_size=64,
            lr=1e-3,
            skip_overridden=skip,
            heldout_fraction=0.0,
        )
        candidates, _ = proposer.sample(
            torch.zeros(1, 3), generator=torch.Generator().manual_seed(1)
        )
        means[skip] = (candidates[..., 0, 0] > 0).float().mean().item()  # share near +0.9
    assert means[True] < 0.05  # only the executed (-0.9) actions
    assert 0.2 < means[False] < 0.8  # both modes
