"""Wall time of the diffusion recipes' first stage, per phase, and of its reuse (issue [13/18]).

The first stage (``torchrl_auv.training.first_stage``) is built once per first-stage values and
then reused. This benchmark builds it with ``first_stage_from_config`` from a recipe config
(``recipes/diffusion/<preset>.yaml``) into a fresh cache, prints the wall time of each phase
(expert demonstrations, pretraining, DAgger collection and training summed over the rounds,
from the artefact's ``metrics.json``) and the total, then loads it again with the same values
and prints the reuse time. Issue [13/18]'s targets: the paper preset's first stage in <= 20
minutes per sea state on a 2-core machine, and a second run with the same values reusing it in
seconds.

    .venv/bin/python benchmarks/bench_first_stage.py                     # quick preset, ideal
    .venv/bin/python benchmarks/bench_first_stage.py --preset paper --sea-states ves  # ~14 min
    .venv/bin/python benchmarks/bench_first_stage.py --cache runs/first_stage   # existing ones

With ``--cache`` nothing is built: every artefact found there is listed with its stored phase
times, and each is reused once (timed).
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

from _runner import print_summary, print_table, setup

REPO = Path(__file__).resolve().parents[1]


def _arguments(parser) -> None:
    parser.add_argument("--preset", default="quick", choices=("quick", "paper"))
    parser.add_argument("--sea-states", nargs="+", default=["ideal"])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--cache", default=None, help="list and reuse the artefacts here")


def _config(preset: str, sea: str, seed: int, cache: Path):
    from omegaconf import OmegaConf

    cfg = OmegaConf.load(REPO / "recipes" / "diffusion" / "paper.yaml")
    if preset == "quick":
        quick = OmegaConf.load(REPO / "recipes" / "diffusion" / "quick.yaml")
        cfg = OmegaConf.merge(cfg, {k: v for k, v in quick.items() if k != "defaults"})
    cfg.run_root = str(cache)
    cfg.run_dir = str(cache / "run")  # the preset's ${now:...} resolves only under Hydra
    cfg.seed = seed
    cfg.env.sea_state = sea
    cfg.proposer.demo_sea_state = sea
    cfg.proposer.cache_dir = str(cache)
    cfg.proposer.compile = False
    return cfg


def _row(folder: Path, reuse_s: float) -> list[object]:
    """Phase times (s) of an artefact: DAgger collection and training summed over its rounds."""
    metrics = json.loads((folder / "metrics.json").read_text())
    rounds = 0
    while f"dagger{rounds + 1}_s" in metrics:
        rounds += 1
    phases = [
        metrics["demonstrations_s"],
        metrics["pretraining_s"],
        sum(metrics[f"dagger{r}_collection_s"] for r in range(1, rounds + 1)),
        sum(metrics[f"dagger{r}_s"] for r in range(1, rounds + 1)),
    ]
    return [folder.name, rounds, *phases, sum(phases) / 60, reuse_s]


def _never(folder: Path) -> None:
    raise RuntimeError(f"{folder}: the stored values did not find their artefact")


def main(argv=None) -> None:
    args = setup(__doc__.split("\n")[0], argv, _arguments)
    from torchrl_auv.modules import DiffusionProposer
    from torchrl_auv.training import ArtefactCache, first_stage_from_config
    from torchrl_auv.training.first_stage.artefacts import VALUES_FILE

    rows = []
    if args.cache:
        for folder in sorted(Path(args.cache).glob(f"*/{VALUES_FILE}")):
            folder = folder.parent
            values = json.loads((folder / VALUES_FILE).read_text())
            start = time.perf_counter()
            found, _ = ArtefactCache(folder.parent).get_or_build(
                folder.name.rsplit("-", 1)[0], values, _never
            )  # values checked
            DiffusionProposer.load(found / "proposer.pt")
            rows.append(_row(folder, time.perf_counter() - start))
    else:
        cache = Path(tempfile.mkdtemp(prefix="first_stage_"))
        for sea in args.sea_states:
            cfg = _config(args.preset, sea, args.seed, cache)
            stage = first_stage_from_config(cfg)
            start = time.perf_counter()
            again = first_stage_from_config(cfg)
            reuse_s = time.perf_counter() - start
            assert not again.built, "the second call should have reused the artefact"
            rows.append(_row(stage.folder, reuse_s))
    header = [
        "artefact",
        "dagger rounds",
        "demos s",
        "pretrain s",
        "dagger collect s",
        "dagger train s",
        "total min",
        "reuse s",
    ]
    print_table(f"first stage ({args.preset if not args.cache else args.cache})", header, rows)
    if rows:
        print_summary(
            "first_stage",
            worst_total_min=max(r[-2] for r in rows),
            worst_reuse_s=max(r[-1] for r in rows),
        )


if __name__ == "__main__":
    main(sys.argv[1:])
