"""Evaluation rows in worker processes: one row (a policy in a sea state) per job.

A row's numbers depend only on its scenes (``make_env(sea_state, seed)``), its policy and the
seed, so rows can be evaluated side by side: :func:`evaluate_rows` runs them on ``workers``
``spawn`` processes (each with ``torch.get_num_threads()`` of the parent's threads) and
returns them in the order given, the same numbers as one after another (a test compares
them). A worker compiles what the rows compile (``env.compile_physics``, the proposer's
denoising step) once and keeps it for its next rows, and ends itself within a second of its
parent's death (a ``kill -9`` of the training process leaves no worker behind).

Everything a job holds is pickled into the worker: ``make_env`` and each row's policy must be
picklable (a module, or ``functools.partial`` of a module-level function; not a lambda or a
nested function); one that is not is named before any work.
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
import time
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

import torch
from torchrl.envs.utils import ExplorationType, set_exploration_type

from torchrl_auv.envs.processes import end_with_parent
from torchrl_auv.evaluation.episodes import episode_stats

__all__ = ["RowWorker", "evaluate_row", "evaluate_rows"]

_TICKS = None  # a worker's shared decision counter (set by _start_worker)


def evaluate_row(
    make_env,
    build,
    sea_state: str,
    name: str,
    *,
    seed: int,
    steps: int,
    tick: Callable | None = None,
    transition_stats: Callable | None = None,
) -> dict:
    """One row: ``build`` (a policy module, or ``env -> policy``) on ``make_env(sea_state,
    seed)`` rolled out for ``steps`` decisions with
    deterministic actions, torch's global generator seeded with ``seed`` (forked: restored
    after), ``tick()`` after every decision; ``transition_stats``:
    :func:`~torchrl_auv.evaluation.episode_stats`'."""
    env = make_env(sea_state, seed)
    policy = build if isinstance(build, torch.nn.Module) else build(env)
    with (
        set_exploration_type(ExplorationType.DETERMINISTIC),
        torch.no_grad(),
        torch.random.fork_rng(),
    ):
        torch.manual_seed(seed)  # random actions and proposals: seeded too
        stats = episode_stats(
            env,
            policy,
            steps,
            callback=None if tick is None else lambda *_: tick(),
            transition_stats=transition_stats,
        )
    return {"sea_state": sea_state, "policy": name, **stats}


def _start_worker(threads: int, ticks, parent: int) -> None:
    global _TICKS
    torch.set_num_threads(threads)
    _TICKS = ticks
    end_with_parent(parent)  # a kill -9 of the training process leaves no worker behind


def _tick() -> None:
    with _TICKS.get_lock():
        _TICKS.value += 1


def _dumps(what: str, obj) -> bytes:
    """``obj`` pickled once, for a worker; one that cannot be is named."""
    try:
        return pickle.dumps(obj)
    except Exception as error:
        raise ValueError(
            f"workers > 1 evaluates rows in worker processes, which needs {what} to be "
            f"picklable (functools.partial of a module-level function, not a lambda): {error}"
        ) from error


def _pickled_row(
    make_env,
    policy_bytes: bytes,
    sea_state: str,
    name: str,
    seed: int,
    steps: int,
    transition_stats: Callable | None = None,
) -> tuple[dict, float]:
    """In a worker: one row of a pickled policy and the seconds it took; with a shared
    counter (:func:`evaluate_rows`), every decision counted."""
    began, tick = time.perf_counter(), None if _TICKS is None else _tick
    row = evaluate_row(
        make_env,
        pickle.loads(policy_bytes),
        sea_state,
        name,
        seed=seed,
        steps=steps,
        tick=tick,
        transition_stats=transition_stats,
    )
    if tick is not None:
        tick()  # the rollout's callback skips the last decision
    return row, time.perf_counter() - began


