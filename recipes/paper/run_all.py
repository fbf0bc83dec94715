"""The paper's experiments from one command: their jobs, then their figures and tables.

    .venv/bin/python recipes/paper/run_all.py budget=quick
    .venv/bin/python recipes/paper/run_all.py budget=paper frames=50000 experiments=[fig7,table2]

1. The jobs (``torchrl_auv.report.paper.grid``): the union of the experiments' training runs,
   each once, ``parallel`` at a time, each ``recipes/train.py`` in its own process (its log in
   ``<run_root>/logs/``), grouped by first stage (its builder, then the jobs that reuse it;
   a job waits for its first stage, the other core does not). A job whose ``eval.csv``
   exists is finished and skipped; one with checkpoints is resumed from its newest
   (``resume=``); a failed job is named at the end and the command exits non-zero after
   writing what the others allow.
   With ``store=DIR`` (``results/paper`` for the paper budget) the finished jobs' outputs
   that the report reads are copied into ``DIR`` as each job finishes and back into the run
   folder when the command starts (``torchrl_auv.report.paper.store``): commit ``DIR`` after
   a sitting, and the next sitting, on this machine or another, skips those jobs.
2. The report (``torchrl_auv.report.paper.write_report``): per experiment, under
   ``<run_root>/report/<experiment>/``, PNG figures, a Markdown table, the same as CSV and a
   JSON of every number, each stating the budget and seeds.
3. With ``page=docs/results.md``: the results page from the report (our numbers next to the
   paper's, a verdict per claim, the run's facts; ``torchrl_auv.report.paper.results_page``),
   its figures copied to ``docs/results/``.

``status=true`` runs no job and changes no result: it prints each job's state (finished,
here or in the store; started, with its newest checkpoint's frames; not started), the counts
by framework and the time left at the rate of the sittings recorded in the store
(``torchrl_auv.report.paper.progress``); Hydra still opens its log, ``run_all.log``, in
``run_root``.
"""

from __future__ import annotations

import datetime
import logging
import os
import platform
import subprocess
import sys
import time
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from pathlib import Path

import hydra
from omegaconf import DictConfig, OmegaConf

from torchrl_auv.report.paper import grid, store, write_report
from torchrl_auv.report.paper.output import first_stage_folder
from torchrl_auv.report.paper.progress import format_status, grid_status, job_state
from torchrl_auv.report.paper.results_page import write_results_page

HERE = Path(__file__).resolve().parent
TRAIN = HERE.parent / "train.py"
log = logging.getLogger("run_all")


def run_job(job: grid.Job, cfg: DictConfig, root: Path) -> tuple[str, str, float]:
    """Run (or resume, or skip) one job in its own process; returns (name, state, seconds)."""
    run_dir = root / "jobs" / job.name
    state = job_state(run_dir)
    if state == "done":
        return job.name, "skipped (finished)", 0.0
    overrides = job.overrides(cfg.budget, root=root, frames=cfg.frames)
    if state == "stopped":
        overrides.append(f"resume={run_dir}")
    if job.values.get("advisor.backend") == "openai" and cfg.get("llm_base_url"):
        overrides.append(f"advisor.base_url={cfg.llm_base_url}")
    logfile = root / "logs" / f"{job.name.replace('/', '__')}.log"
    logfile.parent.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    env.setdefault("WANDB_MODE", "offline")
    start = time.perf_counter()
    with open(logfile, "a") as out:
        out.write(f"\n$ {sys.executable} {TRAIN} {' '.join(overrides)}\n")
        out.flush()
        code = subprocess.call(
            [sys.executable, str(TRAIN), *overrides], stdout=out, stderr=subprocess.STDOUT, env=env
        )
    seconds = time.perf_counter() - start
    if code != 0:
        return job.name, f"FAILED (exit {code}; log {logfile})", seconds
    return job.name, "resumed and finished" if state == "stopped" else "finished", seconds


def sync_store(root: Path, stored: Path, jobs: list[grid.Job]) -> None:
    """Before any work: the jobs finished under ``root`` and not yet in the store ``stored``
    go into it (a sitting cut short on this machine), then the stored ones come back."""
    saved = store.save_finished(root, stored, jobs)
    restored = store.restore_finished(stored, root, jobs)
    log.info("store %s: %d files saved, %d restored", stored, len(saved), len(restored))


