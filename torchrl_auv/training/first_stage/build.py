"""Building a first stage (:func:`build_first_stage`): the expert's demonstrations, the
proposer's pretraining and the DAgger rounds, written into one artefact folder. The steps, the
folder's files and how artefacts are keyed and reused: :mod:`~torchrl_auv.training.first_stage`.
"""

from __future__ import annotations

import copy
import csv
import json
import logging
import os
import shutil
import time
from collections.abc import Callable, Mapping
from functools import partial
from pathlib import Path

import torch
from tensordict import TensorDictBase

from torchrl_auv.envs.demonstrations import (
    collect_demonstration_batches,
    load_demonstrations,
    save_demonstrations,
)
from torchrl_auv.modules import DiffusionProposer, ProposerAlone
from torchrl_auv.objectives import pretrain_proposer
from torchrl_auv.training.keys import AGENTS, OBSERVATION

__all__ = ["build_first_stage", "demonstrations_with_env_keys", "untrained_proposer"]

log = logging.getLogger(__name__)


def _noise_model_kwargs(model: Mapping) -> dict:
    if model["noise_model"] == "mlp":
        return {"hidden": model["hidden"], "cond_dim": model["cond_dim"], "depth": model["depth"]}
    return {"channels": (model["hidden"],) * model["depth"], "cond_dim": model["cond_dim"]}


def untrained_proposer(
    obs_dim: int, act_dim: int, *, history: int, horizon: int, model: Mapping
) -> DiffusionProposer:
    """The first stage's proposer before pretraining, on the agents layout: conditioned on the
    observation and its ``history``-long history, chunks of ``horizon`` actions, the noise
    model and schedule of ``model`` (the first-stage values' ``"model"`` group, or a recipe's
    ``proposer`` config group, which has the same keys)."""
    return DiffusionProposer(
        DiffusionProposer.conditioning_dim(obs_dim, act_dim, history),
        act_dim,
        state_key=OBSERVATION,
        history_key=(AGENTS, "history"),
        horizon=horizon,
        noise_model=model["noise_model"],
        noise_model_kwargs=_noise_model_kwargs(model),
        num_train_steps=model["num_train_steps"],
        schedule=model["schedule"],
    )


def _dagger_policy(proposer: DiffusionProposer, env) -> ProposerAlone:
    """The proposer acting alone in a demonstration env (picklable through ``partial``)."""
    return ProposerAlone(proposer, "medoid", action_key=env.base_env.agent_action_key)


def demonstrations_with_env_keys(data: TensorDictBase) -> TensorDictBase:
    """Demonstration samples with the env's keys (the dataset's are flat: ``observation``,
    ``("history", ...)``)."""
    nested = data.empty()
    nested[OBSERVATION] = data["observation"]
    nested[AGENTS, "history"] = data["history"]
    for key in ("action_chunk", "action_chunk_mask", "overridden", "episode"):
        nested[key] = data[key]
    return nested


def _append(data: TensorDictBase, more: TensorDictBase) -> TensorDictBase:
    """``data`` and ``more`` as one dataset, ``more``'s episodes numbered after ``data``'s."""
    more = more.exclude("executed")
    more["episode"] = more["episode"] + int(data["episode"].max()) + 1
    return torch.cat([data, more.select(*data.keys(True, True))])


#: the build's record of its finished phases (in the folder while it builds; removed at the end)
PROGRESS_FILE = "build_progress.json"


def _phase_proposer(folder: Path, phase: str) -> Path:
    return folder / f"proposer_after_{phase}.pt"


def _save(proposer: DiffusionProposer, path: Path) -> None:
    """Save ``proposer`` at ``path`` over what a build cut short may have left there."""
    path.unlink(missing_ok=True)
    proposer.save(path)


def _record(folder: Path, progress: dict) -> None:
    """Write the build's progress atomically (a kill leaves the old record or the new one)."""
    tmp = folder / f"{PROGRESS_FILE}.tmp"
    tmp.write_text(json.dumps(progress, indent=1))
    os.replace(tmp, folder / PROGRESS_FILE)


