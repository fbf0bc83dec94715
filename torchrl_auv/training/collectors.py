"""Collection by config alone: one process, N worker processes, or remote collectors on Ray.

======================================  ===================================================
``backend``, ``num_workers``            TorchRL collector
======================================  ===================================================
``"local"``, 1                          ``Collector`` in this process
``"local"``, N > 1                      ``MultiSyncCollector``: N worker processes (spawned)
``"ray"``, N                            ``RayCollector``: N remote ``Collector`` actors on a
                                        Ray cluster (``sync=True``), the learner here
======================================  ===================================================

Every worker builds its own env from a picklable factory; worker ``i`` is seeded ``seed + i``
(worker 0 sees the scenes of the single-process run). ``frames_per_batch`` is the batch over
all workers and must split into whole env steps of every worker. A batch always comes back as
``[scenes, time]`` (the workers' scenes one after the other), whatever the backend, so the
recipes' code after collection does not change. After each round of updates a recipe calls
``collector.update_policy_weights_()``: the workers act with the new weights (buffers
included: the Lyapunov form a selector uses travels with them).

Ray is an optional extra (``pip install torch==2.13.0 -e .[ray]``) imported only here, only
for ``backend="ray"``. The cluster: ``ray_address`` (``"auto"``, ``"host:port"``,
``"ray://host:port"``), else the ``RAY_ADDRESS`` environment variable, else a local Ray
instance started with ``num_workers`` CPUs. A ``host:port`` that does not answer is refused
within seconds, naming it (:func:`check_ray_address`).

Examples:
    >>> from functools import partial
    >>> from torchrl_auv.training import make_actor, make_env
    >>> create = partial(make_env, "ideal", num_envs=2, max_steps=50)
    >>> env = create(seed=0)
    >>> collector = make_collector(create, make_actor(env, hidden=(16,)), seed=0,
    ...                            frames_per_batch=20, total_frames=40)
    >>> [data.batch_size for data in collector]
    [torch.Size([2, 10]), torch.Size([2, 10])]
    >>> collector.shutdown()
"""

from __future__ import annotations

import importlib.util
import os
import socket
from collections.abc import Callable, Mapping
from functools import partial

import torch
from tensordict import TensorDictBase
from torchrl.collectors import Collector, MultiSyncCollector
from torchrl.envs import EnvBase

from torchrl_auv.training.env import env_factory

__all__ = [
    "COLLECTOR_BACKENDS",
    "check_ray_address",
    "check_ray_backend",
    "collector_from_config",
    "make_collector",
    "ray_init_config",
]

#: Collection backends: this machine (1 process or ``num_workers`` processes) or Ray.
COLLECTOR_BACKENDS = ("local", "ray")


def _merge_workers(data: TensorDictBase) -> TensorDictBase:
    """``[workers, scenes, time]`` -> ``[workers * scenes, time]`` (a no-op on 2-D batches)."""
    return data.reshape(-1, data.shape[-1]) if data.ndim > 2 else data


def check_ray_address(
    address: str, *, key: str = "collector.ray_address", timeout_s: float = 5.0
) -> None:
    """Raise ``ValueError`` naming ``key`` and ``address`` when a ``host:port`` (or
    ``ray://host:port``) Ray address does not accept a TCP connection within ``timeout_s``;
    ``"auto"`` and ``"local"`` are left to Ray.

    Examples:
        >>> check_ray_address("127.0.0.1:1")
        Traceback (most recent call last):
        ...
        ValueError: collector.ray_address '127.0.0.1:1' is unreachable (...); ...
    """
    if address in ("auto", "local"):
        return
    hostport = address.split("://", 1)[-1]
    host, sep, port = hostport.rpartition(":")
    if not sep or not port.isdigit() or not host:
        raise ValueError(
            f"{key} must be 'auto', 'local', 'host:port' or 'ray://host:port', got {address!r}"
        )
    try:
        socket.create_connection((host, int(port)), timeout=timeout_s).close()
    except OSError as error:
        raise ValueError(
            f"{key} {address!r} is unreachable ({error}); "
            f"start a cluster with `ray start --head` or fix the address"
        ) from error


def check_ray_backend(address: str | None = None) -> str | None:
    """Fail fast before a Ray run: Ray must be installed and the cluster's address (``address``,
    else ``RAY_ADDRESS``) reachable. Returns that address (``None``: a local instance)."""
    if importlib.util.find_spec("ray") is None:
        raise ImportError(
            "collector.backend='ray' needs Ray: pip install torch==2.13.0 -e '.[ray]'"
        )
    address = address or os.environ.get("RAY_ADDRESS") or None
    if address and address != "local":
        check_ray_address(address)
        return address
    return None


