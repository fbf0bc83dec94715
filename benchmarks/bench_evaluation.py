"""Evaluation's share of a diffusion_lac paper-preset run, before and after the [15/18] changes.

Builds the paper preset's pieces (``recipes/diffusion_lac/paper.yaml``: ves, 8 training scenes,
compiled physics, K = 5 candidates of 50 DDPM steps, the proposer alone's medoid of 10,
networks 256x256, 250 updates of batch 64 per 1000 frames) around a proposer of the paper's
architecture (untrained: the time per decision does not depend on the weights), then times

* the training loop: seconds per 1000-frame batch (collection with the selection policy and
  250 updates), alone and with a learning-curve point evaluated in the background worker
  at the same time (``eval.curve_background``; the second core);
* one learning-curve point in the loop (2 held-out scenes of the training sea);
* the final evaluation's rows in one sea (4 scenes): the 10 rows one after another as before
  (OA evaluated again), the 9 rows with OA copied, and those 9 in 2 worker processes
  (``eval.workers=2``, the worker start-up and compilation included).

``--decisions`` decisions per row (default 100; ``--quick``: 10, a smoke run whose
extrapolation means little) are timed and scaled to the paper's 1000 (the worker
start-up, timed on 1-decision rows, is not scaled), and the paper's 3 seas; the run's share
is (final evaluation + curve points the loop waits for) / (that + 300 batches of training,
first stage cached). Before: 13 points in the loop (every 25,000 of 300,000 frames); after:
only the last one (the loop waits for it at the end), plus whatever the background worker
slows the 300 batches down by (counted as evaluation, not training). Issue [15/18]'s
target: evaluation <= 25 % of a run's time.
"""

from __future__ import annotations

import time
from pathlib import Path

from _runner import print_summary, print_table, setup

REPO = Path(__file__).resolve().parents[1]
PAPER_FRAMES, CURVE_POINTS, SEAS, FULL_DECISIONS = 300_000, 13, 3, 1000


def _arguments(parser) -> None:
    parser.add_argument(
        "--decisions",
        type=int,
        default=None,
        help="decisions per timed row (default 100; --quick: 10)",
    )
    parser.add_argument(
        "--batches", type=int, default=None, help="timed training batches (default 3; --quick: 1)"
    )


def _pieces():
    from hydra import compose, initialize_config_dir

    from torchrl_auv import training
    from torchrl_auv.modules import DiffusionProposer

    with initialize_config_dir(str(REPO / "recipes" / "diffusion_lac"), version_base="1.3"):
        cfg = compose("paper", ["run_dir=/tmp/bench_evaluation", "logger.backend="])
    env = training.env_from_config(cfg)
    p = cfg.proposer
    obs_dim = env.observation_spec[training.OBSERVATION].shape[-1]
    proposer = DiffusionProposer(
        DiffusionProposer.conditioning_dim(obs_dim, 3, p.history),
        3,
        state_key=training.OBSERVATION,
        history_key=(training.AGENTS, "history"),
        horizon=p.horizon,
        noise_model=p.noise_model,
        num_candidates=p.num_candidates,
        noise_model_kwargs={"hidden": p.hidden, "depth": p.depth, "cond_dim": p.cond_dim},
        num_inference_steps=p.num_inference_steps,
        sampler=p.sampler,
        compile=p.compile,
    )
    actor = training.make_actor(env, cfg.network.hidden)
    critic = training.make_lyapunov_critic(env, cfg.network.hidden)
    learner = training.lac_from_config(cfg, env, actor, critic)
    policy = training.make_selection_policy(
        proposer, critic, mode="lyapunov", loss=learner.loss, critic_out_key=training.LYAPUNOV_RAW
    )
    return cfg, env, actor, proposer, learner, policy


