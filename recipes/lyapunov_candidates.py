r"""Hand-made Lyapunov candidates against the decrease condition on the scripted expert's
approach legs: could any simple function of the state certify a good policy, decision by
decision?

    .venv/bin/python recipes/lyapunov_candidates.py --seas ideal ves --scenes 16 --steps 1000

For each sea state, the scripted expert (and idle AUVs, a policy that never arrives) runs in
``--scenes`` held-out scenes (seeds from ``--seed``, the recipes' ``eval.seed``), and
:class:`~torchrl_auv.evaluation.LyapunovCertificate` measures, on every approach transition,
the condition :math:`(1 - e) L(s') - L(s) + \alpha c \le 0` (stability cost :math:`c`) for

- ``decisions_to_go``: :math:`L = d / (v \Delta t)`, the decisions a straight approach at
  :math:`v \Delta t` = 1.5 m a decision still needs: the condition holds where the AUV closes
  on its target by at least :math:`1.5\,\alpha c` m (a few centimetres), i.e. where it closes;
- ``distance_squared``: :math:`L = d^2 / (2 D v \Delta t)` at :math:`v \Delta t` = 1.5 m a
  decision, the leg cost-to-go of a straight approach (``LyapunovActorCriticLoss``'s
  docstring).

A learned critic is no better placed than these where the expert's own approach does not close
on its target: the expert arrives from downstream, bow into the current, and first swings
round. Prints one markdown table (policy, candidate, transitions, the share that hold, the
change's spread against the margin; the legs, the share whose summed condition holds, the
share that arrived) and writes it as CSV with ``--csv``.
"""

from __future__ import annotations

import argparse
import csv
import functools
import math

import torch
from tensordict.nn import TensorDictModule

from torchrl_auv.envs import DataCollectionEnv
from torchrl_auv.envs.keys import AGENT_ACTION, AGENT_OBSERVATION
from torchrl_auv.evaluation import (
    CERTIFICATE_KEYS,
    LyapunovCertificate,
    episode_stats,
    reference_policies,
)
from torchrl_auv.iout import OBSERVATION_FEATURES
from torchrl_auv.objectives import LyapunovSpec

#: metres an approach covers per decision in the straight-approach cost-to-go
STEP_M = 1.5
RAW = ("agents", "candidate_raw")
DISTANCE = OBSERVATION_FEATURES.index("target_distance")  # d / D in the observation


def candidates(diagonal_m: float) -> dict[str, TensorDictModule]:
    """Each candidate as a critic whose raw output, squared, is L (the ``squared`` form)."""

    def decisions_to_go(obs, action):
        return (obs[..., DISTANCE : DISTANCE + 1].clamp_min(0.0) * diagonal_m / STEP_M).sqrt()

    def distance_squared(obs, action):
        return obs[..., DISTANCE : DISTANCE + 1] * math.sqrt(diagonal_m / (2.0 * STEP_M))

    return {
        name: TensorDictModule(fn, [AGENT_OBSERVATION, AGENT_ACTION], [RAW])
        for name, fn in (
            ("decisions_to_go", decisions_to_go),
            ("distance_squared", distance_squared),
        )
    }


def _score_all(certify: dict, rollout, mask) -> dict:
    """Every candidate's certificate of one rollout, keyed ``(candidate, key)``."""
    return {
        (name, key): value
        for name, one in certify.items()
        for key, value in one(rollout, mask).items()
    }


def measure(seas, scenes: int, steps: int, seed: int, alpha: float) -> list[dict]:
    """One row per sea state, policy and candidate (the certificate's values without their
    ``lyapunov_`` prefix); each policy's one rollout scored by every candidate."""
    rows = []
    spec = LyapunovSpec(form="squared", alpha=alpha)
    for sea in seas:
        env = DataCollectionEnv(batch_size=[scenes], sea_state=sea, seed=seed, max_steps=steps)
        certify = {
            name: LyapunovCertificate(critic, spec, raw_key=RAW)
            for name, critic in candidates(env.config.area_diagonal_m).items()
        }
        every_candidate = functools.partial(_score_all, certify)

        for policy_name in ("expert", "idle"):
            env.set_seed(seed)  # the same scenes for every policy
            policy = reference_policies()[policy_name](env)
            with torch.no_grad():
                row = episode_stats(env, policy, steps, transition_stats=every_candidate)
            for name in certify:
                values = {k.removeprefix("lyapunov_"): row[name, k] for k in CERTIFICATE_KEYS}
                rows.append({"sea_state": sea, "policy": policy_name, "candidate": name, **values})
    return rows


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seas", nargs="+", default=["ideal", "ves"])
    parser.add_argument("--scenes", type=int, default=16)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=100_000)
    parser.add_argument("--alpha", type=float, default=0.1)
    parser.add_argument("--csv", default=None)
    args = parser.parse_args(argv)
    rows = measure(args.seas, args.scenes, args.steps, args.seed, args.alpha)
    print(
        "| sea | policy | L | transitions | holds | change std | margin mean | legs | "
        "legs that hold | legs arrived |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['sea_state']} | {r['policy']} | {r['candidate']} | {r['transitions']:.0f} | "
            f"{r['decrease_holds']:.3f} | {r['change_std']:.4f} | {r['margin_mean']:.4f} | "
            f"{r['legs']:.0f} | {r['leg_decrease_holds']:.3f} | {r['legs_arrived']:.3f} |"
        )
    if args.csv:
        with open(args.csv, "w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)


if __name__ == "__main__":
    main()
