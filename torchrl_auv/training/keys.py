"""The tensordict keys the training layer reads and writes, on the multi-agent layout of
:class:`~torchrl_auv.envs.DataCollectionEnv` (``("agents", ...)``, one set of network weights
shared by the AUVs: each AUV decides from its own observation).

Examples:
    >>> ACTION, LYAPUNOV_RAW
    (('agents', 'action'), ('agents', 'lyapunov_raw'))
"""

from __future__ import annotations

__all__ = ["ACTION", "ACTOR_ACTION", "AGENTS", "LYAPUNOV_RAW", "OBSERVATION", "Q_VALUE"]

AGENTS = "agents"
OBSERVATION = (AGENTS, "observation")
ACTION = (AGENTS, "action")
#: a Q critic's output
Q_VALUE = (AGENTS, "state_action_value")
#: the actor's own action when it competes with the proposer's candidates
ACTOR_ACTION = (AGENTS, "actor", "action")
#: the Lyapunov critic's raw output z(o, a), before the form (softplus, ...)
LYAPUNOV_RAW = (AGENTS, "lyapunov_raw")
