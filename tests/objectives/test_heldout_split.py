"""The pretraining's held-out samples are whole episodes (samples of one episode are near
copies, so a split of samples would measure the training fit)."""

from __future__ import annotations

import torch
from tensordict import TensorDict

from torchrl_auv.objectives.pretraining import heldout_split


def test_whole_episodes_are_held_out():
    episode = torch.arange(20).repeat_interleave(50)  # 20 episodes of 50 samples
    data = TensorDict({"episode": episode, "x": torch.randn(1000, 2)}, [1000])
    heldout, train = heldout_split(data, 0.1, torch.Generator().manual_seed(0))
    assert len(heldout) == 100 and len(train) == 900  # 2 of 20 episodes
    assert not set(heldout["episode"].tolist()) & set(train["episode"].tolist())
    other, _ = heldout_split(data, 0.1, torch.Generator().manual_seed(1))
    assert set(other["episode"].tolist()) != set(heldout["episode"].tolist())  # seeded draw


def test_without_episodes_samples_are_split_and_one_episode_is_held_out_at_least():
    data = TensorDict({"x": torch.randn(50, 2)}, [50])
    heldout, train = heldout_split(data, 0.2, torch.Generator().manual_seed(0))
    assert (len(heldout), len(train)) == (10, 40)
    few = TensorDict({"episode": torch.tensor([0, 0, 1, 1, 2, 2])}, [6])
    heldout, train = heldout_split(few, 0.1, torch.Generator().manual_seed(0))
    assert len(heldout) == 2 and len(set(heldout["episode"].tolist())) == 1