def _data(
    folder: Path, name: str, collect: Callable[[], TensorDictBase], metadata: Mapping
) -> tuple[TensorDictBase, bool]:
    """The samples saved under ``folder/name`` by a build cut short (``metadata.json`` is
    written last: its presence means they are whole), else collected and saved. Returns
    ``(data, collected)``."""
    out = folder / name
    if (out / "metadata.json").exists():  # read back as saved (without the buffer's "index")
        return load_demonstrations(out)[:].exclude("index").clone(), False
    shutil.rmtree(out, ignore_errors=True)  # a save cut short
    data = collect()
    save_demonstrations(data, out, metadata=dict(metadata))
    return data, True


def build_first_stage(
    folder: str | Path,
    values: Mapping,
    *,
    workers: int = 1,
    plot_loss: Callable | None = None,
) -> dict:
    """Collect the demonstrations, pretrain a proposer, run the DAgger rounds and write the
    artefact into ``folder`` (module docstring). ``workers`` processes collect the batches
    of scenes; ``plot_loss(steps, losses, path, heldout_steps=, heldout_losses=, phases=)``
    (e.g. :func:`torchrl_auv.report.plot_pretraining_loss`) draws ``loss.png``. Returns the
    metrics written to ``metrics.json``.

    A build cut short goes on from its last finished phase when called again on the same
    folder (:meth:`ArtefactCache.get_or_build` with ``resumable=True`` hands it over): the
    saved demonstrations and DAgger samples are loaded instead of collected, and the proposer
    after each training phase is loaded instead of trained, so the artefact is the one an
    uninterrupted build writes (every phase draws from its own seeds).
    """
    folder = Path(folder)
    demo, model, train = values["demonstrations"], values["model"], values["pretraining"]
    dagger = values["dagger"]
    collect = partial(
        collect_demonstration_batches,
        workers=workers,
        seed=values["seed"],
        env="data_collection",
        episodes=demo["demo_episodes"],
        max_steps=demo["demo_steps"],
        horizon=demo["horizon"],
        history=demo["history"],
        sea_state=values["sea_state"],
        controller=values["controller"],
        rate_model=values["rate_model"],
    )
    progress = {
        "done": [],
        "metrics": {},
        "phases": [],
        "curve": {"phase": [], "step": [], "split": [], "loss": []},
    }
    if (folder / PROGRESS_FILE).exists():
        progress = json.loads((folder / PROGRESS_FILE).read_text())
    if progress["done"]:
        log.info("first stage: going on after %s", ", ".join(progress["done"]))
    metrics, curve = progress["metrics"], progress["curve"]
    phases: list[tuple[int, str]] = [tuple(phase) for phase in progress["phases"]]

    start = time.perf_counter()
    data, collected = _data(folder, "demonstrations", lambda: collect(demo["demo_batches"]), values)
    if collected:
        metrics["demonstrations_s"] = time.perf_counter() - start
    metrics.setdefault("samples", len(data))
    metrics.setdefault("overridden_samples", int(data["overridden"].sum()))
    _record(folder, progress)
    obs_dim, act_dim = data["observation"].shape[-1], data["action"].shape[-1]
    proposer = untrained_proposer(
        obs_dim, act_dim, history=demo["history"], horizon=demo["horizon"], model=model
    )

    def fit(phase: str, steps: int, lr: float, first: bool) -> float:
        """Train on ``data`` (fitting the state standardisation the first time); add the
        curves to ``curve`` after the steps so far; return the held-out loss. A phase that a
        build cut short had finished is loaded instead (its proposer, curve and metrics)."""
        nonlocal proposer
        if phase in progress["done"]:
            proposer = DiffusionProposer.load(_phase_proposer(folder, phase))
            return metrics[f"{phase}_heldout_loss"]
        offset = curve["step"][-1] if curve["step"] else 0
        phases.append((offset, phase))
        began = time.perf_counter()
        with torch.random.fork_rng():  # the replay buffer's sampler draws from the global RNG
            torch.manual_seed(values["seed"] + len(phases))
            result = pretrain_proposer(
                proposer,
                demonstrations_with_env_keys(data),
                steps=steps,
                batch_size=train["batch_size"],
                lr=lr,
                lr_schedule=train["lr_schedule"],
                weight_decay=train["weight_decay"],
                ema_decay=train["ema_decay"],
                normalize_state=first and train["normalize_state"],
                heldout_fraction=train["heldout_fraction"],
                seed=values["seed"],
                log_every=max(1, steps // 100),
                eval_every=max(1, steps // 10),
            )
        metrics[f"{phase}_s"] = time.perf_counter() - began
        metrics[f"{phase}_heldout_loss"] = result.heldout_loss
        for split, steps_, losses in (
            ("train", result.steps, result.losses),
            ("heldout", result.heldout_steps, result.heldout_losses),
        ):
            for step, value in zip(steps_, losses, strict=True):
                curve["phase"].append(phase)
                curve["step"].append(offset + step)
                curve["split"].append(split)
                curve["loss"].append(value)
        log.info(
            "first stage: %s, %d samples, %d steps in %.0f s, held-out loss %.4f",
            phase,
            len(data),
            steps,
            metrics[f"{phase}_s"],
            result.heldout_loss,
        )
        _save(proposer, _phase_proposer(folder, phase))
        progress["done"].append(phase)
        progress["phases"] = [list(p) for p in phases]
        _record(folder, progress)
        return result.heldout_loss

    fit("pretraining", train["pretrain_steps"], train["lr"], first=True)
    proposer.use_ema = train["ema_decay"] is not None
    if dagger["dagger_rounds"]:
        _save(proposer, folder / "proposer_bc.pt")  # before DAgger: behaviour cloning alone
    for r in range(1, dagger["dagger_rounds"] + 1):
        actor = copy.deepcopy(proposer)
        actor.configure_sampling(
            num_inference_steps=dagger["dagger_inference_steps"], sampler="ddim"
        )
        start = time.perf_counter()
        first_batch = demo["demo_batches"] + (r - 1) * dagger["dagger_batches"]
        visited, collected = _data(
            folder,
            f"dagger{r}",
            lambda first_batch=first_batch, actor=actor: collect(
                dagger["dagger_batches"],
                first_batch=first_batch,
                policy=partial(_dagger_policy, actor),
            ),
            {**values, "round": r},
        )
        if collected:
            metrics[f"dagger{r}_collection_s"] = time.perf_counter() - start
        metrics.setdefault(f"dagger{r}_samples", len(visited))
        _record(folder, progress)
        data = _append(data, visited)
        fit(f"dagger{r}", dagger["dagger_steps"], dagger["dagger_lr"], first=False)
    proposer.save(folder / "proposer.pt")
    with open(folder / "pretrain_loss.csv", "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(("step", "split", "loss", "phase"))
        writer.writerows(
            zip(curve["step"], curve["split"], curve["loss"], curve["phase"], strict=True)
        )
    if plot_loss is not None:
        split = [s == "train" for s in curve["split"]]
        pick = lambda key, keep: [v for v, k in zip(curve[key], split, strict=True) if k == keep]  # noqa: E731
        plot_loss(
            pick("step", True),
            pick("loss", True),
            folder / "loss.png",
            heldout_steps=pick("step", False),
            heldout_losses=pick("loss", False),
            phases=phases,
        )
    losses = [v for v, s in zip(curve["loss"], curve["split"], strict=True) if s == "train"]
    metrics.update(
        final_training_loss=losses[-1],
        training_samples=len(data),
        heldout_loss=metrics[f"dagger{dagger['dagger_rounds']}_heldout_loss"]
        if dagger["dagger_rounds"]
        else metrics["pretraining_heldout_loss"],
    )
    (folder / "metrics.json").write_text(json.dumps(metrics, indent=2))
    for phase, _ in phases:  # the build's own records: the artefact keeps what it always held
        _phase_proposer(folder, phase).unlink(missing_ok=True)
    (folder / PROGRESS_FILE).unlink(missing_ok=True)
    return metrics
