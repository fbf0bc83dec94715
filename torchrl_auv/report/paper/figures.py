"""The paper's figures (4, 5/6, 7, 8/9, 10/11) from a grid's finished jobs (PNG + numbers).

Every function writes its PNG and the numbers behind it (``.csv``, ``.json``, ``.md`` through
:func:`~torchrl_auv.report.paper.output.write_table`) into ``out_dir`` and returns the paths.
Bands are ± one standard deviation: over seeds (Fig. 7, 8/9) or over the episodes of every
seed (Fig. 10/11, one episode per held-out scene and AUV).
"""

from __future__ import annotations

import csv
import math
import statistics
from collections.abc import Sequence
from fnmatch import fnmatch
from pathlib import Path

import torch

from torchrl_auv.report.curves import read_curve
from torchrl_auv.report.paper.grid import (
    ALPHAS,
    FIXED_ALPHA,
    FIXED_FORM,
    FORMS,
    MAIN_SEA,
    SEAS,
    Job,
)
from torchrl_auv.report.paper.output import (
    first_stage_folder,
    first_stage_pattern,
    job_rows,
    mean_std,
    write_table,
)
from torchrl_auv.report.paper.published import FIG8_RETURN_E3, FIG9
from torchrl_auv.report.paper.tables import LABELS
from torchrl_auv.report.pyplot import pyplot

__all__ = [
    "fig4",
    "fig5_6",
    "fig7",
    "fig8_9",
    "fig10_11",
    "lyapunov_trace",
    "pool_traces",
    "tenth_means",
]


def _plt():
    return pyplot()


