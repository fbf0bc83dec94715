"""Where a training frame of the paper preset goes, and what it means for the paper's grid.

A frame is one scene-decision. For ``diffusion_lac`` and ``diffusion_rl`` at the paper preset
(``ves``, 8 scenes, compiled physics, K = 5 candidates of the preset's sampler, networks 256x256,
250 updates of batch 64 per 1000 frames) this times, after warm-up, one decision step of the
env (8 frames), of the acting policy (the proposer's K chunks per AUV, then the critic's
selection) and of the proposer alone, and one gradient update; the proposer has the preset's
architecture with untrained weights (acting costs the same whatever the weights), so no first
stage is built. ``--sampler ddim --steps 10`` times the other sampler.

It then prints the frames/s these parts allow one process (collection and updates in turn, as
the recipes run them; the recipes' own bookkeeping, logging and learning-curve points are not
in it) and what the paper's grid (``recipes/paper/run_all.py budget=paper``: its jobs by
framework, ``--first-stage-min`` per first stage alone, ``--eval-min`` per job's final
evaluation) would take at ``--frames`` frames per job with two jobs at a time on the two cores.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from _runner import measure, print_summary, print_table, setup

REPO = Path(__file__).resolve().parents[1]


def _arguments(parser):
    parser.add_argument(
        "--framework", default="diffusion_lac", choices=("diffusion_lac", "diffusion_rl")
    )
    parser.add_argument("--sampler", default=None, help="ddpm | ddim (default: the preset's)")
    parser.add_argument("--steps", type=int, default=None, help="denoising steps")
    parser.add_argument("--frames", type=int, default=50_000, help="frames per grid job")
    parser.add_argument(
        "--first-stage-min",
        type=float,
        default=14.0,
        help="minutes per first stage alone on 2 cores (recipes/README.md)",
    )
    parser.add_argument(
        "--fps",
        type=float,
        default=None,
        help="frames/s per job for the grid estimate (default: the parts' "
        "rate; the recipes measured 27-42 with two runs on 2 cores)",
    )
    parser.add_argument(
        "--eval-min",
        type=float,
        default=3.0,
        help="minutes per job's final evaluation in one sea (about 0.56 "
        "per row of 4 scenes x 1000 decisions on 2 workers, 5 rows)",
    )


def _build(framework: str, sampler: str | None, steps: int | None, folder: Path):
    import torch
    from hydra import compose, initialize_config_dir

    from torchrl_auv import training
    from torchrl_auv.training.first_stage_build import untrained_proposer

    overrides = [
        f"framework={framework}",
        "preset=paper",
        f"run_dir={folder}/run",
        f"proposer.path={folder}/proposer.pt",
    ]
    overrides += [f"proposer.sampler={sampler}"] if sampler else []
    overrides += [f"proposer.num_inference_steps={steps}"] if steps else []
    with initialize_config_dir(config_dir=str(REPO / "recipes"), version_base="1.3"):
        cfg = compose("train", overrides=overrides)
    p = cfg.proposer
    env = training.env_from_config(cfg)
    obs_dim = env.observation_spec["agents", "observation"].shape[-1]
    untrained_proposer(obs_dim, 3, history=p.history, horizon=p.horizon, model=p).save(
        folder / "proposer.pt"
    )
    proposer = training.first_stage_from_config(cfg).proposer
    actor = training.make_actor(env, cfg.network.hidden)
    if framework == "diffusion_lac":
        critic = training.make_lyapunov_critic(env, cfg.network.hidden)
        learner = training.lac_from_config(cfg, env, actor, critic)
        policy = training.make_selection_policy(
            proposer,
            critic,
            mode="lyapunov",
            loss=learner.loss,
            critic_out_key=training.LYAPUNOV_RAW,
        )
    else:
        from torchrl_auv.objectives import QEnsembleCritic

        learner = training.sac_from_config(cfg, env, actor)
        critic = QEnsembleCritic.from_loss(learner.loss)
        policy = training.make_selection_policy(
            proposer, critic, mode="q", critic_out_key=critic.out_keys[0]
        )
    buffer = training.buffer_from_config(cfg, folder / "run")
    with torch.no_grad():
        data = env.rollout(40, break_when_any_done=False)
    buffer.extend(training.select_for_replay(data.reshape(-1)))
    return cfg, env, proposer, policy, learner, buffer


def main(argv=None) -> None:
    args = setup(__doc__.split("\n")[0], argv, _arguments)
    import torch

    from torchrl_auv.report.paper.grid import EXPERIMENTS, grid

    with tempfile.TemporaryDirectory() as tmp:
        cfg, env, proposer, policy, learner, buffer = _build(
            args.framework, args.sampler, args.steps, Path(tmp)
        )
        td = env.reset()
        start = time.perf_counter()
        env.step(policy(td.clone()))
        print(f"first step (compilation included): {time.perf_counter() - start:.1f} s")
        repeats = 2 if args.quick else 5
        with torch.no_grad():
            t_policy = measure(lambda: policy(td.clone()), repeats=repeats).median
            t_proposer = measure(lambda: proposer(td.clone()), repeats=repeats).median
            acted = policy(td.clone())
            t_env = measure(lambda: env.step(acted.clone()), repeats=repeats).median
        t_update = measure(lambda: learner.step(buffer.sample()), repeats=repeats).median
    scenes = env.batch_size[0]
    ratio = cfg.optim.updates_per_batch / cfg.collector.frames_per_batch
    parts = {
        "env step": t_env / scenes,
        "policy (proposer + selection)": t_policy / scenes,
        "  of which the proposer": t_proposer / scenes,
        "updates": t_update * ratio,
    }
    per_frame = parts["env step"] + parts["policy (proposer + selection)"] + parts["updates"]
    print_table(
        f"{args.framework}, paper preset, sampler {proposer.sampler} "
        f"{proposer.num_inference_steps} steps: ms per frame",
        ["part", "ms", "share"],
        [[k, v * 1e3, f"{100 * v / per_frame:.0f} %"] for k, v in parts.items()],
    )
    fps = 1.0 / per_frame
    if args.fps:
        fps = args.fps
    jobs = grid([e for e in EXPERIMENTS if e != "advisor_llm"], seeds=(0, 1, 2))
    trained = [job for job in jobs if job.framework != "diffusion"]
    builders = [job for job in jobs if job.framework == "diffusion"]
    # two jobs at a time, one core each; a first stage alone uses both cores
    hours = (
        len(builders) * args.first_stage_min / 60
        + len(jobs) * args.eval_min / 60 / 2
        + len(trained) * args.frames / fps / 3600 / 2
    )
    print_table(
        "the paper grid (3 seeds) on 2 cores, two jobs at a time",
        ["jobs", "first stages", "frames per job", "frames/s per job", "hours"],
        [[len(jobs), len(builders), args.frames, fps, hours]],
    )
    print_summary(
        "bench_frame_cost",
        frames_per_s=fps,
        proposer_share=parts["  of which the proposer"] / per_frame,
        update_share=parts["updates"] / per_frame,
        grid_hours=hours,
    )


if __name__ == "__main__":
    main()