def ray_init_config(address: str | None, num_cpus: int) -> dict:
    """``ray.init`` keyword arguments: connect to ``address`` (else ``RAY_ADDRESS``), or start
    a local instance with ``num_cpus`` CPUs; workers' output stays in Ray's logs."""
    address = check_ray_backend(address)
    if address:
        return {"address": address, "log_to_driver": False}
    return {"num_cpus": num_cpus, "include_dashboard": False, "log_to_driver": False}


def make_collector(
    create_env: EnvBase | Callable[..., EnvBase],
    policy,
    *,
    frames_per_batch: int,
    total_frames: int,
    seed: int | None = None,
    init_random_frames: int = 0,
    device: str | torch.device = "cpu",
    num_workers: int = 1,
    backend: str = "local",
    ray_address: str | None = None,
):
    """A TorchRL collector for ``backend`` and ``num_workers`` (module docstring).

    Args:
        create_env: an env (``backend="local"`` with one worker only) or a picklable factory
            called as ``create_env(seed=...)`` (a ``functools.partial`` of
            :func:`~torchrl_auv.training.make_env`, say).
        policy: the acting policy; its weights are copied to the workers.
        frames_per_batch: frames per collected batch over all workers (a frame is one decision
            of one scene, every AUV included).
        total_frames: frames to collect.
        seed: worker ``i`` builds its env with ``seed + i`` (required with a factory).
        init_random_frames: frames of random actions first.
        device: where the policy acts.
        num_workers: worker processes (``"local"``) or remote collectors (``"ray"``).
        backend: ``"local"`` or ``"ray"``.
        ray_address: the Ray cluster (``"ray"`` only; default ``RAY_ADDRESS`` or a local one).
    """
    if backend not in COLLECTOR_BACKENDS:
        raise ValueError(
            f"collector.backend must be one of {list(COLLECTOR_BACKENDS)}, got {backend!r}"
        )
    if not isinstance(num_workers, int) or num_workers < 1:
        raise ValueError(f"collector.num_workers must be an integer >= 1, got {num_workers!r}")
    if isinstance(create_env, EnvBase):
        if backend != "local" or num_workers != 1:
            raise ValueError(
                "create_env must be an env factory (e.g. functools.partial of "
                "make_env) for worker processes or Ray, got an env instance"
            )
        env, factories = create_env, None
    else:
        if seed is None:
            raise ValueError("seed is required with an env factory (worker i uses seed + i)")
        factories = [partial(create_env, seed=seed + i) for i in range(num_workers)]
        env = factories[0]() if backend == "local" and num_workers == 1 else None
    scenes = (env if env is not None else factories[0]()).batch_size.numel()
    step = scenes * num_workers
    if frames_per_batch < step or frames_per_batch % step:
        raise ValueError(
            f"collector.frames_per_batch must be a positive multiple of "
            f"{num_workers} worker(s) x {scenes} scenes = {step}, "
            f"got {frames_per_batch}"
        )
    # our policies hold no recurrent state: nothing to append to the env (torchrl 0.14.1
    # otherwise warns that an InitTracker is missing, for any policy)
    common = dict(
        frames_per_batch=frames_per_batch,
        total_frames=total_frames,
        init_random_frames=init_random_frames,
    )
    if env is not None:
        return Collector(
            env, policy, device=device, auto_register_policy_transforms=False, **common
        )
    if backend == "local":
        return MultiSyncCollector(
            factories,
            policy,
            device=device,
            postproc=_merge_workers,
            auto_register_policy_transforms=False,
            **common,
        )
    from torchrl.collectors.distributed import RayCollector

    collector = RayCollector(
        factories,
        policy,
        sync=True,
        device=device,
        postproc=_merge_workers,
        ray_init_config=ray_init_config(ray_address, num_workers),
        remote_configs={"num_cpus": 1},
        collector_class=Collector,
        collector_kwargs={"auto_register_policy_transforms": False},
        **common,
    )
    collector.update_policy_weights_(policy)  # the workers start from the learner's weights
    return collector


def collector_from_config(
    cfg: Mapping,
    policy,
    *,
    env=None,
    total_frames: int | None = None,
    init_random_frames: int = 0,
):
    """The collector of ``cfg.collector`` (:func:`make_collector`): ``env`` itself with one
    local worker, else fresh envs of ``cfg.env`` in every worker
    (:func:`~torchrl_auv.training.env_factory`, worker ``i`` seeded ``cfg.seed + i``).
    ``total_frames`` defaults to ``cfg.collector.total_frames``; ``init_random_frames`` are
    the random frames still to go."""
    col = cfg["collector"]
    single = col["backend"] == "local" and col["num_workers"] == 1
    create = env if single and env is not None else env_factory(cfg)
    return make_collector(
        create,
        policy,
        seed=cfg["seed"],
        frames_per_batch=col["frames_per_batch"],
        total_frames=col["total_frames"] if total_frames is None else total_frames,
        init_random_frames=init_random_frames,
        device=cfg["device"],
        num_workers=col["num_workers"],
        backend=col["backend"],
        ray_address=col.get("ray_address"),
    )
