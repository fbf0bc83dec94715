"""Episode statistics of the data-collection task: roll a policy out and summarise it.

:func:`episode_stats` rolls a policy out in :class:`~torchrl_auv.envs.DataCollectionEnv` for one
episode per scene and returns the numbers the task is judged by (per scene, then averaged):
the paper's metrics (SDR in Mbit, SSN, EC), tracking (heading and depth error mean and std over
the moving decisions), safety (violations per AUV-decision, collisions, terminated episodes),
station keeping (services that end within the service radius), the localisation (the filter's
and the raw USBL fixes' position error), the cost (mean per AUV-decision, the share of each
term, the discounted cost from reset for given discounts).

Examples:
    >>> from torchrl_auv.envs import DataCollectionEnv
    >>> from torchrl_auv.evaluation import make_policy
    >>> env = DataCollectionEnv(batch_size=[2], seed=0, max_steps=5)
    >>> stats = episode_stats(env, make_policy("expert", env), 5)
    >>> stats["decisions"], stats["terminated"]
    (5.0, 0.0)
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import torch
from tensordict import TensorDictBase

from torchrl_auv import iout
from torchrl_auv.envs import SIM_KEY, DataCollectionEnv

__all__ = ["SE_METRICS", "TRACKING_METRICS", "episode_stats", "first_episode"]

#: the per-scene metrics whose standard error over scenes a row carries as ``<name>_se``
SE_METRICS = ("sdr_mbit", "ssn", "violation_rate", "cost_mean")
TRACKING_METRICS = (
    "heading_error_mean",
    "heading_error_std",
    "depth_error_mean",
    "depth_error_std",
)


def first_episode(rollout: TensorDictBase) -> tuple[torch.Tensor, torch.Tensor]:
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
    transition_stats: Callable | None = None,
) -> dict[str, float]:
    """Roll ``policy`` out for ``steps`` decisions (one episode per scene, or its first
    ``steps`` decisions) and summarise it (module docstring). Values are means over scenes;
    ``kf_error_p95`` is the 95th percentile over every AUV-decision; ``<metric>_se`` the
    standard error over scenes of :data:`SE_METRICS` and the discounted costs (cost per AUV
    from reset, the AUVs' mean). ``callback(env, td)`` is
    called after every decision (``EnvBase.rollout``'s), e.g. to advance a progress bar.
    ``transition_stats(rollout, mask)``: more of the row's values from the rollout and the
    ``[B, T]`` mask of each scene's first episode (e.g. a
    :class:`~torchrl_auv.evaluation.LyapunovCertificate`)."""
    rollout = env.rollout(steps, policy, break_when_any_done=False, callback=callback)
    rollout = rollout.cpu()  # an env on a GPU (device=cuda): the statistics on the CPU
    first, mask = first_episode(rollout)
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
    if transition_stats is not None:
        out.update(transition_stats(rollout, mask))
    return out


def _standard_error(values: torch.Tensor) -> float:
    """Standard error of the mean over scenes (sample std / sqrt(B); 0 for one scene)."""
    if values.numel() < 2:
        return 0.0
    return (values.std() / values.numel() ** 0.5).item()
