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

import torch
import tqdm
from tensordict import TensorDictBase
from torchrl.envs.utils import ExplorationType, set_exploration_type

from torchrl_auv import iout
from torchrl_auv.envs import SIM_KEY, DataCollectionEnv, ScriptedExpert

__all__ = [
    "POLICIES",
    "episode_stats",
    "evaluate",
    "exit_policy",
    "make_policy",
    "reference_policies",
]

POLICIES = ("expert", "random", "exit")
TRACKING_METRICS = ("heading_error_mean", "heading_error_std", "depth_error_mean",
                    "depth_error_std")  # fmt: skip


def exit_policy(env: DataCollectionEnv) -> Callable[[TensorDictBase], TensorDictBase]:
    """Straight out at full speed: hold depth and heading, 1520 rpm (the cheapest way to end an
    episode early, which the termination cost must make expensive)."""

    def act(td: TensorDictBase) -> TensorDictBase:
        shape = (*td.batch_size, env.num_auvs, 3)
        action = torch.zeros(shape)
        action[..., 2] = 1.0
        td.set(env.agent_action_key, action.flatten(-2) if env.flatten_agents else action)
        return td

    return act


def make_policy(name: str, env: DataCollectionEnv):
    """``expert`` (:class:`~torchrl_auv.envs.ScriptedExpert`), ``random`` (uniform actions;
    ``None`` for ``env.rollout``) or ``exit`` (:func:`exit_policy`)."""
    if name not in POLICIES:
        raise ValueError(f"policy must be one of {POLICIES}, got {name!r}")
    return {"expert": lambda: ScriptedExpert(env), "random": lambda: None,
            "exit": lambda: exit_policy(env)}[name]()  # fmt: skip


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
    ``kf_error_p95`` is the 95th percentile over every AUV-decision. ``callback(env, td)`` is
    called after every decision (``EnvBase.rollout``'s), e.g. to advance a progress bar."""
    rollout = env.rollout(steps, policy, break_when_any_done=False, callback=callback)
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
    term_totals = {k: torch.where(mask[..., None], terms[k].double(), 0.0).sum() for k in
                   iout.COST_TERMS}  # fmt: skip
    total = sum(term_totals.values())
    out = {
        "sdr_mbit": metrics["sdr"].double().mean().item(),
        "ssn": metrics["ssn"].double().mean().item(),
        "ec_w": metrics["ec"].double().mean().item(),
        "violation_rate": (metrics["violations"].double() / (n * decisions)).mean().item(),
        "collisions": metrics["collisions"].double().mean().item(),
        "terminated": at_end["terminated"][:, 0].double().mean().item(),
        "decisions": decisions.mean().item(),
        "service_end_inside": (
            metrics["services_inside"].sum() / metrics["ssn"].sum().clamp_min(1)
        ).item(),
        **{k: metrics[k].double().mean().item() for k in TRACKING_METRICS},
        "kf_error_mean": kf_error.double().mean().item(),
        "kf_error_p95": kf_error.double().quantile(0.95).item(),
        "usbl_error_mean": metrics["usbl_position_error"].double().mean().item(),
        "cost_mean": (cost.sum((-2, -1)) / (n * decisions)).mean().item(),
        **{f"share_{k}": (v / total).item() for k, v in term_totals.items()},
    }
    for gamma in gammas:
        discount = gamma ** torch.arange(cost.shape[1], dtype=torch.float64)
        out[f"discounted_cost_{gamma}"] = (cost * discount[:, None]).sum(1).mean().item()
    return out


def evaluate(
    make_env: Callable[[str, int], DataCollectionEnv],
    policies: Mapping[str, Callable[[DataCollectionEnv], object]],
    sea_states: Sequence[str],
    *,
    seed: int,
    steps: int,
    progress: bool = False,
) -> list[dict]:
    """Every policy in every sea state on the same held-out scenes, deterministic actions.

    Args:
        make_env: ``(sea_state, seed) -> env``; called anew per policy so every policy sees
            the same scenes.
        policies: name -> ``env -> policy`` (a TensorDict module, or ``None`` for random
            actions); e.g. ``{"trained": lambda env: actor, **reference_policies()}``.
        sea_states: presets to evaluate in.
        seed: the evaluation seed (keep it apart from the training seeds): the scenes' and,
            through torch's global generator (forked, restored after), the random actions'
            and the proposer's samples.
        steps: decisions per episode.
        progress: show a progress bar (decisions of every row, the row being evaluated).

    Returns:
        one row per (sea state, policy): ``{"sea_state", "policy", **episode_stats}``.
    """
    rows = []
    bar = tqdm.tqdm(total=len(sea_states) * len(policies) * steps, unit="decision",
                    desc="evaluation", disable=not progress)  # fmt: skip
    with set_exploration_type(ExplorationType.DETERMINISTIC), torch.no_grad(), bar:
        for sea_state in sea_states:
            for name, build in policies.items():
                bar.set_postfix_str(f"{sea_state} {name}")
                env = make_env(sea_state, seed)
                with torch.random.fork_rng():  # random actions and proposals: seeded too
                    torch.manual_seed(seed)
                    stats = episode_stats(env, build(env), steps,
                                          callback=lambda *_: bar.update())  # fmt: skip
                rows.append({"sea_state": sea_state, "policy": name, **stats})
                bar.update(len(rows) * steps - bar.n)  # rollout's callback skips the last step
    return rows


def reference_policies() -> dict[str, Callable[[DataCollectionEnv], object]]:
    """The reference rows of every evaluation: the scripted expert and random actions."""
    return {"expert": lambda env: ScriptedExpert(getattr(env, "base_env", env)),
            "random": lambda env: None}  # fmt: skip