def _train_batches(cfg, env, learner, policy, batches: int, worker=None) -> float:
    """Median seconds per 1000-frame batch (the first, with compilation, not timed); with
    ``worker``, a curve point is submitted to it whenever it is idle (busy all along)."""
    from torchrl_auv import training

    buffer = training.buffer_from_config(cfg, Path("/tmp/bench_evaluation"))
    collector = training.collector_from_config(
        cfg, policy, env=env, total_frames=(batches + 1) * 1000
    )
    seconds, began = [], time.perf_counter()
    for i, data in enumerate(collector):
        buffer.extend(training.select_for_replay(data))
        for _ in range(cfg.optim.updates_per_batch):
            learner.step(buffer.sample())
        now = time.perf_counter()
        if i:
            seconds.append(now - began)
        if worker is not None and i < batches:  # keep the worker busy, as a long run would
            worker.results()
            if not worker.pending:
                worker.submit(i, policy)
        began = time.perf_counter()
    collector.shutdown()
    return sorted(seconds)[len(seconds) // 2]


def main() -> None:
    args = setup(__doc__, add_arguments=_arguments)
    from torchrl_auv import training
    from torchrl_auv.evaluation import RowWorker

    args.decisions = args.decisions or (10 if args.quick else 100)
    args.batches = args.batches or (1 if args.quick else 3)
    cfg, env, actor, proposer, learner, policy = _pieces()
    d, scale = args.decisions, FULL_DECISIONS / args.decisions
    rows = training.evaluation_policies_from_config(cfg, "diffusion_lac", policy, actor, proposer)
    old_rows = {**rows, "OA": training.RankedCandidate(policy, 0)}  # evaluated again
    final_env = training.held_out_env(cfg, cfg.eval.num_envs, d)
    curve_env = training.held_out_env(cfg, cfg.eval.curve_envs, d)

    def timed(fn) -> float:
        began = time.perf_counter()
        fn()
        return time.perf_counter() - began

    def final(policies, workers, make_env=final_env, steps=d):
        return training.evaluate(
            make_env, policies, ["ves"], seed=cfg.eval.seed, steps=steps, workers=workers
        )

    final(rows, 1, training.held_out_env(cfg, cfg.eval.num_envs, 2), 2)  # compile in this process
    training.evaluate(
        training.held_out_env(cfg, cfg.eval.curve_envs, 2),
        {"policy": policy},
        ["ves"],
        seed=cfg.eval.seed,
        steps=2,
    )
    point = timed(
        lambda: training.evaluate(
            curve_env, {"policy": policy}, ["ves"], seed=cfg.eval.seed, steps=d
        )
    )
    old_serial = timed(lambda: final(old_rows, 1))
    new_serial = timed(lambda: final(rows, 1))
    start_up = timed(lambda: final(rows, 2, training.held_out_env(cfg, cfg.eval.num_envs, 1), 1))
    new_workers = timed(lambda: final(rows, 2))
    batch = _train_batches(cfg, env, learner, policy, args.batches)
    worker = RowWorker(
        training.held_out_env(cfg, cfg.eval.curve_envs, FULL_DECISIONS),
        "ves",
        seed=cfg.eval.seed,
        steps=FULL_DECISIONS,
    )
    batch_background = _train_batches(cfg, env, learner, policy, args.batches, worker)
    worker.close()  # the point still out is dropped

    full = {
        "point": point * scale,
        "old": old_serial * scale * SEAS,
        "serial": new_serial * scale * SEAS,
        "workers": start_up + (new_workers - start_up) * scale * SEAS,
    }
    training_s = {"old": batch * PAPER_FRAMES / 1000, "new": batch_background * PAPER_FRAMES / 1000}
    before = full["old"] + CURVE_POINTS * full["point"]
    # after: the training the background points slow down is counted as evaluation too
    after = full["workers"] + full["point"] + max(training_s["new"] - training_s["old"], 0.0)
    share_before = before / (before + training_s["old"])
    share_after = after / (after + training_s["old"])
    print_table(
        f"timed on ves ({d} decisions per row), scaled to {FULL_DECISIONS} decisions x {SEAS} seas",
        ["what", f"timed (s, {d} dec.)", "paper run (min)"],
        [
            ["one curve point (2 scenes)", f"{point:.1f}", f"{full['point'] / 60:.1f}"],
            [
                "final eval, 10 rows one after another (before)",
                f"{old_serial:.1f}",
                f"{full['old'] / 60:.1f}",
            ],
            ["final eval, 9 rows (OA copied)", f"{new_serial:.1f}", f"{full['serial'] / 60:.1f}"],
            [
                "final eval, 9 rows, 2 workers (start-up incl.)",
                f"{new_workers:.1f}",
                f"{full['workers'] / 60:.1f}",
            ],
            ["  of which worker start-up (1-decision rows)", f"{start_up:.1f}", "-"],
            ["training, 1000-frame batch", f"{batch:.1f}", f"{training_s['old'] / 60:.1f}"],
            [
                "training batch, curve point in the background",
                f"{batch_background:.1f}",
                f"{training_s['new'] / 60:.1f}",
            ],
        ],
    )
    shares = [
        [
            "before: 13 curve points in the loop, 10 rows serial",
            before,
            training_s["old"],
            share_before,
        ],
        [
            "after: curve in the background (its slowdown of training counted here), "
            "9 rows on 2 workers",
            after,
            training_s["old"],
            share_after,
        ],
    ]
    print_table(
        "evaluation's share of a paper run (first stage cached)",
        ["", "evaluation (min)", "training (min)", "share"],
        [[what, f"{e / 60:.1f}", f"{t / 60:.1f}", f"{s:.1%}"] for what, e, t, s in shares],
    )
    print_summary(
        "evaluation",
        share_before=share_before,
        share_after=share_after,
        final_eval_speedup=full["old"] / full["workers"],
        background_batch_slowdown=batch_background / batch,
    )


if __name__ == "__main__":
    main()
