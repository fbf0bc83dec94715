"""The tensordict keys the training layer reads and writes, on the multi-agent layout of
:class:`~torchrl_auv.envs.DataCollectionEnv` (``("agents", ...)``, one set of network weights
shared by the AUVs: each AUV decides from its own observation). The env's own keys are
:mod:`torchrl_auv.envs.keys`' (``OBSERVATION`` and ``ACTION`` are its ``AGENT_OBSERVATION``
and ``AGENT_ACTION``); the keys of the training layer's modules are defined here.

Examples:
    >>> ACTION, LYAPUNOV_RAW
    (('agents', 'action'), ('agents', 'lyapunov_raw'))
"""

from __future__ import annotations

from torchrl_auv.envs.keys import AGENT_ACTION, AGENT_OBSERVATION, AGENTS

__all__ = ["ACTION", "ACTOR_ACTION", "AGENTS", "LYAPUNOV_RAW", "OBSERVATION", "Q_VALUE"]

OBSERVATION = AGENT_OBSERVATION
ACTION = AGENT_ACTION
#: a Q critic's output
Q_VALUE = (AGENTS, "state_action_value")
#: the actor's own action when it competes with the proposer's candidates
ACTOR_ACTION = (AGENTS, "actor", "action")
#: the Lyapunov critic's raw output z(o, a), before the form (softplus, ...)
LYAPUNOV_RAW = (AGENTS, "lyapunov_raw")
