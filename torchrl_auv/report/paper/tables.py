"""The paper's tables (II, III) and the ablations from a grid's finished jobs.

Each function reads the jobs of its experiment (:func:`~torchrl_auv.report.paper.grid.
experiment_jobs`) under ``root`` and writes ``<name>.md``, ``.csv`` and ``.json`` into
``out_dir`` (:func:`~torchrl_auv.report.paper.output.write_table`); cells are mean ± std over
the seeds whose job finished (``runs``). Metrics are the evaluation's (``eval.csv``: held-out
scenes, deterministic actions): SDR (Mbit), EC (W), SSN, the cost per AUV-decision and the
tracking errors between the controller's setpoints and the true state (rad, m).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path

from torchrl_auv.advisor.trigger import decisions_in_force
from torchrl_auv.report.curves import read_curve
from torchrl_auv.report.paper.grid import (
    ALPHAS,
    CONTROLLERS,
    FIXED_ALPHA,
    FIXED_FORM,
    FORMS,
    FRAMEWORKS,
    MAIN_SEA,
    Job,
)
from torchrl_auv.report.paper.output import (
    first_stage_folder,
    job_rows,
    mean_std,
    window_means,
    write_table,
)
from torchrl_auv.report.paper.published import TABLE2, TABLE3

__all__ = ["ablation_tables", "table2", "table3", "table3_fixed"]

#: the frameworks as the paper names them
LABELS = {
    "sac": "RL (SAC)",
    "diffusion": "Diffusion",
    "diffusion_rl": "Diffusion+RL",
    "diffusion_lac": "Diffusion+RL (LAC)",
}


def table2(root: Path, out_dir: Path, seeds: Sequence[int], header: str) -> list[Path]:
    """Table II: SDR, EC, SSN of Diffusion+RL and Diffusion+RL (LAC) with each controller in
    ES and VES (rows: framework x controller; columns: sea x metric, ours and the paper's)."""
    metrics = ("sdr_mbit", "ec_w", "ssn")
    rows = []
    for framework in ("diffusion_rl", "diffusion_lac"):
        for controller in CONTROLLERS:
            row: dict[str, object] = {"framework": LABELS[framework], "controller": controller}
            for sea in ("es", "ves"):
                jobs = [Job(framework, sea, controller, s) for s in seeds]
                cell = job_rows(root, jobs, None, metrics)
                paper = TABLE2[framework, controller, sea]
                for m in metrics:
                    row[f"{sea} {m}"], row[f"{sea} {m}_std"] = cell[m], cell[f"{m}_std"]
                    row[f"paper {sea} {m}"], row[f"paper {sea} {m}_std"] = paper[m]
                row[f"{sea} runs"] = cell["runs"]
            rows.append(row)
    columns = ["framework", "controller"]
    columns += [
        f"{who}{sea} {m}" for sea in ("es", "ves") for m in metrics for who in ("", "paper ")
    ]
    columns += ["es runs", "ves runs"]
    note = (
        "; SDR: ours is the data delivered per episode (Mbit) at the rate model named, the "
        "paper's is in its own unit (MBit/s) of its link-rate formula"
    )
    return write_table(out_dir, "table2", rows, columns, header=header + note)


def table3(root: Path, out_dir: Path, seeds: Sequence[int], header: str) -> list[Path]:
    """Table III: the mean and (within-episode) standard deviation of the yaw and depth
    tracking errors of the four frameworks with each controller, measured in the
    data-collection evaluation episodes (``MAIN_SEA``), mean ± std over seeds."""
    metrics = ("heading_error_mean", "heading_error_std", "depth_error_mean", "depth_error_std")
    rows = []
    for framework in FRAMEWORKS:
        for controller in CONTROLLERS:
            jobs = [Job(framework, MAIN_SEA, controller, s) for s in seeds]
            paper = {f"paper {m}": v for m, v in TABLE3[framework, controller].items()}
            rows.append(
                {
                    "framework": LABELS[framework],
                    "controller": controller,
                    **job_rows(root, jobs, None, metrics),
                    **paper,
                }
            )
    return write_table(
        out_dir,
        "table3",
        rows,
        ["framework", "controller", "runs", *(c for m in metrics for c in (m, f"paper {m}"))],
        header=header + f"; sea {MAIN_SEA} (the paper names none); errors in rad (heading), "
        "m (depth)",
    )


def table3_fixed(out_dir: Path, header: str, *, runs: int, duration: float, seed: int = 0):
    """The fixed-schedule controller comparison (a separate, labelled experiment: the
    low-level controllers alone tracking a scheduled depth and heading behind the Kalman
    filter, :func:`~torchrl_auv.report.tracking_table`)."""
    from torchrl_auv.report.tracking import tracking_table

    rows, _ = tracking_table(
        CONTROLLERS, ("ideal", "es", "ves"), runs=runs, seed=seed, duration=duration
    )
    columns = [
        "sea_state",
        "controller",
        "heading_error_mean",
        "heading_error_std",
        "depth_error_mean",
        "depth_error_std",
        "kf_rms",
        "usbl_rms",
    ]
    note = (
        f"{header}; fixed schedule, no learning: {runs} runs of {duration:g} s per cell "
        "(not the data-collection episodes of table3)"
    )
    return write_table(out_dir, "table3_fixed", rows, columns, header=note)


def rate_models(
    out_dir: Path,
    header: str,
    *,
    scenes: int,
    steps: int,
    seas: Sequence[str] = ("ideal", "es", "ves"),
    seed: int = 100000,
) -> list[Path]:
    """What the link-rate model does to the paper's metrics (a separate experiment, no
    learning): the scripted expert with S-Surface on ``scenes`` held-out scenes (``seed``) of
    each sea for ``steps`` decisions, with our Shannon rate (``env.rate_model=shannon``, the
    presets') and with the paper's formula (``paper``); beside them the paper's Diffusion+RL
    (LAC), S-Surface numbers of Table II."""
    from torchrl_auv.envs import DataCollectionEnv
    from torchrl_auv.evaluation import episode_stats, make_policy

    rows = []
    for sea in seas:
        for rate_model in ("shannon", "paper"):
            env = DataCollectionEnv(
                batch_size=[scenes], sea_state=sea, rate_model=rate_model, seed=seed
            )
            stats = episode_stats(env, make_policy("expert", env), steps)
            published = TABLE2.get(("diffusion_lac", "s_surface", sea), {})
            rows.append(
                {
                    "sea_state": sea,
                    "rate_model": rate_model,
                    **{k: float(stats[k]) for k in ("sdr_mbit", "ssn", "ec_w")},
                    **{
                        f"paper {k}": published.get(k, (math.nan,))[0]
                        for k in ("sdr_mbit", "ssn", "ec_w")
                    },
                }
            )
    columns = [
        "sea_state",
        "rate_model",
        "sdr_mbit",
        "paper sdr_mbit",
        "ssn",
        "paper ssn",
        "ec_w",
        "paper ec_w",
    ]
    note = (
        f"{header}; the scripted expert (no learning), S-Surface, {scenes} held-out scenes "
        f"x {steps} decisions per sea and rate model; the paper's columns: its Diffusion+RL "
        "(LAC), S-Surface (Table II; it names no ideal-sea numbers)"
    )
    return write_table(out_dir, "rate_models", rows, columns, header=note)


METRICS = ("cost_mean", "sdr_mbit", "ssn", "ec_w", "violation_rate", "terminated")


def _variants(root, seeds, variants):
    rows = []
    for label, variant, values in variants:
        jobs = [Job("diffusion_lac", MAIN_SEA, "s_surface", s, variant, values) for s in seeds]
        rows.append({"variant": label, **job_rows(root, jobs, None, METRICS)})
    return rows


def _ablation_folder(root: Path, seed: int, variant: str) -> Path:
    """The job folder of an ablation's ``variant`` (Diffusion+RL (LAC), ``MAIN_SEA``,
    S-Surface) for ``seed``."""
    return Path(root) / "jobs" / Job("diffusion_lac", MAIN_SEA, "s_surface", seed, variant).name


def ablation_tables(
    root: Path, out_dir: Path, seeds: Sequence[int], header: str, experiment: str
) -> list[Path]:
    """Beyond the paper, the full framework in ``MAIN_SEA``: ``advisor`` (the rule-based
    advisor against the spec fixed at the presets' start and, when the ``advisor_llm``
    experiment ran, a model behind ``advisor.base_url``; with each job's consultations and
    spec changes applied, from its ``advisor.jsonl``), ``lyapunov_cost`` (the stability
    cost against the paper's task cost), ``sampler`` (50 DDPM against 10 DDIM denoising
    steps; the proposer's sampling seconds per decision too), ``fig10`` / ``fig11`` (each
    fixed weight and form)."""
    fixed = f"fixed-{FIXED_FORM}-alpha{FIXED_ALPHA}"
    variants = {
        "advisor": [
            ("rule-based advisor (preset)", "", {}),
            (f"fixed: {FIXED_FORM}, alpha {FIXED_ALPHA}", fixed, {}),
            ("OpenAI-compatible model (experiment advisor_llm)", "openai", {}),
        ],
        "lyapunov_cost": [
            ("stability cost (preset)", "", {}),
            ("task cost (paper)", "task_cost", {}),
        ],
        "sampler": [
            ("the preset's sampler (paper: 50 DDPM)", "", {}),
            ("10 DDIM steps", "ddim10", {}),
        ],
        "fig10": [(f"alpha {a}", f"fixed-{FIXED_FORM}-alpha{a}", {}) for a in ALPHAS],
        "fig11": [(f"form {f}", f"fixed-{f}-alpha{FIXED_ALPHA}", {}) for f in FORMS],
    }[experiment]
    rows = _variants(root, seeds, variants)
    extra, note = [], ""
    if experiment == "advisor":
        for row, (_, variant, _) in zip(rows, variants, strict=True):
            row.update(_advisor_log(root, seeds, variant))
        extra = ["consultations", "spec_changes"]
    if experiment == "lyapunov_cost":
        for row, (_, variant, _) in zip(rows, variants, strict=True):
            row.update(_training_end(root, seeds, variant))
        extra, note = list(TRAINING_END), TRAINING_END_NOTE
    if experiment == "sampler":
        for row, (_, variant, _) in zip(rows, variants, strict=True):
            row.update(_sampling_time(root, variant, seeds[0], earlier=out_dir / "sampler.json"))
        extra = ["sampler", "proposer_s_per_decision", "timed"]
    return write_table(
        out_dir,
        experiment,
        rows,
        ["variant", "runs", *METRICS, *extra],
        header=header + f"; Diffusion+RL (LAC), sea {MAIN_SEA}, S-Surface" + note,
    )


#: the Lyapunov-cost table's training columns -> the ``train_curve.csv`` key each reads
TRAINING_END = {"lambda_end": "train/lambda", "lyapunov_violated_end": "train/violation_rate"}
#: frames at the end of training over which ``lyapunov_violated_end`` is averaged
END_WINDOW = 5000
TRAINING_END_NOTE = (
    "; lambda_end: the Lagrange multiplier at the last training batch (train/lambda; the "
    "presets cap it at lyapunov.lambda_max = 1); lyapunov_violated_end: the share of the "
    "training batches' transitions that violate the Lyapunov condition, mean over the last "
    f"{END_WINDOW:,} frames (train/violation_rate); violation_rate: the env's violations "
    "(outside the area, or too near the seabed or the surface) per AUV-decision on the "
    "held-out scenes"
)


def _training_end(root: Path, seeds: Sequence[int], variant: str) -> dict[str, float]:
    """Over the finished jobs of ``variant`` whose ``train_curve.csv`` logs them: the last
    ``train/lambda`` and the mean ``train/violation_rate`` of the last :data:`END_WINDOW`
    frames (:data:`TRAINING_END`), mean and std over the seeds."""
    values: dict[str, list[float]] = {column: [] for column in TRAINING_END}
    for seed in seeds:
        folder = _ablation_folder(root, seed, variant)
        path = folder / "train_curve.csv"
        if not ((folder / "eval.csv").exists() and path.exists()):
            continue
        curves = read_curve(path)
        _, lam = curves.get(TRAINING_END["lambda_end"], ([], []))
        if lam:
            values["lambda_end"].append(lam[-1])
        violated = window_means(curves, TRAINING_END["lyapunov_violated_end"], END_WINDOW)
        if violated is not None:
            values["lyapunov_violated_end"].append(violated[1])
    out = {}
    for column, found in values.items():
        out[column], out[f"{column}_std"] = mean_std(found)
    return out


#: an applied decision whose alpha differs from the one in force by less than this (relative)
#: and keeps form and prior re-states the spec (a model re-rounding the number): not a change
ALPHA_RTOL = 1e-3


def _changed_spec(record: dict) -> bool:
    """Whether a consultation's decision was applied and changed the form, the prior or alpha
    by more than :data:`ALPHA_RTOL` (a record without the specs: as its ``applied`` says)."""
    before, after = record.get("spec_before"), record.get("decision")
    if not record.get("applied") or not isinstance(before, dict) or not isinstance(after, dict):
        return bool(record.get("applied"))
    if (before.get("form"), before.get("prior")) != (after.get("form"), after.get("prior")):
        return True
    alpha, new = float(before["alpha"]), float(after["alpha"])
    return abs(new - alpha) > ALPHA_RTOL * abs(alpha)


def _advisor_log(root: Path, seeds: Sequence[int], variant: str) -> dict[str, float]:
    """Over the finished jobs of ``variant`` with a decision log (``advisor.jsonl``): the
    consultations and the spec changes per job that stand (a resume's rolled-back ones
    dropped: :func:`~torchrl_auv.advisor.decisions_in_force`; an applied decision that only
    re-states alpha within :data:`ALPHA_RTOL` not counted), mean and std over seeds (NaN
    where no job has a log)."""
    counts = []
    for seed in seeds:
        folder = _ablation_folder(root, seed, variant)
        log = folder / "advisor.jsonl"
        if (folder / "eval.csv").exists() and log.exists():
            records = decisions_in_force(log)
            counts.append((len(records), sum(_changed_spec(r) for r in records)))
    out = {}
    for i, key in enumerate(("consultations", "spec_changes")):
        out[key], out[f"{key}_std"] = mean_std([float(c[i]) for c in counts])
    return out


def _sampling_time(
    root: Path, variant: str, seed: int, repeats: int = 5, *, earlier: Path | None = None
) -> dict:
    """The job's sampler (``.hydra/config.yaml``) and the seconds its proposer (the job's
    first-stage artefact) takes for one decision of both AUVs of a held-out scene: K
    candidates, the median of ``repeats`` timings on this machine's thread count. Where the
    first stage is not on this machine, the time an earlier report measured for the same
    sampler (``earlier``: its ``sampler.json``, which the results store keeps), else NaN."""
    import time

    import torch
    import yaml

    from torchrl_auv.modules import DiffusionProposer
    from torchrl_auv.training import make_history_env

    folder = _ablation_folder(root, seed, variant)
    config = folder / ".hydra" / "config.yaml"
    if not config.exists():
        return {"sampler": "", "proposer_s_per_decision": math.nan, "timed": ""}
    p = yaml.safe_load(config.read_text())["proposer"]
    label = f"{p['sampler']} {p['num_inference_steps']}"
    stage = first_stage_folder(root, MAIN_SEA, seed)
    if stage is None:
        rows = json.loads(earlier.read_text())["rows"] if earlier and earlier.exists() else []
        found = [r["proposer_s_per_decision"] for r in rows if r.get("sampler") == label]
        return {
            "sampler": label,
            "proposer_s_per_decision": found[0] if found else math.nan,
            "timed": "by an earlier report" if found else "",
        }
    proposer = DiffusionProposer.load(stage / "proposer.pt")
    proposer.configure_sampling(
        num_candidates=p["num_candidates"],
        sampler=p["sampler"],
        num_inference_steps=p["num_inference_steps"],
    )
    env = make_history_env(MAIN_SEA, seed=100000, num_envs=1, history=p["history"])
    state = proposer.build_state(env.reset())
    seconds = []
    with torch.no_grad():
        for _ in range(repeats):
            start = time.perf_counter()
            proposer.sample(state)
            seconds.append(time.perf_counter() - start)
    return {
        "sampler": label,
        "proposer_s_per_decision": sorted(seconds)[repeats // 2],
        "timed": "here",
    }
