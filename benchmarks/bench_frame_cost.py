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

``--presets paper fast`` (the default) times both presets of this checkout (``preset=fast``:
40 scenes, 10 DDIM steps, the update compiled; ``recipes/<framework>/fast.yaml``);
``--before PATH`` times the paper preset of another checkout (for example a ``git worktree``
of an older commit: its package and its ``recipes/``) in a subprocess first, and the ratios
of each preset's frames/s to it are printed (issue [20/26]'s target: fast >= 5x the paper
preset before). Times are medians of repeated blocks; on the shared 2-core machines they vary
by 10-30 % from run to run, so compare the columns of one run.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _runner import measure, print_summary, print_table, setup

REPO = Path(__file__).resolve().parents[1]
PRESETS = ("paper", "fast")


def _arguments(parser):
    parser.add_argument(
        "--framework", default="diffusion_lac", choices=("diffusion_lac", "diffusion_rl")
    )
    parser.add_argument(
        "--presets",
        nargs="+",
        default=list(PRESETS),
        choices=PRESETS,
        help="the presets of this checkout to time",
    )
    parser.add_argument("--before", help="another checkout's root: its paper preset, timed first")
    parser.add_argument("--recipes", default=str(REPO / "recipes"), help=argparse.SUPPRESS)
    parser.add_argument("--json-only", action="store_true", help=argparse.SUPPRESS)
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


def _build(
    framework: str, preset: str, sampler: str | None, steps: int | None, folder: Path, recipes: Path
):
    import torch
    from hydra import compose, initialize_config_dir

    from torchrl_auv import training
    from torchrl_auv.training.first_stage.build import untrained_proposer

    overrides = [
        f"framework={framework}",
        f"preset={preset}",
        f"run_dir={folder}/run",
        f"proposer.path={folder}/proposer.pt",
    ]
    overrides += [f"proposer.sampler={sampler}"] if sampler else []
    overrides += [f"proposer.num_inference_steps={steps}"] if steps else []
    with initialize_config_dir(config_dir=str(recipes), version_base="1.3"):
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


def measure_preset(args, preset: str, recipes: Path) -> dict[str, float]:
    """ms per frame of each part of ``preset`` (``recipes`` its config folder)."""
    import torch

    with tempfile.TemporaryDirectory() as tmp:
        cfg, env, proposer, policy, learner, buffer = _build(
            args.framework, preset, args.sampler, args.steps, Path(tmp), recipes
        )
        td = env.reset()
        start = time.perf_counter()
        env.step(policy(td.clone()))
        learner.step(buffer.sample())  # compiles, if compiled
        first = time.perf_counter() - start
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
        "env": t_env / scenes,
        "policy": t_policy / scenes,
        "proposer": t_proposer / scenes,
        "updates": t_update * ratio,
    }
    per_frame = parts["env"] + parts["policy"] + parts["updates"]
    return {
        **{k: v * 1e3 for k, v in parts.items()},
        "frames_per_s": 1.0 / per_frame,
        "scenes": scenes,
        "steps": proposer.num_inference_steps,
        "sampler": proposer.sampler,
        "first_s": first,
    }


def _run_before(args, path: str) -> dict[str, float]:
    command = [
        sys.executable,
        str(Path(__file__).resolve()),
        "--json-only",
        "--presets",
        "paper",
        "--recipes",
        str(Path(path) / "recipes"),
        "--framework",
        args.framework,
    ] + (["--quick"] if args.quick else [])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([path, str(Path(__file__).parent)])}
    result = subprocess.run(command, env=env, capture_output=True, text=True)
    if result.returncode:
        raise RuntimeError(f"the --before run failed:\n{result.stderr[-3000:]}")
    return json.loads(result.stdout.strip().splitlines()[-1])["paper"]


def main(argv=None) -> None:
    args = setup(__doc__.split("\n")[0], argv, _arguments)
    if args.json_only:
        print(json.dumps({p: measure_preset(args, p, Path(args.recipes)) for p in args.presets}))
        return
    from torchrl_auv.report.paper.grid import EXPERIMENTS, grid

    columns = {}
    if args.before:
        columns["paper, before"] = _run_before(args, args.before)
    for preset in args.presets:
        columns[preset] = measure_preset(args, preset, Path(args.recipes))
    rows = [
        [
            name,
            f"{c['scenes']:.0f}",
            f"{c['sampler']} {c['steps']:.0f}",
            c["env"],
            c["policy"],
            c["proposer"],
            c["updates"],
            c["frames_per_s"],
            c["first_s"],
        ]
        for name, c in columns.items()
    ]
    print_table(
        f"{args.framework}: ms per frame (1 thread; first = the first decision and update, "
        "compilation included, s)",
        [
            "preset",
            "scenes",
            "sampler",
            "env",
            "policy",
            "of which proposer",
            "updates",
            "frames/s",
            "first (s)",
        ],
        rows,
    )
    base_name = "paper, before" if args.before else "paper"
    base = columns.get(base_name)
    summary = {
        f"{name.replace(', ', '_')}_frames_per_s": c["frames_per_s"] for name, c in columns.items()
    }
    if base is not None:
        ratios = [
            [name, c["frames_per_s"] / base["frames_per_s"]]
            for name, c in columns.items()
            if name != base_name
        ]
        print_table(
            f"frames/s against {base_name} (issue [20/26]'s target for fast: >= 5)",
            ["preset", "ratio"],
            ratios,
        )
        summary.update({f"{name}_vs_{base_name.replace(', ', '_')}": r for name, r in ratios})
    jobs = grid([e for e in EXPERIMENTS if e != "advisor_llm"], seeds=(0, 1, 2))
    trained = [job for job in jobs if job.framework != "diffusion"]
    builders = [job for job in jobs if job.framework == "diffusion"]
    grid_rows = []
    for name, c in columns.items():
        fps = args.fps or c["frames_per_s"]
        # two jobs at a time, one core each; a first stage alone uses both cores
        hours = (
            len(builders) * args.first_stage_min / 60
            + len(jobs) * args.eval_min / 60 / 2
            + len(trained) * args.frames / fps / 3600 / 2
        )
        grid_rows.append([name, len(jobs), len(builders), args.frames, fps, hours])
    print_table(
        "the paper grid (3 seeds) on 2 cores, two jobs at a time",
        ["preset", "jobs", "first stages", "frames per job", "frames/s per job", "hours"],
        grid_rows,
    )
    print_summary("bench_frame_cost", **summary)


if __name__ == "__main__":
    main()
