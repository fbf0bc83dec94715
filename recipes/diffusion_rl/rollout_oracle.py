"""How much can any selection among the proposer's candidates gain? A rollout oracle.

    .venv/bin/python recipes/diffusion_rl/rollout_oracle.py FIRST_STAGE_FOLDER \\
        --sea ves --scenes 4 --decisions 500 --horizon 20 --score cost --out oracle.json

At every decision the oracle draws the proposer alone's candidates (``--alone`` draws, the
first action of their medoid is the prior's choice) and scores, for each AUV, the first
``--candidates`` of them and the prior's choice by Monte-Carlo rollouts from copies of the
scene: in copy ``(i, k)`` AUV ``i`` executes candidate ``k``, every other AUV the prior's
choice, and then the proposer alone acts for ``--horizon`` decisions in all. The copies of a
scene share every random number of the simulation (common random numbers), so candidates are
compared on the same current, sensor noise and data arrivals. Scores: ``cost``, the
discounted sum of the AUVs' costs over the horizon (what a critic of the prior's cost-to-go
would estimate, truncated), or ``sdr``, the data the AUVs deliver in it (the mission). The
candidate with the best score is executed (the prior's choice on a tie).

This is one step of policy improvement on the prior with a perfect, simulator-backed critic:
an upper bound (up to the rollouts' noise and horizon) on what a learned critic that ranks
the same candidates, with the same prior behind it, can gain. It reads the simulator's state,
which no deployable policy can: a diagnostic, not a controller. ``--score prior`` evaluates the
proposer alone on the same scenes instead.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import torch
from torch.utils._pytree import tree_map
from torchrl.envs import TransformedEnv, step_mdp
from torchrl.envs.utils import ExplorationType, set_exploration_type

from torchrl_auv.envs import DataCollectionEnv, StateActionHistory
from torchrl_auv.evaluation import episode_stats
from torchrl_auv.modules import DiffusionProposer, ProposerAlone, medoid_index
from torchrl_auv.training import make_history_env

OBSERVATION, ACTION = ("agents", "observation"), ("agents", "action")
SCORES = ("cost", "sdr", "prior")


class SharedNoiseEnv(DataCollectionEnv):
    """:class:`DataCollectionEnv` whose consecutive groups of ``copies`` scenes draw every
    random number of a decision once per group: copies of one scene that take the same actions
    stay identical, and copies that differ see the same current, noise and data arrivals."""

    def __init__(self, *args, copies: int, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        if self.batch_size[0] % copies:
            raise ValueError(f"batch_size {self.batch_size} is not a multiple of copies {copies}")
        self.copies = copies

    def _decision_draws(self, td):
        draws = super()._decision_draws(td)
        batch, copies = td.batch_size[0], self.copies

        def shared(x: torch.Tensor) -> torch.Tensor:
            dim = list(x.shape).index(batch)  # the scenes' dim of this draw
            first = x.unflatten(dim, (batch // copies, copies)).narrow(dim + 1, 0, 1)
            return first.expand(*first.shape[: dim + 1], copies, *first.shape[dim + 2 :]).flatten(
                dim, dim + 1
            )

        return tree_map(shared, draws)


def scene_env(sea: str, seed: int, scenes: int, *, copies: int = 1, history: int = 10):
    """The held-out scenes as the recipes evaluate them (S-Surface, shannon rate, 1000-decision
    episodes, the proposer's state-action history: :func:`~torchrl_auv.training.make_history_env`),
    in groups of ``copies`` that share their random numbers when ``copies > 1``."""
    if copies == 1:
        return make_history_env(sea, history=history, seed=seed, num_envs=scenes, max_steps=1000)
    env = SharedNoiseEnv(
        copies=copies, batch_size=[scenes], sea_state=sea, seed=seed, max_steps=1000
    )
    return TransformedEnv(
        env, StateActionHistory(history, observation_key=OBSERVATION, action_key=ACTION)
    )


class RolloutOracle(torch.nn.Module):
    """The oracle's policy (module docstring) on ``scenes`` scenes of ``sea``."""

    def __init__(
        self, proposer, sea, scenes, *, horizon, score, candidates, alone, gamma, auvs, seed
    ):
        super().__init__()
        if score not in ("cost", "sdr"):
            raise ValueError(f"score must be 'cost' or 'sdr', got {score!r}")
        self.proposer, self.horizon, self.score, self.gamma = proposer, horizon, score, gamma
        self.candidates, self.alone, self.auvs = candidates, alone, auvs
        self.prior = ProposerAlone(proposer, "medoid", action_key=ACTION, num_candidates=alone)
        self.copies = auvs * (candidates + 1)
        self.rollouts = scene_env(sea, seed, scenes * self.copies, copies=self.copies)
        self.chosen: list[torch.Tensor] = []  # [S, N] per decision: the option executed
        self.spread: list[torch.Tensor] = []  # [S, N] per decision: best minus worst score

    def options(self, td):
        """``[S, N, K + 1, A]``: the first ``candidates`` draws and, last, the prior's choice."""
        p = self.proposer
        drawn, _ = p.sample(p.build_state(td), num_candidates=self.alone, generator=p.generator)
        first = drawn[..., 0, :]
        medoid = medoid_index(drawn)[..., None, None].expand(*drawn.shape[:-3], 1, first.shape[-1])
        return torch.cat([first[..., : self.candidates, :], first.gather(-2, medoid)], -2)

    def forward(self, td):
        options = self.options(td)
        scenes, auvs, k, dim = options.shape
        prior = options[..., -1, :]
        actions = prior[:, None, None].expand(scenes, auvs, k, auvs, dim).clone()
        for i in range(auvs):  # copy (i, k): AUV i executes option k, the others the prior's
            actions[:, i, :, i] = options[:, i]
        roll = td.exclude(ACTION).unsqueeze(1).expand(scenes, auvs * k).clone()
        roll = roll.reshape(scenes * auvs * k)
        roll.set(ACTION, actions.reshape(scenes * auvs * k, auvs, dim))
        value = torch.zeros(roll.batch_size, dtype=torch.float64)
        alive = torch.ones(roll.batch_size, dtype=torch.bool)
        delivered = roll["metrics", "sdr"].double().clone()
        start = delivered.clone()
        for t in range(self.horizon):
            if t:
                self.prior(roll)
            roll = self.rollouts.step(roll)
            cost = roll["next", "agents", "cost"][..., 0].sum(-1).double()
            value += torch.where(alive, self.gamma**t * cost, 0.0)
            delivered = torch.where(alive, roll["next", "metrics", "sdr"].double(), delivered)
            alive &= ~roll["next", "done"][..., 0]
            roll = step_mdp(roll)
        if self.score == "sdr":
            value = start - delivered  # lower is better: more data delivered
        value = value.reshape(scenes, auvs, k).clone()
        self.spread.append(value.amax(-1) - value.amin(-1))
        value[..., -1] -= 1e-9  # a tie keeps the prior's choice
        best = value.argmin(-1)
        self.chosen.append(best)
        pick = best[..., None, None].expand(scenes, auvs, 1, dim)
        return td.set(ACTION, options.gather(-2, pick).squeeze(-2))


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("first_stage", type=Path, help="a first-stage folder (its proposer.pt)")
    parser.add_argument("--sea", default="ves")
    parser.add_argument("--seed", type=int, default=100000, help="the held-out scenes' seed")
    parser.add_argument("--scenes", type=int, default=4)
    parser.add_argument("--decisions", type=int, default=500)
    parser.add_argument("--horizon", type=int, default=20, help="decisions per rollout")
    parser.add_argument("--score", choices=SCORES, default="cost")
    parser.add_argument("--candidates", type=int, default=5, help="K, the selection's")
    parser.add_argument("--alone", type=int, default=10, help="draws of the prior's medoid")
    parser.add_argument("--gamma", type=float, default=0.99)
    parser.add_argument("--rollout-seed", type=int, default=12345, help="the copies' draws")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    proposer = DiffusionProposer.load(args.first_stage / "proposer.pt")
    proposer.configure_sampling(
        num_candidates=args.candidates, num_inference_steps=10, sampler="ddim"
    )
    env = scene_env(args.sea, args.seed, args.scenes)
    if args.score == "prior":
        policy = ProposerAlone(proposer, "medoid", action_key=ACTION, num_candidates=args.alone)
    else:
        policy = RolloutOracle(
            proposer,
            args.sea,
            args.scenes,
            horizon=args.horizon,
            score=args.score,
            candidates=args.candidates,
            alone=args.alone,
            gamma=args.gamma,
            auvs=env.num_auvs,
            seed=args.rollout_seed,
        )
    began = time.perf_counter()
    with set_exploration_type(ExplorationType.DETERMINISTIC), torch.no_grad():
        torch.manual_seed(args.seed)
        stats = episode_stats(env, policy, args.decisions)
    stats["seconds"] = time.perf_counter() - began
    if args.score != "prior":
        chosen = torch.stack(policy.chosen)
        stats["share_prior_choice"] = (chosen == args.candidates).double().mean().item()
        stats["score_spread_mean"] = torch.stack(policy.spread).mean().item()
    stats["args"] = {k: str(v) for k, v in vars(args).items()}
    args.out.write_text(json.dumps(stats, indent=1))
    return stats


if __name__ == "__main__":
    main()
