"""Demonstrations: chunks line up with the expert's actions; the CLI's dataset loads back."""

from __future__ import annotations

import subprocess
import sys

import pytest
import torch

from torchrl_auv.envs.demonstrations import collect_demonstrations, load_demonstrations


def test_chunks_are_the_next_actions_of_the_same_episode():
    data = collect_demonstrations(episodes=2, max_steps=6, horizon=3, history=4)
    assert data.batch_size == (12,)
    for i in range(12):
        ep, t = data["episode"][i].item(), data["step"][i].item()
        for h in range(3):
            j = i + h if t + h < 6 else ep * 6 + 5
            torch.testing.assert_close(data["action_chunk"][i, h], data["action"][j])
            assert data["action_chunk_mask"][i, h].item() == (t + h < 6)
        if t > 0:  # newest history entry is the previous decision's action
            torch.testing.assert_close(data["history", "action"][i, -1], data["action"][i - 1])


def test_cli_writes_a_dataset_that_loads_into_a_replay_buffer(tmp_path):
    out = tmp_path / "demos"
    subprocess.run(
        [
            sys.executable,
            "-m",
            "torchrl_auv.cli.demonstrations",
            "--env",
            "tracking",
            "--episodes",
            "2",
            "--max-steps",
            "5",
            "--out",
            str(out),
        ],
        check=True,
        capture_output=True,
        timeout=300,
    )
    buffer = load_demonstrations(out)
    assert len(buffer) == 10
    batch = buffer.sample(4)
    assert batch["action_chunk"].shape == (4, 8, 3)
    assert batch["history", "observation"].shape == (4, 10, 16)
    again = subprocess.run(
        [
            sys.executable,
            "-m",
            "torchrl_auv.cli.demonstrations",
            "--episodes",
            "1",
            "--max-steps",
            "2",
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert again.returncode != 0 and "not empty" in again.stderr  # never overwrites


def test_bad_input(tmp_path):
    with pytest.raises(ValueError, match="env"):
        collect_demonstrations("pendulum")
    with pytest.raises(ValueError, match="horizon"):
        collect_demonstrations(horizon=0)
    with pytest.raises(ValueError, match="metadata"):
        load_demonstrations(tmp_path)


def test_data_collection_samples_are_per_auv_and_chunks_stay_in_their_episode():
    data = collect_demonstrations("data_collection", episodes=2, max_steps=5, horizon=3, history=4)
    assert data.batch_size == (2 * 2 * 5,)  # scenes x AUVs x decisions
    assert data["observation"].shape == (20, 38)
    assert data["history", "observation"].shape == (20, 4, 38)
    assert data["history", "action"].shape == (20, 4, 3)
    assert sorted(set(data["agent"].tolist())) == [0, 1]
    for i in range(20):
        t = data["step"][i].item()
        for h in range(3):
            if t + h < 5:  # same scene, same AUV, h decisions later
                torch.testing.assert_close(data["action_chunk"][i, h], data["action"][i + h])
        if t > 0:
            torch.testing.assert_close(data["history", "action"][i, -1], data["action"][i - 1])


def test_overridden_decisions_are_marked_and_end_the_chunks_before_them():
    """Decisions the env overrode (station keeping in service) carry ``overridden`` (the
    env's own flag, recomputed here from the rollout), and a chunk stops at the first later
    overridden decision: it only holds actions that were executed."""
    data = collect_demonstrations(
        "data_collection",
        episodes=2,
        max_steps=150,
        horizon=8,
        history=2,
        rate_model="paper",
        seed=2,
    )
    flags = data["overridden"]
    assert flags.dtype == torch.bool and flags.any() and (~flags).any()
    rows = data.reshape(2 * 2, 150)  # [scene x AUV, decision]
    over = rows["overridden"]
    for r in range(4):
        for t in range(150):
            mask = rows["action_chunk_mask"][r, t]
            stop = next((h for h in range(1, 8) if t + h < 150 and over[r, t + h]), None)
            expected = min(8, 150 - t) if stop is None else min(stop, 150 - t)
            assert int(mask.sum()) == expected and bool(mask[: int(mask.sum())].all())


def test_chunks_never_cross_an_episode_end():
    from torchrl_auv.envs.demonstrations import _chunks

    actions = torch.arange(6.0).view(1, 6, 1).expand(1, 6, 3)
    done = torch.tensor([[False, False, True, False, False, False]])
    chunks, mask = _chunks(actions, done, 3)
    assert chunks[0, :, :, 0].tolist() == [
        [0, 1, 2],
        [1, 2, 2],
        [2, 2, 2],
        [3, 4, 5],
        [4, 5, 5],
        [5, 5, 5],
    ]
    assert mask[0].sum(-1).tolist() == [3, 2, 1, 3, 2, 1]


def test_cli_writes_a_data_collection_dataset(tmp_path):
    out = tmp_path / "demos_dc"
    subprocess.run(
        [
            sys.executable,
            "-m",
            "torchrl_auv.cli.demonstrations",
            "--env",
            "data_collection",
            "--episodes",
            "1",
            "--max-steps",
            "4",
            "--out",
            str(out),
        ],
        check=True,
        capture_output=True,
        timeout=300,
    )
    buffer = load_demonstrations(out)
    assert len(buffer) == 8  # 1 scene x 2 AUVs x 4 decisions
    batch = buffer.sample(3)
    assert batch["history", "observation"].shape == (3, 10, 38)
    assert batch["action_chunk"].shape == (3, 8, 3)


def test_another_policy_acts_and_the_expert_labels_the_states_it_visits():
    """DAgger data: the random policy's actions are executed (they are the history), the
    labels are the expert's actions at the visited observations (recomputed here)."""
    from torchrl.envs.utils import RandomPolicy

    from torchrl_auv import iout
    from torchrl_auv.envs.experts import _collection_action

    data = collect_demonstrations(
        "data_collection",
        episodes=2,
        max_steps=6,
        horizon=3,
        history=2,
        policy=lambda env: RandomPolicy(env.full_action_spec),
    )
    expert = _collection_action(data["observation"], iout.IoUTConfig(), iout.ExpertConfig())
    torch.testing.assert_close(data["action"], expert.to(data["action"].dtype))
    assert (data["executed"] - data["action"]).abs().mean() > 0.3  # random, not the expert
    rows = data.reshape(4, 6)
    torch.testing.assert_close(rows["history", "action"][:, 1:, -1], rows["executed"][:, :-1])
    torch.testing.assert_close(rows["action_chunk"][:, :4, 1], rows["action"][:, 1:5])


def test_batches_do_not_depend_on_the_number_of_workers():
    from torchrl_auv.envs.demonstrations import collect_demonstration_batches

    options = {
        "env": "data_collection",
        "episodes": 1,
        "max_steps": 4,
        "horizon": 2,
        "history": 2,
        "seed": 3,
    }
    one = collect_demonstration_batches(2, workers=1, **options)
    two = collect_demonstration_batches(2, workers=2, **options)
    assert one["batch"].tolist() == two["batch"].tolist() == [0] * 8 + [1] * 8
    torch.testing.assert_close(one["observation"], two["observation"])
    torch.testing.assert_close(one["action_chunk"], two["action_chunk"])
    assert not torch.equal(one["observation"][:8], one["observation"][8:])  # new scenes


def test_a_sampling_policys_batches_depend_on_seed_and_batch_alone():
    """A DAgger round's proposer samples its candidates from the global RNG: each batch is
    seeded by (seed, batch), so the data are the same with 1 or 2 worker processes and on a
    second run (they were not: a worker's RNG state depended on which batches it took)."""
    from functools import partial

    from torchrl_auv.envs.demonstrations import collect_demonstration_batches
    from torchrl_auv.training.first_stage.build import _dagger_policy, untrained_proposer

    torch.manual_seed(0)
    model = {
        "noise_model": "mlp",
        "hidden": 16,
        "cond_dim": 8,
        "depth": 1,
        "schedule": "linear",
        "num_train_steps": 50,
    }
    proposer = untrained_proposer(38, 3, history=2, horizon=2, model=model)
    proposer.configure_sampling(num_inference_steps=2, sampler="ddim")
    options = {
        "env": "data_collection",
        "episodes": 1,
        "max_steps": 6,
        "horizon": 2,
        "history": 2,
        "seed": 3,
        "policy": partial(_dagger_policy, proposer),
    }
    runs = [collect_demonstration_batches(2, workers=w, **options) for w in (1, 2, 2)]
    for other in runs[1:]:
        torch.testing.assert_close(runs[0]["executed"], other["executed"], rtol=0, atol=0)
    assert not torch.equal(runs[0]["executed"][:12], runs[0]["executed"][12:])  # new scenes


def _spawned_children(parent: int) -> list[int]:
    """The ``multiprocessing`` spawn workers whose parent is ``parent`` (Linux ``/proc``)."""
    from pathlib import Path

    children = []
    for proc in Path("/proc").iterdir():
        try:
            stat = (proc / "stat").read_text()
            cmdline = (proc / "cmdline").read_bytes()
        except (OSError, ValueError):
            continue
        if int(stat.rsplit(")", 1)[1].split()[1]) == parent and b"spawn_main" in cmdline:
            children.append(int(proc.name))
    return children


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_collection_workers_end_when_their_parent_is_killed():
    """kill -9 of a process collecting demonstrations on two workers (a first-stage build)
    leaves no worker behind (they used to collect on as orphans), also when the workers were
    still starting."""
    import os
    import signal
    import time

    script = (
        "from torchrl_auv.envs.demonstrations import collect_demonstration_batches\n"
        "if __name__ == '__main__':\n"
        "    collect_demonstration_batches(2, workers=2, env='data_collection', episodes=2,\n"
        "                                  max_steps=100000, horizon=2, history=2)\n"
    )
    parent = subprocess.Popen(
        [sys.executable, "-c", script], env={**os.environ, "OMP_NUM_THREADS": "1"}
    )
    deadline = time.monotonic() + 120
    workers: list[int] = []
    while len(workers) < 2 and time.monotonic() < deadline:  # killed as soon as they exist,
        time.sleep(0.05)  # while they still import torch: before their initializer has run
        workers = _spawned_children(parent.pid)
    try:
        assert len(workers) == 2, f"expected 2 collection workers, found {workers}"
    finally:
        parent.send_signal(signal.SIGKILL)
        parent.wait()
    deadline = time.monotonic() + 60  # a worker still importing torch on a loaded machine
    while time.monotonic() < deadline:
        alive = []
        for worker in workers:
            try:
                os.kill(worker, 0)
                alive.append(worker)
            except ProcessLookupError:
                pass
        if not alive:
            return
        time.sleep(0.2)
    for worker in alive:
        os.kill(worker, signal.SIGKILL)
    raise AssertionError(f"workers {alive} outlived their killed parent by 60 s")
