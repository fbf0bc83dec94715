"""Held-out evaluation: every policy in every sea state on the same scenes, deterministic
actions, one row each (:func:`~torchrl_auv.evaluation.episode_stats`), in this process or in
worker processes (:mod:`~torchrl_auv.evaluation.pool`).

Examples:
    >>> from torchrl_auv.envs import DataCollectionEnv
    >>> from torchrl_auv.evaluation import reference_policies
    >>> def make_env(sea_state, seed):
    ...     return DataCollectionEnv(batch_size=[1], sea_state=sea_state, seed=seed, max_steps=4)
    >>> rows = evaluate(make_env, {**reference_policies(), "also idle": SameRowAs("idle")},
    ...                 ["ideal"], seed=100, steps=4)
    >>> [row["policy"] for row in rows]
    ['expert', 'idle', 'random', 'also idle']
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

from torchrl_auv.envs import DataCollectionEnv
from torchrl_auv.evaluation.pool import evaluate_rows

__all__ = ["SameRowAs", "evaluate"]


@dataclass(frozen=True)
class SameRowAs:
    """A row that is another row of the same evaluation by construction, copied from it
    instead of evaluated again: e.g. ``OA`` (rank 0 of the selector's ranking executed alone)
    is the framework's own choice when the actor's action does not compete."""

    name: str


def evaluate(
    make_env: Callable[[str, int], DataCollectionEnv],
    policies: Mapping[str, Callable[[DataCollectionEnv], object] | SameRowAs],
    sea_states: Sequence[str],
    *,
    seed: int,
    steps: int,
    progress: bool = False,
    workers: int = 1,
    transition_stats=None,
) -> list[dict]:
    """Every policy in every sea state on the same held-out scenes, deterministic actions.

    Args:
        make_env: ``(sea_state, seed) -> env``; called anew per policy so every policy sees
            the same scenes.
        policies: name -> a policy (a module, e.g. a trained actor), ``env -> policy`` (a
            policy built on the row's env, or ``None`` for random actions), or
            :class:`SameRowAs` another name (its row copied); e.g. ``{"trained": actor,
            **reference_policies()}``.
        sea_states: presets to evaluate in.
        seed: the evaluation seed (keep it apart from the training seeds): the scenes' and,
            through torch's global generator (forked, restored after), the random actions'
            and the proposer's samples.
        steps: decisions per episode.
        progress: show a progress bar (decisions of every row, the row being evaluated).
        workers: rows evaluated side by side in this many worker processes (the same
            numbers; ``make_env`` and the policies must then be picklable, see
            :mod:`~torchrl_auv.evaluation.pool`).
        transition_stats: more values of every row from its rollout
            (:func:`~torchrl_auv.evaluation.episode_stats`; e.g. a
            :class:`~torchrl_auv.evaluation.LyapunovCertificate`).

    Returns:
        one row per (sea state, policy): ``{"sea_state", "policy", **episode_stats}``.
    """
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be an int >= 1, got {workers!r}")
    evaluated = [name for name, build in policies.items() if not isinstance(build, SameRowAs)]
    for name, build in policies.items():
        if isinstance(build, SameRowAs) and build.name not in evaluated:
            raise ValueError(
                f"policies[{name!r}] is the row of {build.name!r}, which is not "
                f"an evaluated row of policies (those are {evaluated})"
            )
    jobs = [
        (sea, name, build)
        for sea in sea_states
        for name, build in policies.items()
        if not isinstance(build, SameRowAs)
    ]
    bar = contextlib.nullcontext()
    if progress:  # tqdm: a dependency of the recipes, not of the library
        import tqdm

        bar = tqdm.tqdm(total=len(jobs) * steps, unit="decision", desc="evaluation")
    with bar as shown:
        rows = evaluate_rows(
            make_env,
            jobs,
            seed=seed,
            steps=steps,
            workers=workers,
            bar=shown,
            transition_stats=transition_stats,
        )
    found = {(row["sea_state"], row["policy"]): row for row in rows}
    return [
        found[sea, name]
        if not isinstance(build, SameRowAs)
        else {**found[sea, build.name], "policy": name}
        for sea in sea_states
        for name, build in policies.items()
    ]
