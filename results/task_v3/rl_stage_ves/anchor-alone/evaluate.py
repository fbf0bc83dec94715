"""The anchor alone: the proposer executing the medoid of its K = 5 candidates (what the anchored
selection executes while it does not deviate), on the runs' 16 held-out ves scenes.

Run from the repository root with RUN_ROOT replaced by the runs' folder; writes rows.json.
"""

import json

from omegaconf import OmegaConf

from torchrl_auv import training

cfg = OmegaConf.load("RUN_ROOT/R-anchor/.hydra/config.yaml")
proposer = training.proposer_from_config(cfg)
rows = {
    "proposer alone (medoid of 5)": training.proposer_alone(proposer, "medoid", num_candidates=5)
}
out = training.evaluate(
    training.held_out_env(cfg, 16, 1000), rows, ["ves"], seed=cfg.eval.seed, steps=1000
)
with open("rows.json", "w") as f:
    json.dump(out, f, indent=1, default=float)
