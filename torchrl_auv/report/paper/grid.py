"""The paper's experiments (§IV) as training jobs: which runs each figure and table needs.

Every experiment names the jobs it reads (:func:`experiment_jobs`); a job is one run of
``recipes/train.py`` (framework, sea state, low-level controller, seed and, for the
ablations, a variant such as a fixed Lyapunov weight). Experiments share jobs: Fig. 7's
Diffusion+RL (LAC) runs in ES and VES with the S-Surface controller are Table II's S-Surface
rows, Table III's VES rows and Fig. 8/9's runs; :func:`grid` is the union, each job once.
Jobs are named by their values, ``<framework>/<sea>/<controller>[/<variant>]/seed<s>``, and
write to ``<root>/jobs/<name>``; every diffusion job shares the first stage of its (sea,
controller, rate model, seed) through ``<root>/first_stage``.

A *budget* is the overrides every job gets: :data:`BUDGETS` ``"quick"`` (the quick presets cut
to a few hundred frames: the machinery end to end, in minutes, numbers that mean nothing) and
``"paper"`` (the paper presets; ``frames`` per job). Each job evaluates in its own sea only.

Examples:
    >>> jobs = grid(["fig7", "table2"], seeds=(0,))
    >>> len(jobs), jobs[0].name
    (24, 'diffusion/ideal/s_surface/seed0')
    >>> job = experiment_jobs("fig10", seeds=(0,))[0]
    >>> job.name, job.values["lyapunov.stability_weight"]
    ('diffusion_lac/ves/s_surface/fixed-softplus-alpha0.05/seed0', 0.05)
    >>> overrides = job.overrides("quick", root="/tmp/p")
    >>> "framework=diffusion_lac" in overrides, "preset=quick" in overrides
    (True, True)
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

__all__ = [
    "BUDGETS",
    "EXPERIMENTS",
    "FRAMEWORKS",
    "Job",
    "experiment_jobs",
    "first_stage_job",
    "grid",
]

#: The recipes a job can run (``framework=``): the RL baseline, the proposer alone and the two
#: frameworks built on it.
FRAMEWORKS = ("sac", "diffusion", "diffusion_rl", "diffusion_lac")
SEAS = ("ideal", "es", "ves")
CONTROLLERS = ("s_surface", "pid", "smc")
#: The fixed Lyapunov spec of Fig. 10 (form) and Fig. 11 (weight) and of the advisor
#: ablation: the presets' spec before the advisor's first consultation
FIXED_FORM, FIXED_ALPHA = "softplus", 0.1
ALPHAS = (0.05, 0.1, 0.25, 0.5)
FORMS = ("softplus", "squared", "log")
#: The sea of the experiments the paper runs in one sea (Table III, Fig. 8-11, ablations).
MAIN_SEA = "ves"

#: What every job of a budget gets, by config group (a group a framework lacks is skipped:
#: SAC has no proposer). ``quick``: a few hundred frames of the quick presets; ``paper``: the
#: paper presets, ``collector.total_frames`` from the grid's ``frames``.
BUDGETS: dict[str, dict[str, dict[str, object]]] = {
    "quick": {
        "": {"preset": "quick", "logger.backend": "csv"},
        "env": {"env.max_steps": 100, "env.num_envs": 2},
        "collector": {"collector.total_frames": 200, "collector.frames_per_batch": 100},
        "sac": {"collector.init_random_frames": 100},
        "optim": {"optim.updates_per_batch": 5},
        "checkpoint": {"checkpoint.every_frames": 100},
        "eval": {
            "eval.steps": 50,
            "eval.num_envs": 2,
            "eval.every_frames": 100,
            "eval.curve_steps": 50,
            "eval.curve_envs": 1,
            "eval.workers": 1,
        },
        "proposer": {
            "proposer.demo_batches": 1,
            "proposer.demo_episodes": 2,
            "proposer.demo_steps": 100,
            "proposer.demo_workers": 1,
            "proposer.pretrain_steps": 50,
            "proposer.dagger_batches": 1,
            "proposer.dagger_steps": 20,
        },
    },
    "paper": {
        "": {"preset": "paper"},
        # the proposer alone is not trained after its first stage: its frames only act
        "diffusion": {"collector.total_frames": 1000},
        # a grid runs over several sittings: a job resumed from a checkpoint goes on with
        # its replay buffer (sized to the job's frames, so a checkpoint holds only them),
        # from at most 10,000 frames back (~4 min of a training job)
        "checkpoint": {"checkpoint.every_frames": 10000},
        "replay": {"checkpoint.replay_buffer": True},
    },
}
#: the groups of :data:`BUDGETS` that apply to each framework (its config's groups and itself)
_GROUPS = {
    "sac": ("", "env", "collector", "optim", "checkpoint", "replay", "eval", "sac"),
    "diffusion": ("", "env", "collector", "checkpoint", "eval", "proposer", "diffusion"),
    "diffusion_rl": ("", "env", "collector", "optim", "checkpoint", "replay", "eval", "proposer"),
    "diffusion_lac": ("", "env", "collector", "optim", "checkpoint", "replay", "eval", "proposer"),
}


@dataclass(frozen=True)
class Job:
    """One training run: ``framework`` in ``sea`` with ``controller``, ``seed``, and the
    ``values`` (config key -> value) that make it a variant (``variant`` names them)."""

    framework: str
    sea: str
    controller: str
    seed: int
    variant: str = ""
    values: Mapping[str, object] = field(default_factory=dict, compare=False, hash=False)

    @property
    def ranks(self) -> bool:
        """Whether it evaluates each rank of its selection alone (OA, CA1-CA4: an evaluation
        each): only the jobs of Fig. 8/9, the full framework as preset in the main sea."""
        return (
            self.framework == "diffusion_lac"
            and self.sea == MAIN_SEA
            and self.controller == "s_surface"
            and not self.variant
        )

    @property
    def name(self) -> str:
        """``<framework>/<sea>/<controller>[/<variant>]/seed<seed>``: its folder under
        ``<root>/jobs``."""
        parts = [self.framework, self.sea, self.controller, self.variant, f"seed{self.seed}"]
        return "/".join(part for part in parts if part)

    def overrides(self, budget: str, *, root: str | Path, frames: int | None = None) -> list[str]:
        """``recipes/train.py`` overrides of this job under ``budget`` (:data:`BUDGETS`),
        writing to ``<root>/jobs/<name>``; ``frames``: ``collector.total_frames`` (the paper
        budget's; the quick budget's own when ``None``)."""
        if budget not in BUDGETS:
            raise ValueError(f"budget must be one of {sorted(BUDGETS)}, got {budget!r}")
        root = Path(root)
        values: dict[str, object] = {"framework": self.framework}
        for group in _GROUPS[self.framework]:
            values.update(BUDGETS[budget].get(group, {}))
        if frames is not None and self.framework != "diffusion":
            values["collector.total_frames"] = int(frames)  # the proposer alone trains nothing
        frames_of_job = values.get("collector.total_frames")
        if values.get("checkpoint.replay_buffer") and frames_of_job:
            # the buffer never evicts within the job (the same samples as the preset's 1e6)
            # and a checkpoint stores its capacity, not its fill
            values["replay_buffer.size"] = frames_of_job
        values.update(
            {
                "env.sea_state": self.sea,
                "env.controller": self.controller,
                "seed": self.seed,
                "eval.sea_states": f"[{self.sea}]",
                "run_dir": str(root / "jobs" / self.name),
            }
        )
        if self.framework != "sac":
            values["proposer.cache_dir"] = str(root / "first_stage")
        if self.framework in ("diffusion_rl", "diffusion_lac"):  # OA, CA1-CA4: Fig. 8/9's jobs
            values["eval.ranks"] = self.ranks
        values.update(self.values)
        return [f"{key}={value}" for key, value in values.items()]


def _jobs(
    frameworks: Iterable[str],
    seas: Iterable[str],
    controllers: Iterable[str],
    seeds: Sequence[int],
    variant: str = "",
    **values: object,
) -> list[Job]:
    return [
        Job(f, sea, c, s, variant, dict(values))
        for f in frameworks
        for sea in seas
        for c in controllers
        for s in seeds
    ]


def _fixed(seeds: Sequence[int], form: str = FIXED_FORM, alpha: float = FIXED_ALPHA) -> list[Job]:
    """The full framework with the Lyapunov form and weight fixed (no advisor)."""
    return _jobs(
        ["diffusion_lac"],
        [MAIN_SEA],
        ["s_surface"],
        seeds,
        f"fixed-{form}-alpha{alpha}",
        **{"advisor.backend": "fixed", "lyapunov.form": form, "lyapunov.stability_weight": alpha},
    )


def _alpha(seeds: Sequence[int]) -> list[Job]:
    return [job for alpha in ALPHAS for job in _fixed(seeds, alpha=alpha)]


def _forms(seeds: Sequence[int]) -> list[Job]:
    return [job for form in FORMS for job in _fixed(seeds, form=form)]


def _main(framework: str, seeds: Sequence[int]) -> list[Job]:
    return _jobs([framework], [MAIN_SEA], ["s_surface"], seeds)


#: experiment -> the jobs it reads, given the seeds (module docstring)
EXPERIMENTS = {
    # Fig. 4 and Fig. 5/6: the first stage (the proposer alone in each sea; its artefact)
    "fig4": lambda seeds: _jobs(["diffusion"], SEAS, ["s_surface"], seeds),
    "fig5_6": lambda seeds: _jobs(["diffusion"], [MAIN_SEA], ["s_surface"], seeds[:1]),
    # Fig. 7: RL, Diffusion+RL, Diffusion+RL (LAC) in every sea
    "fig7": lambda seeds: _jobs(
        ["sac", "diffusion_rl", "diffusion_lac"], SEAS, ["s_surface"], seeds
    ),
    # Table II: the two frameworks x three controllers x ES, VES
    "table2": lambda seeds: _jobs(
        ["diffusion_rl", "diffusion_lac"], ["es", "ves"], CONTROLLERS, seeds
    ),
    # Table III: the four frameworks x three controllers (VES)
    "table3": lambda seeds: _jobs(FRAMEWORKS, [MAIN_SEA], CONTROLLERS, seeds),
    # Fig. 8/9: OA, CA1-CA4 and RL (LAC) of the full framework (VES)
    "fig8_9": lambda seeds: _main("diffusion_lac", seeds),
    # Fig. 10/11: the Lyapunov value for fixed weights and forms (VES)
    "fig10": _alpha,
    "fig11": _forms,
    # beyond the paper: the advisor, the Lyapunov cost, the sampler
    "advisor": lambda seeds: _main("diffusion_lac", seeds) + _fixed(seeds),
    # ... and an OpenAI-compatible model (e.g. the local SmolLM2 server at the presets'
    # advisor.base_url; a job whose endpoint does not answer is refused before any work)
    "advisor_llm": lambda seeds: _jobs(
        ["diffusion_lac"],
        [MAIN_SEA],
        ["s_surface"],
        seeds,
        "openai",
        **{"advisor.backend": "openai"},
    ),
    "lyapunov_cost": lambda seeds: (
        _main("diffusion_lac", seeds)
        + _jobs(
            ["diffusion_lac"],
            [MAIN_SEA],
            ["s_surface"],
            seeds,
            "task_cost",
            **{"lyapunov.cost": "task"},
        )
    ),
    "sampler": lambda seeds: (
        _main("diffusion_lac", seeds)
        + _jobs(
            ["diffusion_lac"],
            [MAIN_SEA],
            ["s_surface"],
            seeds,
            "ddim10",
            **{"proposer.sampler": "ddim", "proposer.num_inference_steps": 10},
        )
    ),
}


def experiment_jobs(experiment: str, seeds: Sequence[int]) -> list[Job]:
    """The jobs ``experiment`` (a key of :data:`EXPERIMENTS`) reads, for ``seeds``."""
    if experiment not in EXPERIMENTS:
        raise ValueError(f"experiment must be one of {sorted(EXPERIMENTS)}, got {experiment!r}")
    if not seeds:
        raise ValueError("seeds must name at least one seed")
    return EXPERIMENTS[experiment](tuple(seeds))


def first_stage_job(job: Job) -> Job | None:
    """The proposer-alone job (``diffusion``) whose run builds the first stage ``job`` reuses:
    the same sea, controller and seed (the grid's jobs share the rate model and the first-stage
    keys). ``None`` for SAC (no proposer) and for a proposer-alone job itself."""
    if job.framework in ("sac", "diffusion"):
        return None
    return Job("diffusion", job.sea, job.controller, job.seed)


def grid(experiments: Iterable[str], seeds: Sequence[int]) -> list[Job]:
    """The union of the experiments' jobs, each once, with the proposer alone (``diffusion``)
    for every first stage a diffusion job needs, grouped by first stage: its builder, then the
    jobs that reuse it (so a sitting spends the first stages it builds: only their records go
    into the results store). Seed by seed (one seed of every experiment is done before the
    next seed starts); within a seed the first stages with the most jobs first, then SAC.
    ``recipes/paper/run_all.py`` starts a job only once its first stage's builder has ended
    (two jobs starting together on one unbuilt artefact would leave one waiting for the
    other's build)."""
    found: dict[str, Job] = {}
    for experiment in experiments:
        for job in experiment_jobs(experiment, seeds):
            found.setdefault(job.name, job)
    users: dict[Job, list[Job]] = {}
    for job in found.values():
        builder = first_stage_job(job)
        if builder is not None:
            users.setdefault(builder, []).append(job)
    for builder in users:
        found.setdefault(builder.name, builder)
    order = {name: i for i, name in enumerate(FRAMEWORKS)}
    by_name = lambda job: (order[job.framework], job.name)  # noqa: E731
    ordered: list[Job] = []
    for seed in dict.fromkeys(job.seed for job in found.values()):
        groups = sorted(
            (builder for builder in users if builder.seed == seed),
            key=lambda b: (-len(users[b]), SEAS.index(b.sea), CONTROLLERS.index(b.controller)),
        )
        for builder in groups:
            ordered += [found[builder.name], *sorted(users[builder], key=by_name)]
        alone = [
            job
            for job in found.values()
            if job.seed == seed and job.framework == "diffusion" and job not in users
        ]
        ordered += sorted(alone, key=by_name)
        ordered += sorted(
            (job for job in found.values() if job.seed == seed and job.framework == "sac"),
            key=by_name,
        )
    return ordered