def run_jobs(jobs: list[grid.Job], cfg: DictConfig, root: Path, stored: Path | None) -> list[str]:
    """Every job (:func:`run_job`) in the grid's order, ``cfg.parallel`` at a time: a free
    core takes the first ready job, so the other core goes on while a first stage builds. A
    job is ready once the builder of its first stage (:func:`grid.first_stage_job`, when it is
    among ``jobs``) has ended and the first stage is built; where that builder ended without
    it (its job was restored from a results store, say) one of its jobs at a time runs, the
    first to start building it; where that builder failed, its jobs fail unrun. With a
    ``stored`` results store, each job is stored as it finishes. Returns the names of the
    jobs that failed."""
    log.info(
        "%d jobs (%s budget) under %s, %d at a time", len(jobs), cfg.budget, root, cfg.parallel
    )
    start, failed = time.perf_counter(), []
    waiting, running = list(jobs), {}
    unended = {job.name for job in jobs}
    now = lambda: datetime.datetime.now(datetime.timezone.utc).isoformat()  # noqa: E731
    sitting = {
        "start": now(),
        "end": None,
        "jobs_finished": 0,
        "machine": platform.node(),
        "parallel": int(cfg.parallel),
    }

    def blocked(job: grid.Job) -> str | None:
        """Why ``job`` cannot start now: ``"wait"``, ``"failed"`` or ``None`` (ready)."""
        builder = grid.first_stage_job(job)
        if builder is None or first_stage_folder(
            root, builder.sea, builder.seed, controller=builder.controller
        ):
            return None
        if builder.name in unended:
            return "wait"
        if builder.name in failed:
            return "failed"
        building = any(grid.first_stage_job(other) == builder for other in running.values())
        return "wait" if building else None

    def ended(job: grid.Job, state: str, seconds: float) -> None:
        unended.discard(job.name)
        done = len(jobs) - len(unended)
        log.info("[%d/%d] %-58s %s (%.0f s)", done, len(jobs), job.name, state, seconds)
        if state.startswith("FAILED"):
            failed.append(job.name)
        elif stored is not None:
            try:
                store.save_finished(root, stored, [job])
                if state.endswith("finished") and not state.startswith("skipped"):
                    sitting.update(end=now(), jobs_finished=sitting["jobs_finished"] + 1)
                    store.record_sitting(stored, sitting)
            except OSError:
                log.exception("%s: storing its outputs in %s failed", job.name, stored)

    with ThreadPoolExecutor(max_workers=int(cfg.parallel)) as pool:
        while waiting or running:
            for job in [job for job in waiting if blocked(job) == "failed"]:
                waiting.remove(job)
                builder = grid.first_stage_job(job).name
                ended(
                    job, f"FAILED (not run: {builder}, which builds its first stage, failed)", 0.0
                )
            while len(running) < int(cfg.parallel):
                job = next((job for job in waiting if blocked(job) is None), None)
                if job is None:
                    break
                waiting.remove(job)
                running[pool.submit(run_job, job, cfg, root)] = job
            if not running:
                if waiting:  # cannot happen: a builder has nothing to wait for
                    raise RuntimeError(f"no job can start: {[j.name for j in waiting]}")
                break
            finished, _ = wait(running, return_when=FIRST_COMPLETED)
            for future in finished:
                job = running.pop(future)
                try:
                    _, state, seconds = future.result()
                except Exception as error:  # the job's process could not even be started
                    log.exception("%s: not run", job.name)
                    state, seconds = f"FAILED ({type(error).__name__}: {error})", 0.0
                ended(job, state, seconds)
    log.info("jobs done in %.1f min", (time.perf_counter() - start) / 60)
    return failed


@hydra.main(config_path=".", config_name="run_all", version_base="1.3")
def main(cfg: DictConfig) -> None:
    if cfg.budget not in grid.BUDGETS:
        raise ValueError(f"budget must be one of {sorted(grid.BUDGETS)}, got {cfg.budget!r}")
    seeds = (
        list(cfg.seeds)
        if cfg.seeds is not None
        else ([0, 1] if cfg.budget == "quick" else [0, 1, 2])
    )
    if cfg.budget == "paper" and cfg.frames is None:
        cfg.frames = 50_000
    experiments = list(cfg.experiments)
    root = Path(cfg.run_root).resolve()
    jobs = grid.grid([e for e in experiments if e in grid.EXPERIMENTS], seeds)
    stored = Path(cfg.store).resolve() if cfg.get("store") else None
    if cfg.get("status"):  # how far the grid has run; nothing is run or written
        sittings = store.read_sittings(stored) if stored else []
        status = grid_status(root, jobs, store=stored, sittings=sittings)
        print(
            f"{len(jobs)} jobs ({cfg.budget} budget, seeds {seeds}) under {root}"
            + (f", results store {stored}" if stored else "")
        )
        print(format_status(status))
        if not (root / "jobs").is_dir():
            print(f"(no jobs/ folder under {root}: is run_root the grid's run folder?)")
        return
    if stored is not None:
        sync_store(root, stored, jobs)
    failed = run_jobs(jobs, cfg, root, stored) if cfg.jobs else []
    if cfg.report:
        written = write_report(
            root,
            experiments,
            seeds=seeds,
            budget=cfg.budget,
            frames=cfg.frames,
            command=" ".join(sys.argv),
            config=OmegaConf.to_container(cfg, resolve=True),
        )
        for path in written:
            log.info("wrote %s", path)
        if stored is not None:  # what the report made from first stages alone (Fig. 5/6)
            store.save_finished(root, stored, jobs, report=True)
    if cfg.get("page"):
        sittings = store.read_sittings(stored) if stored else []
        page = write_results_page(
            root, cfg.page, seeds=seeds, jobs=jobs, experiments=experiments, sittings=sittings
        )
        log.info("wrote the results page %s", page)
    if failed:
        log.error("%d jobs failed: %s", len(failed), ", ".join(failed))
        raise SystemExit(1)


if __name__ == "__main__":
    main()
