"""The tensordict keys of :class:`~torchrl_auv.envs.DataCollectionEnv`'s multi-agent layout,
defined once: the env writes them, and the training layer (``torchrl_auv.training.keys``)
reads them under the same names.

Examples:
    >>> AGENT_OBSERVATION, AGENT_ACTION, AGENT_COST
    (('agents', 'observation'), ('agents', 'action'), ('agents', 'cost'))
"""

from __future__ import annotations

__all__ = [
    "AGENTS",
    "AGENT_ACTION",
    "AGENT_APPROACH",
    "AGENT_COST",
    "AGENT_OBSERVATION",
    "AGENT_REWARD",
    "AGENT_SERVICE_START",
    "AGENT_STABILITY_COST",
]

#: the group of the AUVs (TorchRL's multi-agent layout, as VMAS's ``"agents"``)
AGENTS = "agents"
#: each AUV's observation ``[*B, N, 38]``
AGENT_OBSERVATION = (AGENTS, "observation")
#: each AUV's action ``[*B, N, 3]`` in [-1, 1]
AGENT_ACTION = (AGENTS, "action")
#: each AUV's reward, cost and stability cost ``[*B, N, 1]`` (under ``"next"``)
AGENT_REWARD = (AGENTS, "reward")
AGENT_COST = (AGENTS, "cost")
AGENT_STABILITY_COST = (AGENTS, "stability_cost")
#: per AUV ``[*B, N, 1]`` bool (observation keys: False at reset, then the last decision's):
#: the decision was part of an approach leg, and it ended the leg by starting service
#: (:mod:`torchrl_auv.iout.legs`; the Lyapunov critic's legs and equilibrium)
AGENT_APPROACH = (AGENTS, "approach")
AGENT_SERVICE_START = (AGENTS, "service_start")
