"""torchrl_auv.training.make_collector: one process, worker processes and Ray remote collectors
give the same batches' layout and frame count, seed each worker apart, and act with the
learner's latest weights (buffers included); bad input is named."""

from __future__ import annotations

import time
from functools import partial

import pytest
import torch
from tensordict.nn import TensorDictModule
from torch import nn

from torchrl_auv.training import check_ray_address, make_collector, make_env

OBS, ACTION = ("agents", "observation"), ("agents", "action")
SCENES = 2
create = partial(make_env, "ideal", num_envs=SCENES, max_steps=50)


class BufferAction(nn.Module):
    """Acts with the value of a buffer for every AUV: which weights a worker holds is visible
    in the actions it collected (the selector's Lyapunov form travels as a buffer too)."""

    def __init__(self) -> None:
        super().__init__()
        self.register_buffer("value", torch.zeros(3))

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        return self.value.expand(*observation.shape[:-1], 3).clone()


def _policy() -> TensorDictModule:
    return TensorDictModule(BufferAction(), in_keys=[OBS], out_keys=[ACTION])


def _collect_twice(backend: str, num_workers: int):
    policy = _policy()
    collector = make_collector(
        create,
        policy,
        seed=7,
        frames_per_batch=20,
        total_frames=40,
        num_workers=num_workers,
        backend=backend,
    )
    batches = []
    try:
        for data in collector:
            batches.append(data)
            with torch.no_grad():
                policy.module.value.fill_(0.5)  # a "gradient step"
            collector.update_policy_weights_()
    finally:
        collector.shutdown()
    return batches


def _check(batches, num_workers: int) -> None:
    assert len(batches) == 2 and sum(b.numel() for b in batches) == 40
    scenes = SCENES * num_workers
    assert all(b.batch_size == torch.Size([scenes, 20 // scenes]) for b in batches)
    # the first batch acted with the initial weights, the second with the updated ones
    assert torch.all(batches[0][ACTION] == 0.0) and torch.all(batches[1][ACTION] == 0.5)
    # worker i's scenes are those of an env seeded 7 + i
    for worker in range(num_workers):
        first = batches[0][worker * SCENES : (worker + 1) * SCENES, 0]
        torch.testing.assert_close(first[OBS], create(seed=7 + worker).reset()[OBS])


def test_one_local_worker_is_torchrls_collector_on_the_seeded_env():
    _check(_collect_twice("local", 1), 1)


def test_two_worker_processes_collect_the_same_frames_with_their_own_seeds():
    _check(_collect_twice("local", 2), 2)


def test_two_ray_remote_collectors_collect_the_same_frames_with_their_own_seeds(
    monkeypatch, skip_if_ray_started_too_slowly
):
    ray = pytest.importorskip("ray")
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    try:
        frames = _collect_twice("ray", 2)  # a local Ray instance with 2 CPUs
    except Exception as error:
        skip_if_ray_started_too_slowly(f"{type(error).__name__}: {error}")
        raise
    finally:
        ray.shutdown()
    _check(frames, 2)


@pytest.mark.parametrize(
    ("kwargs", "named"),
    [
        ({"backend": "slurm"}, "collector.backend"),
        ({"num_workers": 0}, "collector.num_workers"),
        ({"frames_per_batch": 30, "num_workers": 2}, "collector.frames_per_batch"),
        ({"seed": None}, "seed"),
    ],
)
def test_bad_collector_arguments_are_named(kwargs, named):
    args = {"seed": 0, "frames_per_batch": 20, "total_frames": 20, **kwargs}
    with pytest.raises(ValueError, match=named):
        make_collector(create, _policy(), **args)


def test_an_env_instance_cannot_be_sent_to_workers():
    with pytest.raises(ValueError, match="create_env must be an env factory"):
        make_collector(
            create(seed=0), _policy(), frames_per_batch=20, total_frames=20, num_workers=2
        )


def test_an_unreachable_ray_address_is_refused_within_seconds_naming_it():
    start = time.perf_counter()
    with pytest.raises(ValueError, match=r"collector.ray_address '127\.0\.0\.1:9' is unreachable"):
        check_ray_address("127.0.0.1:9")
    assert time.perf_counter() - start < 10.0
    with pytest.raises(ValueError, match=r"collector\.ray_address must be"):
        check_ray_address("my-cluster")


def test_only_rays_slow_start_is_skipped(skip_if_ray_started_too_slowly):
    skip_if_ray_started_too_slowly("ValueError: collector.num_workers must be ...")  # returns
    with pytest.raises(pytest.skip.Exception, match="60 s weight-sync"):
        skip_if_ray_started_too_slowly(
            "torch.distributed.DistStoreError: Timed out after 61 seconds waiting for clients"
        )