def _save(fig, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    _plt().close(fig)
    return path


def fig4(root: Path, out_dir: Path, seeds: Sequence[int], header: str) -> list[Path]:
    """Fig. 4: the proposer's denoising loss (training and held-out) against optimiser steps
    in each sea (first seed), log scale, with an inset of the final fifth; the table: the
    final held-out loss per sea, mean ± std over seeds."""
    plt = _plt()
    fig, axes = plt.subplots(1, len(SEAS), figsize=(4.2 * len(SEAS), 3.4), squeeze=False)
    rows = []
    for ax, sea in zip(axes[0], SEAS, strict=True):
        finals = []
        for seed in seeds:
            folder = first_stage_folder(root, sea, seed, records=True)
            if folder is None:
                continue
            curve = {"train": ([], []), "heldout": ([], [])}
            with open(folder / "pretrain_loss.csv", newline="") as handle:
                for row in csv.DictReader(handle):
                    if row["split"] in curve:
                        curve[row["split"]][0].append(int(row["step"]))
                        curve[row["split"]][1].append(float(row["loss"]))
            if curve["heldout"][1]:
                finals.append(curve["heldout"][1][-1])
            if seed != seeds[0]:
                continue
            inset = ax.inset_axes([0.45, 0.45, 0.5, 0.45])
            for split, (steps, losses) in curve.items():
                ax.plot(steps, losses, label=split)
                tail = [i for i, s in enumerate(steps) if s >= 0.8 * max(steps or [0])]
                inset.plot([steps[i] for i in tail], [losses[i] for i in tail])
            inset.set_title("final fifth", fontsize="small")
            inset.tick_params(labelsize="x-small")
        ax.set_yscale("log")
        ax.set_title(f"{sea}")
        ax.set_xlabel("optimiser step")
        mean, std = mean_std(finals)
        rows.append(
            {"sea_state": sea, "runs": len(finals), "heldout_loss": mean, "heldout_loss_std": std}
        )
    axes[0, 0].set_ylabel("denoising loss")
    axes[0, 0].legend(loc="lower left", fontsize="small")
    paths = [_save(fig, Path(out_dir) / "fig4.png")]
    return paths + write_table(
        out_dir,
        "fig4",
        rows,
        ["sea_state", "runs", "heldout_loss"],
        header=header + "; held-out denoising loss at the end of the first stage",
    )


def fig5_6(root: Path, out_dir: Path, seeds: Sequence[int], header: str) -> list[Path]:
    """Fig. 5/6: the K candidates of the first seed's ``MAIN_SEA`` proposer, from the first
    state of a held-out scene, at three denoising stages (early, middle, final), each rolled
    out through the vehicles (:func:`~torchrl_auv.report.candidate_rollouts.
    roll_out_candidates`): Fig. 5 the top view of the first AUV's paths, Fig. 6 both AUVs in
    3-D; ``fig5_6.json`` holds the chunks and the paths (m, NED). Where the first stage is
    not on this machine, the paths of an earlier report's ``fig5_6.json`` in ``out_dir`` (the
    results store restores it) are plotted again."""
    import json

    from torchrl_auv.modules import DiffusionProposer
    from torchrl_auv.report.candidate_rollouts import roll_out_candidates
    from torchrl_auv.training import make_history_env

    folder = first_stage_folder(root, MAIN_SEA, seeds[0])
    data = Path(out_dir) / "fig5_6.json"
    if folder is None:
        # the first stage is not on this machine: the rollouts of an earlier report (restored
        # from the results store), which depend on the first stage alone
        if not data.exists():
            return []
        stored = json.loads(data.read_text())
        if not fnmatch(Path(stored["artefact"]).name, first_stage_pattern(MAIN_SEA, seeds[0])):
            return []  # another first stage's rollouts
        return [*_plot_fig5_6(stored["paths_ned_m"], stored["stages"], Path(out_dir)), data]
    proposer = DiffusionProposer.load(folder / "proposer.pt")
    values = json.loads((folder / "values.json").read_text())
    history = values["demonstrations"]["history"]

    def make(n):
        return make_history_env(
            MAIN_SEA,
            seed=100000,
            num_envs=n,
            history=history,
            controller=values["controller"],
            rate_model=values["rate_model"],
        )

    with torch.no_grad():
        state = proposer.build_state(make(1).reset())
        _, stages = proposer.sample(state, generator=torch.Generator().manual_seed(0), num_stages=3)
    chunks = stages[0].permute(1, 2, 0, 3, 4)  # [N, S, K, H, A] -> [S, K, N, H, A]
    paths = roll_out_candidates(make, chunks)  # [S, K, H + 1, N, 3]
    labels = ["early", "middle", "final"]
    written = _plot_fig5_6(paths.tolist(), labels, Path(out_dir))
    data.write_text(
        json.dumps(
            {
                "header": header,
                "artefact": str(folder),
                "stages": labels,
                "chunks": chunks.tolist(),
                "paths_ned_m": paths.tolist(),
            }
        )
    )
    return [*written, data]


def _plot_fig5_6(paths: list, labels: Sequence[str], out_dir: Path) -> list[Path]:
    """Fig. 5 (top view of the first AUV) and Fig. 6 (3-D, both AUVs) from the candidates'
    rolled-out positions ``paths[stage][candidate][step][auv] = (north, east, down)`` (m)."""
    paths = torch.as_tensor(paths)
    plt = _plt()
    fig, axes = plt.subplots(1, 3, figsize=(11, 3.8), squeeze=False)
    for s, ax in enumerate(axes[0]):
        for k in range(paths.shape[1]):
            ax.plot(paths[s, k, :, 0, 1], paths[s, k, :, 0, 0], marker=".", label=f"candidate {k}")
        ax.set_title(f"{labels[s]} stage")
        ax.set_xlabel("east (m)")
        ax.set_aspect("equal", adjustable="datalim")
    axes[0, 0].set_ylabel("north (m)")
    axes[0, -1].legend(fontsize="x-small")
    written = [_save(fig, out_dir / "fig5.png")]
    fig = plt.figure(figsize=(11, 3.8))
    for s in range(3):
        ax = fig.add_subplot(1, 3, s + 1, projection="3d")
        for auv in range(paths.shape[3]):
            for k in range(paths.shape[1]):
                p = paths[s, k, :, auv]
                ax.plot(p[:, 1], p[:, 0], p[:, 2], color=f"C{auv}", alpha=0.8)
        ax.set_title(f"{labels[s]} stage (AUV 1: C0, AUV 2: C1)", fontsize="small")
        ax.set_xlabel("east (m)")
        ax.set_ylabel("north (m)")
        ax.set_zlabel("depth (m)")
        ax.invert_zaxis()
    written.append(_save(fig, out_dir / "fig6.png"))
    return written


CURVE_KEYS = (
    ("eval/cost_mean", "cost per AUV-decision"),
    ("eval/sdr_mbit", "SDR (Mbit)"),
    ("eval/ssn", "SSN"),
    ("eval/ec_w", "EC (W)"),
)
#: the training-time curves (``train_curve.csv``: the collected batches, exploration on; the
#: env logs no episode EC) and the width of their bins (frames)
TRAIN_CURVE_KEYS = (
    ("train/cost_mean", "cost per AUV-decision"),
    ("train/episode_sdr", "SDR (Mbit) per episode"),
    ("train/episode_ssn", "SSN per episode"),
)
TRAIN_BIN_FRAMES = 5000


def fig7(root: Path, out_dir: Path, seeds: Sequence[int], header: str) -> list[Path]:
    """Fig. 7: the evaluation learning curves (``eval_curve.csv``: the policy being trained,
    deterministic, on held-out scenes of its sea) of RL, Diffusion+RL and Diffusion+RL (LAC)
    in each sea; mean and band over seeds, a marker per evaluation, the runs per line in the
    legend, "not run yet" on a panel without any. The paper plots the return: here its
    per-decision form, the cost per AUV-decision (lower is better). Only finished jobs
    (``eval.csv`` written) are read, so the figure is the same wherever the results store
    is.

    Beside it, ``fig7_training``: the curves of the training itself (``train_curve.csv``, as
    the paper's Fig. 7 plots its training episodes), exploration on: each collected batch's
    cost per AUV-decision and, where episodes ended in it, their mean SDR and SSN; each
    seed's batches averaged in bins of :data:`TRAIN_BIN_FRAMES` frames (episodes end
    irregularly), then mean and band over seeds."""
    written = []
    training = (
        f"training curves, not on held-out scenes: the collected batches, exploration "
        f"on, averaged in {TRAIN_BIN_FRAMES:,}-frame bins (frames: a bin's end, or the "
        "job's last)"
    )
    for name, file, keys, bins, what, title in (
        ("fig7", "eval_curve.csv", CURVE_KEYS, None, "evaluation curves", None),
        (
            "fig7_training",
            "train_curve.csv",
            TRAIN_CURVE_KEYS,
            TRAIN_BIN_FRAMES,
            training,
            "Training curves: the collected batches, exploration on (not held-out scenes)",
        ),
    ):
        fig, rows = _curve_panels(root, seeds, file, keys, bins)
        if title:
            fig.suptitle(title)
        written.append(_save(fig, Path(out_dir) / f"{name}.png"))
        written += write_table(
            out_dir,
            name,
            rows,
            ["sea_state", "framework", "metric", "frames", "runs", "value"],
            header=header + f"; {what}, mean ± std over seeds",
        )
    return written


def _binned(run: dict[int, float], width: int | None, last: int) -> dict[int, float]:
    """``{step: value}`` averaged in bins of ``width`` frames, each named by its end (steps
    1..width go to ``width``, step 0 to 0) or by ``last`` (the job's last frame), whichever
    is less; ``None``: as it is."""
    if width is None:
        return run
    bins: dict[int, list[float]] = {}
    for step, value in run.items():
        bins.setdefault(min(-(-step // width) * width, last), []).append(value)
    return {step: statistics.fmean(values) for step, values in bins.items()}


def _curve_panels(root: Path, seeds: Sequence[int], file: str, keys, width: int | None):
    """A (metric x sea) grid of curves of the finished jobs' ``file`` for the Fig. 7
    frameworks: mean and band over seeds at each step (bins of ``width`` frames). Returns
    the figure and its rows."""
    plt = _plt()
    fig, axes = plt.subplots(
        len(keys),
        len(SEAS),
        figsize=(4.2 * len(SEAS), 2.25 * len(keys)),
        squeeze=False,
        sharex="col",
    )
    colours = dict(zip(("sac", "diffusion_rl", "diffusion_lac"), ("C0", "C1", "C2"), strict=True))
    rows = []
    for j, sea in enumerate(SEAS):
        for framework, colour in colours.items():
            curves = [
                Path(root) / "jobs" / Job(framework, sea, "s_surface", s).name / file for s in seeds
            ]
            # finished jobs only: a running job's curve stops short (and is not stored)
            curves = [
                read_curve(c) for c in curves if c.exists() and (c.parent / "eval.csv").exists()
            ]
            lasts = [max((max(s) for s, _ in c.values()), default=0) for c in curves]  # last frame
            for i, (key, label) in enumerate(keys):
                runs = [
                    _binned(dict(zip(*c[key], strict=True)), width, last)
                    for c, last in zip(curves, lasts, strict=True)
                    if key in c
                ]
                axes[i, 0].set_ylabel(label)
                if not runs:
                    continue
                steps = sorted(set().union(*runs))
                stats = [mean_std([r[s] for r in runs if s in r]) for s in steps]
                mean = [m for m, _ in stats]
                std = [d for _, d in stats]
                name = f"{LABELS[framework]} ({len(runs)} of {len(seeds)})"
                axes[i, j].plot(steps, mean, marker="o", markersize=3, color=colour, label=name)
                axes[i, j].fill_between(
                    steps,
                    [m - d for m, d in zip(mean, std, strict=True)],
                    [m + d for m, d in zip(mean, std, strict=True)],
                    color=colour,
                    alpha=0.2,
                )
                rows += [
                    {
                        "sea_state": sea,
                        "framework": LABELS[framework],
                        "metric": key,
                        "frames": s,
                        "runs": sum(s in r for r in runs),
                        "value": m,
                        "value_std": d,
                    }
                    for s, m, d in zip(steps, mean, std, strict=True)
                ]
        axes[0, j].set_title(sea)
        axes[-1, j].set_xlabel("frames")
        if axes[0, j].lines:
            axes[0, j].legend(fontsize="small", title="runs of the seeds", title_fontsize="small")
        if not any(ax.lines for ax in axes[:, j]):  # the column shares its x axis
            axes[-1, j].set_xticks([])
        for ax in axes[:, j]:
            if not ax.lines:
                ax.set_yticks([])
                ax.text(
                    0.5,
                    0.5,
                    "not run yet",
                    ha="center",
                    va="center",
                    transform=ax.transAxes,
                    color="0.5",
                )
    return fig, rows


RANKS = ("OA", "CA1", "CA2", "CA3", "CA4", "RL")
#: Fig. 8/9's reference rows (not in the paper): the same jobs' proposer alone (the medoid of
#: its own ``proposer.alone_candidates`` draws, 10 in the paper presets, where the selection
#: ranks K = 5; no critic), the scripted expert and random actions
REFERENCES = ("proposer alone", "expert", "random")
BAR_TITLES = {
    "return": "episode return",
    **{key.removeprefix("eval/"): label for key, label in CURVE_KEYS},
}


def fig8_9(root: Path, out_dir: Path, seeds: Sequence[int], header: str) -> list[Path]:
    """Fig. 8/9: the full framework's selection executed at a fixed rank (OA: the lowest L,
    its own choice; CA1-CA4: the next ranks) and its actor alone (RL (LAC)) on the same
    held-out scenes: the episode return (minus the cost per AUV over the episode), SDR, SSN
    and EC, mean ± std over seeds (``MAIN_SEA``, S-Surface); then, in grey and not in the
    paper, the same jobs' :data:`REFERENCES` rows."""
    plt = _plt()
    from matplotlib.patches import Patch

    metrics = ("return", "sdr_mbit", "ssn", "ec_w")
    jobs = [Job("diffusion_lac", MAIN_SEA, "s_surface", s) for s in seeds]
    rows = []
    names = {"RL": "RL (LAC)", **{policy: f"{policy} (reference)" for policy in REFERENCES}}
    for policy in RANKS + REFERENCES:
        cell = job_rows(root, jobs, policy, ("return", "terminated", *metrics[1:]))
        cell["ended early"], cell["ended early_std"] = cell["terminated"], cell["terminated_std"]
        paper = {f"paper {m}": FIG9.get(policy, {}).get(m, math.nan) for m in metrics[1:]}
        rows.append(
            {
                "policy": names.get(policy, policy),
                **cell,
                "paper return (x 1e3)": FIG8_RETURN_E3.get(policy, math.nan),
                **paper,
            }
        )
    colours = ["C0"] * len(RANKS) + ["0.6"] * len(REFERENCES)
    fig, axes = plt.subplots(1, len(metrics), figsize=(4.0 * len(metrics), 3.6), squeeze=False)
    for ax, metric in zip(axes[0], metrics, strict=True):
        ran = [r for r in rows if math.isfinite(r[metric])]
        # NaN (a row not run, the std of one seed) draws no bar and no error bar, not a 0
        ax.bar(
            [r["policy"].removesuffix(" (reference)") for r in rows],
            [r[metric] for r in rows],
            yerr=[r[f"{metric}_std"] for r in rows],
            capsize=3,
            color=colours,
        )
        if len(ran) < len(rows):
            ax.text(
                0.5,
                0.5,
                "not run yet" if not ran else "–: not run yet",
                ha="center",
                va="center",
                transform=ax.transAxes,
                color="0.5",
            )
        if not ran:
            ax.set_yticks([])
        ax.set_title(BAR_TITLES[metric])
        plt.setp(ax.get_xticklabels(), rotation=45, ha="right", rotation_mode="anchor")
    grey = Patch(color="0.6", label="reference (not in the paper)")
    fig.legend(handles=[grey], fontsize="small", loc="lower left", frameon=False)
    paths = [_save(fig, Path(out_dir) / "fig8_9.png")]
    return paths + write_table(
        out_dir,
        "fig8_9",
        rows,
        [
            "policy",
            "runs",
            "return",
            "paper return (x 1e3)",
            "ended early",
            *(c for m in metrics[1:] for c in (m, f"paper {m}")),
        ],
        header=header + f"; sea {MAIN_SEA}; return = -cost per AUV summed over the episode "
        "(each seed's cost per AUV-decision x its decisions, the means over its scenes, so "
        "not exact where its scenes ended at different decisions; then mean ± std over the "
        "seeds; "
        "the paper's return is on its own reward scale, and its column is in the paper's unit "
        "of 1e3); ended early: the share of the held-out scenes whose episode an AUV ended "
        "(more than 100 m outside the area, or a diverged state): such an episode sums fewer "
        "decisions, so its return can be higher than a full episode's despite the termination "
        "cost (which is set against discounted sums, gamma <= 0.99, not the undiscounted "
        "1000-decision sum); RL (LAC): the job's own actor alone, trained beside the selection "
        "but not executed by it (selection.include_actor=false in the paper presets); the paper's "
        "SDR is in its own unit (MBit/s) of its link-rate formula (Fig. 9: no CA3 numbers, EC "
        "for OA and CA4 only); reference rows (not in the paper): the same jobs' proposer alone "
        "(the medoid of its proposer.alone_candidates draws, no critic), scripted expert and "
        "random actions",
    )


def lyapunov_trace(root: Path, job: Job) -> dict[str, list[float]] | None:
    """The job's ``lyapunov_trace.csv``: per decision of the held-out episodes, the mean and
    std over episodes of the executed candidate's Lyapunov value, and the episodes counted;
    ``None`` when the job wrote none."""
    path = Path(root) / "jobs" / job.name / "lyapunov_trace.csv"
    if not path.exists():
        return None
    out = {"mean": [], "std": [], "episodes": []}
    with open(path, newline="") as handle:
        for row in csv.DictReader(handle):
            for key in out:
                out[key].append(float(row[key]))
    return out


def pool_traces(traces: Sequence[dict[str, list[float]]]) -> dict[str, list[float]]:
    """Traces of :func:`lyapunov_trace` (e.g. one per seed) as one: per decision, the mean and
    the sample std (n - 1, as each trace's) over every episode still running in any of them,
    and their number; a trace shorter than the longest counts no episode beyond its end; NaN
    where none runs, std 0 where one does."""
    out = {"mean": [], "std": [], "episodes": []}
    for i in range(max((len(t["mean"]) for t in traces), default=0)):
        parts = [
            (t["mean"][i], t["std"][i], t["episodes"][i])
            for t in traces
            if i < len(t["mean"]) and t["episodes"][i] > 0
        ]
        count = sum(n for _, _, n in parts)
        mean = sum(m * n for m, _, n in parts) / count if count else math.nan
        # within each trace (n - 1) s^2, between them n (m - mean)^2: the episodes' squares
        square = sum((n - 1) * s**2 + n * (m - mean) ** 2 for m, s, n in parts)
        out["mean"].append(mean)
        out["std"].append(
            math.sqrt(square / (count - 1)) if count > 1 else (0.0 if count else math.nan)
        )
        out["episodes"].append(float(count))
    return out


def tenth_means(trace: dict[str, list[float]]) -> tuple[float, float]:
    """The mean of ``trace`` (:func:`lyapunov_trace` or :func:`pool_traces`) over its first
    and over its last tenth of the decisions with an episode running, each decision weighed
    by how many (episodes that end early leave fewer behind); NaN for an empty trace."""
    running = [(m, n) for m, n in zip(trace["mean"], trace["episodes"], strict=True) if n > 0]
    if not running:
        return math.nan, math.nan
    tenth = max(1, len(running) // 10)

    def pooled(part):
        return sum(m * n for m, n in part) / sum(n for _, n in part)

    return pooled(running[:tenth]), pooled(running[-tenth:])


def fig10_11(
    root: Path, out_dir: Path, seeds: Sequence[int], header: str, experiment: str
) -> list[Path]:
    """Fig. 10 (``experiment="fig10"``: the weight alpha) or Fig. 11 (``"fig11"``: the form):
    the executed candidate's Lyapunov value along held-out episodes (``lyapunov_trace.csv``
    of each job), per decision the mean over every episode of every seed still running and a
    ± one std band (:func:`pool_traces`); the table's first and last tenth by
    :func:`tenth_means`."""
    plt = _plt()
    variants = (
        [(f"alpha {a}", FIXED_FORM, a) for a in ALPHAS]
        if experiment == "fig10"
        else [(f"form {f}", f, FIXED_ALPHA) for f in FORMS]
    )
    fig, ax = plt.subplots(figsize=(6.5, 3.6))
    rows = []
    for label, form, alpha in variants:
        traces = [
            lyapunov_trace(
                root, Job("diffusion_lac", MAIN_SEA, "s_surface", s, f"fixed-{form}-alpha{alpha}")
            )
            for s in seeds
        ]
        traces = [t for t in traces if t is not None]
        if not traces:
            continue
        pooled = pool_traces(traces)
        mean, spread, length = pooled["mean"], pooled["std"], len(pooled["mean"])
        (line,) = ax.plot(range(length), mean, label=f"{label} ({len(traces)} of {len(seeds)})")
        ax.fill_between(
            range(length),
            [m - s for m, s in zip(mean, spread, strict=True)],
            [m + s for m, s in zip(mean, spread, strict=True)],
            color=line.get_color(),
            alpha=0.15,
        )
        first, last = tenth_means(pooled)
        running = sum(n > 0 for n in pooled["episodes"])  # decisions with an episode on
        rows.append(
            {
                "variant": label,
                "runs": len(traces),
                "decisions": running,
                "L_first_tenth": first,
                "L_last_tenth": last,
            }
        )
    ax.set_xlabel("decision")
    ax.set_ylabel("L(s, a) of the executed action")
    if ax.lines:
        ax.legend(fontsize="small", title="runs of the seeds", title_fontsize="small")
    else:
        ax.text(
            0.5, 0.5, "not run yet", ha="center", va="center", transform=ax.transAxes, color="0.5"
        )
    paths = [_save(fig, Path(out_dir) / f"{experiment}.png")]
    return paths + write_table(
        out_dir,
        f"{experiment}_lyapunov",
        rows,
        ["variant", "runs", "decisions", "L_first_tenth", "L_last_tenth"],
        header=header + f"; sea {MAIN_SEA}; Lyapunov value along held-out episodes",
    )
