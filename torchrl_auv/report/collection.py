"""The data-collection task's card: how the expert, random actions and an exit policy fare.

:func:`episode_stats` rolls a policy out in :class:`~torchrl_auv.envs.DataCollectionEnv` for one
episode per scene and returns the numbers the task is judged by (per scene, then averaged):
the paper's metrics (SDR in Mbit, SSN, EC), safety (violations per AUV-decision, collisions,
terminated episodes), station keeping (services that end within the service radius), the
localisation (the filter's and the raw USBL fixes' position error), the cost (mean per
AUV-decision, the share of each term, the discounted cost from reset for given discounts).
``python -m torchrl_auv.report.collection`` prints them as a markdown table for every preset
and rate model.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Sequence

import torch
from tensordict import TensorDictBase

from torchrl_auv import iout
from torchrl_auv.envs import DataCollectionEnv, ScriptedExpert

__all__ = ["POLICIES", "episode_stats", "exit_policy", "main", "make_policy"]

POLICIES = ("expert", "random", "exit")


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
) -> dict[str, float]:
    """Roll ``policy`` out for ``steps`` decisions (one episode per scene, or its first
    ``steps`` decisions) and summarise it (module docstring). Values are means over scenes;
    ``kf_error_p95`` is the 95th percentile over every AUV-decision."""
    rollout = env.rollout(steps, policy, break_when_any_done=False)
    first, mask = _first_episode(rollout)
    scenes = torch.arange(rollout.batch_size[0])
    at_end = rollout["next"][scenes, first]
    metrics = at_end["metrics"]
    n = env.num_auvs
    decisions = (first + 1).double()
    truth = rollout["next", "truth", "eta"][..., :3]
    kf_error = torch.linalg.vector_norm(rollout["next", "kf", "mean"][..., :3] - truth, dim=-1)
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


def main(argv: Sequence[str] | None = None) -> list[dict]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presets", nargs="+", default=["ideal", "es", "ves"])
    parser.add_argument("--rate-models", nargs="+", default=["shannon", "paper"])
    parser.add_argument("--policies", nargs="+", default=["expert", "random"])
    parser.add_argument("--scenes", type=int, default=8)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    rows = []
    for preset in args.presets:
        for rate_model in args.rate_models:
            for name in args.policies:
                env = DataCollectionEnv(batch_size=[args.scenes], sea_state=preset,
                                        rate_model=rate_model, seed=args.seed)  # fmt: skip
                stats = episode_stats(env, make_policy(name, env), args.steps)
                rows.append({"preset": preset, "rate_model": rate_model, "policy": name, **stats})
                print(_row(rows[-1], header=len(rows) == 1), flush=True)
    return rows


def _row(row: dict, header: bool) -> str:
    keys = list(row)
    line = "| " + " | ".join(_fmt(row[k]) for k in keys) + " |"
    if not header:
        return line
    return "| " + " | ".join(keys) + " |\n|" + "---|" * len(keys) + "\n" + line


def _fmt(value) -> str:
    if isinstance(value, float):
        return "nan" if math.isnan(value) else f"{value:.3g}"
    return str(value)


if __name__ == "__main__":
    main()
