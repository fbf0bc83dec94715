"""The anchor alone: the proposer executing the medoid of its K = 5 candidates (what the anchored
selection executes while it does not deviate), on the runs' 16 held-out ves scenes."""
import json, sys
from omegaconf import OmegaConf
from torchrl_auv import training
cfg = OmegaConf.load("RUN_ROOT/R-anchor/.hydra/config.yaml")
training.configure_threads(1) if hasattr(training, "configure_threads") else None
proposer = training.proposer_from_config(cfg)
rows = {f"proposer alone (medoid of {k})": training.proposer_alone(proposer, "medoid", num_candidates=k) for k in (5,)}
out = training.evaluate(training.held_out_env(cfg, 16, 1000), rows, ["ves"], seed=cfg.eval.seed, steps=1000)
json.dump(out, open("RUN_ROOT/medoid5/rows.json", "w"), indent=1, default=float)
print(out)
