"""Evaluation on the data-collection task: roll a policy out and summarise its episodes.

:func:`episode_stats` rolls a policy out in :class:`~torchrl_auv.envs.DataCollectionEnv` for one
episode per scene and returns the numbers the task is judged by (per scene, then averaged):
the paper's metrics (SDR in Mbit, SSN, EC), tracking (heading and depth error mean and std over
the moving decisions), safety (violations per AUV-decision, collisions, terminated episodes),
station keeping (services that end within the service radius), the localisation (the filter's
and the raw USBL fixes' position error), the cost (mean per AUV-decision, the share of each
term, the discounted cost from reset for given discounts). :func:`evaluate` runs it for a
trained policy and the reference policies on the same held-out seeds.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import torch
import tqdm
from tensordict import TensorDictBase

from torchrl_auv import iout
from torchrl_auv.envs import SIM_KEY, DataCollectionEnv, IdlePolicy, LazyExpert, ScriptedExpert
from torchrl_auv.training.evaluation_pool import evaluate_rows

__all__ = [
    "POLICIES",
    "SameRowAs",
    "episode_stats",
    "evaluate",
    "exit_policy",
    "expert_policy",
    "idle_policy",
    "lazy_policy",
    "make_policy",
    "random_policy",
    "reference_policies",
]

POLICIES = ("expert", "lazy", "idle", "random", "exit")
#: the per-scene metrics whose standard error over scenes a row carries as ``<name>_se``
SE_METRICS = ("sdr_mbit", "ssn", "violation_rate", "cost_mean")
TRACKING_METRICS = (
    "heading_error_mean",
    "heading_error_std",
    "depth_error_mean",
    "depth_error_std",
)


def exit_policy(env: DataCollectionEnv) -> Callable[[TensorDictBase], TensorDictBase]:
    """Straight out at full speed: hold depth and heading, 1520 rpm (the cheapest way to end an
    episode early, which the termination cost must make expensive)."""

    def act(td: TensorDictBase) -> TensorDictBase:
        shape = (*td.batch_size, env.num_auvs, 3)
        action = torch.zeros(shape, device=env.device)
        action[..., 2] = 1.0
        td.set(env.agent_action_key, action.flatten(-2) if env.flatten_agents else action)
        return td

    return act


def make_policy(name: str, env: DataCollectionEnv):
    """A reference policy by name (:data:`POLICIES`): ``expert``
    (:class:`~torchrl_auv.envs.ScriptedExpert`), ``lazy`` (:class:`~torchrl_auv.envs.LazyExpert`),
    ``idle`` (:class:`~torchrl_auv.envs.IdlePolicy`), ``random`` (uniform actions; ``None`` for
    ``env.rollout``) or ``exit`` (:func:`exit_policy`)."""
    if name not in POLICIES:
        raise ValueError(f"policy must be one of {POLICIES}, got {name!r}")
    return {
        "expert": expert_policy,
        "lazy": lazy_policy,
        "idle": idle_policy,
        "random": random_policy,
        "exit": exit_policy,
    }[name](env)


def _first_episode(rollout: TensorDictBase) -> tuple[torch.Tensor, torch.Tensor]:
    """Per scene: the index of the first ``done`` step (the last step if none) and the mask
    ``[B, T]`` of the steps of that first episode."""
    done = rollout["next", "done"][..., 0]
    steps = torch.arange(done.shape[-1])
    first = torch.where(done, steps, done.shape[-1] - 1).amin(-1)
    return first, steps[None, :] <= first[:, None]


def episode_stats(
    env: DataCollectionEnv,
    policy,
    steps: int,
    *,
    gammas: Sequence[float] = (0.97, 0.99),
    callback: Callable | None = None,
) -> dict[str, float]:
    """Roll ``policy`` out for ``steps`` decisions (one episode per scene, or its first
    ``steps`` decisions) and summarise it (module docstring). Values are means over scenes;
    ``kf_error_p95`` is the 95th percentile over every AUV-decision; ``<metric>_se`` the
    standard error over scenes of :data:`SE_METRICS` and the discounted costs (cost per AUV
    from reset, the AUVs' mean). ``callback(env, td)`` is
    called after every decision (``EnvBase.rollout``'s), e.g. to advance a progress bar."""
    rollout = env.rollout(steps, policy, break_when_any_done=False, callback=callback)
    rollout = rollout.cpu()  # an env on a GPU (device=cuda): the statistics on the CPU
    first, mask = _first_episode(rollout)
    scenes = torch.arange(rollout.batch_size[0])
    at_end = rollout["next"][scenes, first]
    metrics = at_end["metrics"]
    n = env.num_auvs
    decisions = (first + 1).double()
    sim = rollout["next", SIM_KEY]
    truth = sim["truth", "eta"][..., :3]
    kf_error = torch.linalg.vector_norm(sim["kf", "mean"][..., :3] - truth, dim=-1)
    kf_error = kf_error[mask[..., None].expand_as(kf_error) & kf_error.isfinite()]
    cost = rollout["next", "agents", "cost"][..., 0].double()  # [B, T, N]
    cost = torch.where(mask[..., None], cost, 0.0)
    terms = rollout["next", "cost_terms"]
    term_totals = {
        k: torch.where(mask[..., None], terms[k].double(), 0.0).sum() for k in iout.COST_TERMS
    }
    total = sum(term_totals.values())
    per_scene = {  # [B] each: their means are the row's values, their standard errors `_se`
        "sdr_mbit": metrics["sdr"].double(),
        "ssn": metrics["ssn"].double(),
        "violation_rate": metrics["violations"].double() / (n * decisions),
        "terminated": at_end["terminated"][:, 0].double(),
        "cost_mean": cost.sum((-2, -1)) / (n * decisions),
    }
    for gamma in gammas:
        discount = gamma ** torch.arange(cost.shape[1], dtype=torch.float64)
        per_scene[f"discounted_cost_{gamma}"] = (cost * discount[:, None]).sum((1, 2)) / n
    out = {
        **{k: v.mean().item() for k, v in per_scene.items() if k != "cost_mean"},
        "ec_w": metrics["ec"].double().mean().item(),
        "collisions": metrics["collisions"].double().mean().item(),
        "decisions": decisions.mean().item(),
        "service_end_inside": (
            metrics["services_inside"].sum() / metrics["ssn"].sum().clamp_min(1)
        ).item(),
        **{k: metrics[k].double().mean().item() for k in TRACKING_METRICS},
        "kf_error_mean": kf_error.double().mean().item(),
        "kf_error_p95": kf_error.double().quantile(0.95).item(),
        "usbl_error_mean": metrics["usbl_position_error"].double().mean().item(),
        "cost_mean": per_scene["cost_mean"].mean().item(),
        **{f"share_{k}": (v / total).item() for k, v in term_totals.items()},
    }
    for key in SE_METRICS:
        if key in per_scene:
            out[f"{key}_se"] = _standard_error(per_scene[key])
    for gamma in gammas:
        out[f"discounted_cost_{gamma}_se"] = _standard_error(per_scene[f"discounted_cost_{gamma}"])
    return out


def _standard_error(values: torch.Tensor) -> float:
    """Standard error of the mean over scenes (sample std / sqrt(B); 0 for one scene)."""
    if values.numel() < 2:
        return 0.0
    return (values.std() / values.numel() ** 0.5).item()


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
            :mod:`~torchrl_auv.training.evaluation_pool`).

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
    bar = tqdm.tqdm(
        total=len(jobs) * steps, unit="decision", desc="evaluation", disable=not progress
    )
    with bar:
        rows = evaluate_rows(make_env, jobs, seed=seed, steps=steps, workers=workers, bar=bar)
    found = {(row["sea_state"], row["policy"]): row for row in rows}
    return [
        found[sea, name]
        if not isinstance(build, SameRowAs)
        else {**found[sea, build.name], "policy": name}
        for sea in sea_states
        for name, build in policies.items()
    ]


def expert_policy(env: DataCollectionEnv) -> ScriptedExpert:
    """The scripted expert of ``env`` (of its base env when wrapped)."""
    return ScriptedExpert(getattr(env, "base_env", env))


def lazy_policy(env: DataCollectionEnv) -> LazyExpert:
    """The lazy expert of ``env`` (half the time at rest, :class:`~torchrl_auv.envs.LazyExpert`)."""
    return LazyExpert(env)


def idle_policy(env: DataCollectionEnv) -> IdlePolicy:
    """The idle policy of ``env`` (safe, serves no node, :class:`~torchrl_auv.envs.IdlePolicy`)."""
    return IdlePolicy(env)


def random_policy(env: DataCollectionEnv) -> None:
    """Uniform random actions (``None``: ``env.rollout``'s own)."""
    return None


def reference_policies() -> dict[str, Callable[[DataCollectionEnv], object]]:
    """The reference rows of every evaluation: the scripted expert, the idle policy (the
    cost of serving nothing) and random actions."""
    return {"expert": expert_policy, "idle": idle_policy, "random": random_policy}
