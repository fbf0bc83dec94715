"""evaluate(workers=N): rows side by side in worker processes give the rows of one process;
SameRowAs copies a row; what cannot travel to a worker is named before any work."""

from __future__ import annotations

import pytest
import torch
from omegaconf import OmegaConf
from torchrl.envs.utils import ExplorationType, set_exploration_type

from torchrl_auv import training
from torchrl_auv.modules import DiffusionProposer

STEPS = 6


def _setup():
    cfg = OmegaConf.create(
        {"env": {"sea_state": "ideal", "controller": "pid", "rate_model": "shannon", "history": 2}}
    )
    make_env = training.held_out_env(cfg, 2, STEPS)
    env = make_env("ideal", 0)
    proposer = DiffusionProposer.for_env(env, num_inference_steps=3, horizon=4)
    policies = {
        "actor": training.make_actor(env, (8,)),
        "alone": training.proposer_alone(proposer, num_candidates=3),  # draws from torch's RNG
        "same as actor": training.SameRowAs("actor"),
        **training.reference_policies(),
    }
    return make_env, policies


def test_rows_from_two_workers_are_the_rows_of_one_process():
    make_env, policies = _setup()
    args = {"seed": 100_000, "steps": STEPS}
    one = training.evaluate(make_env, policies, ["ideal", "es"], **args)
    two = training.evaluate(make_env, policies, ["ideal", "es"], workers=2, **args)
    assert [(r["sea_state"], r["policy"]) for r in two] == [
        (sea, name) for sea in ("ideal", "es") for name in policies
    ]
    assert two == one  # the same numbers, row by row
    by_name = {(r["sea_state"], r["policy"]): r for r in two}
    assert {**by_name["es", "same as actor"], "policy": "actor"} == by_name["es", "actor"]
    # each row is its policy's own rollout (seeded as evaluate documents), not another's
    for name, policy in (("expert", training.expert_policy), ("alone", policies["alone"])):
        env = make_env("es", 100_000)
        with set_exploration_type(ExplorationType.DETERMINISTIC), torch.random.fork_rng():
            torch.manual_seed(100_000)
            own = training.episode_stats(env, policy(env) if name == "expert" else policy, STEPS)
        assert by_name["es", name] == {"sea_state": "es", "policy": name, **own}


def test_a_policy_that_cannot_reach_a_worker_is_named_and_a_missing_row_too():
    make_env, policies = _setup()
    with pytest.raises(ValueError, match=r"row 'local'.*picklable"):
        training.evaluate(
            make_env,
            {**policies, "local": lambda env: None},
            ["ideal"],
            seed=0,
            steps=STEPS,
            workers=2,
        )
    with pytest.raises(ValueError, match=r"policies\['OA'\] is the row of 'framework'"):
        training.evaluate(
            make_env, {"OA": training.SameRowAs("framework")}, ["ideal"], seed=0, steps=STEPS
        )
    with pytest.raises(ValueError, match="workers must be an int >= 1, got 0"):
        training.evaluate(make_env, policies, ["ideal"], seed=0, steps=STEPS, workers=0)


def test_a_worker_ends_when_its_parent_is_killed():
    """kill -9 of the process that owns an evaluation worker leaves no worker behind."""
    import os
    import signal
    import subprocess
    import sys
    import time

    script = (
        "import os, time\n"
        "from omegaconf import OmegaConf\n"
        "from torchrl_auv import training\n"
        "from torchrl_auv.evaluation import RowWorker\n"
        "if __name__ == '__main__':\n"
        "    cfg = OmegaConf.create({'env': {'sea_state': 'ideal', 'controller': 'pid',\n"
        "                                    'rate_model': 'shannon'}})\n"
        "    worker = RowWorker(training.held_out_env(cfg, 1, 2), 'ideal', seed=0, steps=2)\n"
        "    print(worker.pool.submit(os.getpid).result(), flush=True)\n"
        "    time.sleep(600)\n"
    )
    parent = subprocess.Popen(
        [sys.executable, "-c", script],
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    worker = int(parent.stdout.readline())
    os.kill(worker, 0)  # alive while its parent lives
    parent.send_signal(signal.SIGKILL)
    parent.wait()
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline:
        try:
            os.kill(worker, 0)
        except ProcessLookupError:
            return
        time.sleep(0.2)
    os.kill(worker, signal.SIGKILL)
    raise AssertionError(f"worker {worker} outlived its killed parent by 20 s")
