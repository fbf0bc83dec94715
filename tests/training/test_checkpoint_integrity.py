"""Checkpoints verified on load: a damaged newest checkpoint is passed over with its path named,
the next intact one is loaded, and rotation never deletes the newest intact one."""

from __future__ import annotations

import shutil
import warnings

import pytest
import torch
from torchrl.checkpoint import CheckpointError

from torchrl_auv.training.run.checkpointing import make_checkpoint, resume_latest
from torchrl_auv.training.run.progress import Progress
from torchrl_auv.training.run.verified_rotation import CHECKSUMS, checkpoint_problems


def _two_checkpoints(run_dir):
    """Checkpoints at frames 100 (weights 1) and 200 (weights 2) of a net and its optimiser."""
    net = torch.nn.Linear(8, 16)
    optimiser = torch.optim.Adam(net.parameters())
    progress = Progress()
    checkpoint, rotation = make_checkpoint(
        run_dir, modules={"net": net, "opt": optimiser}, progress=progress, keep_last=2
    )
    for frames, value in ((100, 1.0), (200, 2.0)):
        with torch.no_grad():
            net.weight.fill_(value)
        progress.frames = frames
        rotation.save(checkpoint, step=frames)
    return net, checkpoint, rotation, progress


def _truncate(path):
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


def _flip_a_byte(path):
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))


def _weights(root):
    return max(
        (p for p in root.rglob("*.memmap") if "0000-net" in str(p)), key=lambda p: p.stat().st_size
    )


DAMAGES = {
    "truncated weights": lambda root: _truncate(_weights(root)),
    "flipped byte in weights": lambda root: _flip_a_byte(_weights(root)),
    "truncated state.json": lambda root: _truncate(next(root.rglob("0001-opt/state.json"))),
    "truncated manifest": lambda root: _truncate(root / "manifest.json"),
    "missing weight file": lambda root: _weights(root).unlink(),
    "unlisted extra file": lambda root: (root / "components" / "extra.bin").write_bytes(b"x"),
    "unreadable checksums": lambda root: _truncate(root / CHECKSUMS),
}


@pytest.mark.parametrize("damage", DAMAGES)
def test_a_damaged_newest_checkpoint_is_named_and_the_previous_one_loaded(tmp_path, damage):
    net, checkpoint, rotation, progress = _two_checkpoints(tmp_path)
    newest = rotation.latest()
    assert checkpoint_problems(newest) == []
    DAMAGES[damage](newest)
    assert checkpoint_problems(newest)
    with torch.no_grad():
        net.weight.zero_()
    with pytest.warns(UserWarning, match=str(newest)):
        frames, _ = resume_latest(tmp_path, checkpoint, progress)
    assert frames == 100 and progress.frames == 100
    assert bool((net.weight == 1.0).all())  # the older checkpoint's weights, not zeros


def test_no_intact_checkpoint_is_an_error_naming_each_one(tmp_path):
    _, checkpoint, rotation, progress = _two_checkpoints(tmp_path)
    paths = rotation.checkpoint_dirs()
    for path in paths:
        _truncate(_weights(path))
    with pytest.raises(CheckpointError) as error, pytest.warns(UserWarning):
        resume_latest(tmp_path, checkpoint, progress)
    assert all(str(path) in str(error.value) for path in paths)


def test_rotation_keeps_the_newest_intact_checkpoint_and_clears_cut_short_saves(tmp_path):
    _, checkpoint, rotation, _ = _two_checkpoints(tmp_path)
    rotation.keep_last = 1
    older, newest = rotation.checkpoint_dirs()
    _truncate(_weights(newest))
    stage = rotation.directory / ".stage-cut-short"  # a save killed before publishing
    shutil.copytree(older, stage)
    assert rotation.newest_intact()[0] == older
    rotation.prune()
    assert rotation.checkpoint_dirs() == [older, newest]  # the intact one survives keep_last=1
    assert not stage.exists()
    # a new intact save makes the old ones expendable
    rotation.save(checkpoint, step=300)
    assert [p.name[-3:] for p in rotation.checkpoint_dirs()] == ["300"]


def test_a_checkpoint_without_checksums_loads_with_a_warning_when_nothing_verifies(tmp_path):
    """Runs saved before checksums existed still resume (unverified, said so)."""
    _, checkpoint, rotation, progress = _two_checkpoints(tmp_path)
    for path in rotation.checkpoint_dirs():
        (path / CHECKSUMS).unlink()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        frames, _ = resume_latest(tmp_path, checkpoint, progress)
    assert frames == 200
    assert [str(w.message)[:40] for w in caught] == [
        f"checkpoint {rotation.checkpoint_dirs()[-1]}"[:40]
    ]
    assert "cannot be verified" in str(caught[0].message)
