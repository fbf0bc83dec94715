"""The sensor network of the data-collection task, as plain batched torch (no TorchRL import).

Owns everything the multi-AUV data-collection task (``docs/spec/data_collection.md``) adds
to the vehicles: the configuration (:class:`IoUTConfig`), the random seabed
(:mod:`~torchrl_auv.iout.terrain`), the sensor nodes and their Poisson data arrivals
(:mod:`~torchrl_auv.iout.nodes`), the node-to-AUV acoustic link rate
(:mod:`~torchrl_auv.iout.link`), the target rule (:mod:`~torchrl_auv.iout.targets`), service
with the per-decision state update (:mod:`~torchrl_auv.iout.service`), station keeping over
a node during a service (:mod:`~torchrl_auv.iout.station_keeping`),
collisions and violations (:mod:`~torchrl_auv.iout.safety`), the agent's task features
(:mod:`~torchrl_auv.iout.observation`), the paper's episode metrics
(:mod:`~torchrl_auv.iout.metrics`), cost and reward (:mod:`~torchrl_auv.iout.reward`) and the
scripted expert's setpoints (:mod:`~torchrl_auv.iout.expert`). Every function is batched over
leading scene dims ``[*B]``, follows the dtype and device of its inputs, returns new tensors
and TensorDicts without changing its inputs, and draws randomness only from a passed
:class:`torch.Generator`.

>>> cfg, g = IoUTConfig(), torch.Generator().manual_seed(0)
>>> state, positions = reset_state(cfg, (4,), generator=g)
>>> state, events = step(state, positions, cfg, generator=g)
>>> sorted(state.keys())
['auvs', 'decision', 'nodes', 'terrain']
"""

from __future__ import annotations

from torchrl_auv.iout.approach import approach_direction
from torchrl_auv.iout.config import IoUTConfig
from torchrl_auv.iout.expert import ExpertConfig, expert_setpoints, other_positions
from torchrl_auv.iout.legs import approach_legs
from torchrl_auv.iout.link import link_rate
from torchrl_auv.iout.metrics import METRIC_KEYS, TaskMetrics
from torchrl_auv.iout.nodes import data_arrivals, sample_nodes
from torchrl_auv.iout.observation import OBSERVATION_FEATURES, task_observation
from torchrl_auv.iout.reward import (
    COST_TERMS,
    STABILITY_TERMS,
    CostWeights,
    stability_cost,
    task_cost,
)
from torchrl_auv.iout.safety import collision_mask, nearest_auv_distance, violation_mask
from torchrl_auv.iout.service import reset_state, sample_auv_start, step
from torchrl_auv.iout.station_keeping import StationKeepingConfig, station_keeping_setpoints
from torchrl_auv.iout.targets import NO_TARGET, assign_targets, gather_nodes, priority
from torchrl_auv.iout.termination import (
    ending_auvs,
    episode_flags,
    outside_area,
    with_termination,
)
from torchrl_auv.iout.terrain import make_terrain, seabed_depth

__all__ = [
    "COST_TERMS",
    "METRIC_KEYS",
    "NO_TARGET",
    "OBSERVATION_FEATURES",
    "STABILITY_TERMS",
    "CostWeights",
    "ExpertConfig",
    "IoUTConfig",
    "StationKeepingConfig",
    "TaskMetrics",
    "approach_direction",
    "approach_legs",
    "assign_targets",
    "collision_mask",
    "data_arrivals",
    "ending_auvs",
    "episode_flags",
    "expert_setpoints",
    "gather_nodes",
    "link_rate",
    "make_terrain",
    "nearest_auv_distance",
    "other_positions",
    "outside_area",
    "priority",
    "reset_state",
    "sample_auv_start",
    "sample_nodes",
    "seabed_depth",
    "stability_cost",
    "station_keeping_setpoints",
    "step",
    "task_cost",
    "task_observation",
    "violation_mask",
    "with_termination",
]