def evaluate_rows(
    make_env,
    jobs: Sequence[tuple],
    *,
    seed: int,
    steps: int,
    workers: int,
    bar=None,
    transition_stats: Callable | None = None,
) -> list[dict]:
    """``jobs``: ``(sea_state, name, build)``; the rows in that order (module docstring).
    ``bar``: a tqdm bar advanced by every decision of every row; ``transition_stats``: every
    row's (:func:`~torchrl_auv.evaluation.episode_stats`; picklable for ``workers > 1``)."""
    if workers == 1 or len(jobs) <= 1:
        rows = []
        for sea_state, name, build in jobs:
            if bar is not None:
                bar.set_postfix_str(f"{sea_state} {name}")
            tick = None if bar is None else lambda: bar.update()
            rows.append(
                evaluate_row(
                    make_env,
                    build,
                    sea_state,
                    name,
                    seed=seed,
                    steps=steps,
                    tick=tick,
                    transition_stats=transition_stats,
                )
            )
            if bar is not None:
                bar.update(len(rows) * steps - bar.n)  # the callback skips the last decision
        return rows
    _dumps("make_env", make_env)
    _dumps("transition_stats", transition_stats)
    pickled = {name: _dumps(f"the policy of row {name!r}", build) for _, name, build in jobs}
    context = multiprocessing.get_context("spawn")
    ticks = context.Value("q", 0)
    start = (torch.get_num_threads(), ticks, os.getpid())
    with ProcessPoolExecutor(
        min(workers, len(jobs)), mp_context=context, initializer=_start_worker, initargs=start
    ) as pool:
        futures = [
            pool.submit(
                _pickled_row,
                make_env,
                pickled[name],
                sea_state,
                name,
                seed,
                steps,
                transition_stats,
            )
            for sea_state, name, _ in jobs
        ]
        pending = set(futures)
        while pending:
            done, pending = wait(pending, timeout=0.5, return_when=FIRST_COMPLETED)
            failed = [future for future in done if future.exception() is not None]
            if failed:  # the first failure ends the evaluation; rows not started are dropped
                pool.shutdown(wait=False, cancel_futures=True)
                raise failed[0].exception()
            if bar is not None:
                bar.set_postfix_str(
                    f"{len(jobs) - len(pending)}/{len(jobs)} rows, {workers} workers"
                )
                bar.update(ticks.value - bar.n)
        return [future.result()[0] for future in futures]


class RowWorker:
    """One ``spawn`` worker process that evaluates rows while the caller goes on (e.g. a
    learning curve's points while training continues on the other core). :meth:`submit`
    pickles the policy at once, so the row evaluates the weights of that moment whatever
    training does next; :meth:`results` hands back finished rows in the order submitted.

    Args:
        make_env: ``(sea_state, seed) -> env``, picklable (e.g.
            :func:`~torchrl_auv.training.held_out_env`).
        sea_state, seed, steps: the rows' scenes and length.
    """

    def __init__(self, make_env, sea_state: str, *, seed: int, steps: int) -> None:
        _dumps("make_env", make_env)
        context = multiprocessing.get_context("spawn")
        threads, parent = torch.get_num_threads(), os.getpid()
        self.pool = ProcessPoolExecutor(
            1, mp_context=context, initializer=_start_worker, initargs=(threads, None, parent)
        )
        self.job = (make_env, sea_state, seed, steps)
        self.pending: list[tuple[int, object]] = []

    def submit(self, step: int, policy) -> None:
        """Evaluate ``policy`` as it is now, labelled ``step``."""
        make_env, sea_state, seed, steps = self.job
        self.pending.append(
            (
                step,
                self.pool.submit(
                    _pickled_row,
                    make_env,
                    _dumps("the policy", policy),
                    sea_state,
                    "policy",
                    seed,
                    steps,
                ),
            )
        )

    def results(self, wait: bool = False) -> list[tuple[int, dict, float]]:
        """``(step, row, seconds)`` of the rows finished so far (``wait``: of every row
        submitted), oldest first; a row that failed raises here."""
        out = []
        while self.pending and (wait or self.pending[0][1].done()):
            step, future = self.pending.pop(0)
            out.append((step, *future.result()))
        return out

    def close(self) -> None:
        """Stop the worker (rows still pending are dropped)."""
        self.pool.shutdown(wait=False, cancel_futures=True)
