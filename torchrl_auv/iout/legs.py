r"""Approach legs: the stretches of decisions in which an AUV heads for one target node.

The data-collection task has no single equilibrium: an AUV serves a node, takes a new target
and sets off again. What a Lyapunov function can certify is each **approach leg**, from the
decision an AUV takes (or keeps) a target to the decision it starts service there. Per leg the
task is a stabilisation problem with an absorbing equilibrium, *service start*: the stability
cost (:func:`~torchrl_auv.iout.stability_cost`) is 0 there, and a Lyapunov critic whose TD
target ends there (:math:`L = 0` at the equilibrium) can satisfy the decrease condition along
every transition of a policy that arrives (``LyapunovActorCriticLoss``'s docstring derives it).

A decision (the transition from its start to its end) is

- an **approach** decision when the AUV was not in service at its start, had a target, and at
  its end still has the same target (it heads for it, or starts service at it: the target
  rule re-chooses only for AUVs out of service, so a service start keeps its target);
- a **service start** when the AUV was not in service at its start and is at its end (it
  reached its target within the service radius): the leg's last transition.

Decisions spent in service (the station keeper holds the AUV, the policy's action is
overridden) and decisions in which the target rule switched the AUV to another node belong to
no leg: across a switch the function's goal changes, so no decrease is owed there.

Examples:
    >>> # AUVs: heading for node 3; reaching it; in service; switched to node 5; no target
    >>> before = torch.tensor([False, False, True, False, False])
    >>> after = torch.tensor([False, True, True, False, False])
    >>> approach, start = approach_legs(before, torch.tensor([3, 3, 3, 3, -1]), after,
    ...                                 torch.tensor([3, 3, 3, 5, -1]))
    >>> approach.tolist(), start.tolist()
    ([True, True, False, False, False], [False, True, False, False, False])
"""

from __future__ import annotations

import torch

__all__ = ["approach_legs"]


def approach_legs(
    in_service_before: torch.Tensor,
    target_before: torch.Tensor,
    in_service_after: torch.Tensor,
    target_after: torch.Tensor,
) -> tuple[torch.Tensor, torch.Tensor]:
    """``(approach, service_start)`` per AUV (module docstring), bool, shaped like the inputs.

    Args:
        in_service_before, in_service_after: ``[*B, N]`` bool, the AUV's ``in_service`` flag at
            the decision's start and end.
        target_before, target_after: ``[*B, N]`` int64 target node indices (``-1``: none).
    """
    service_start = ~in_service_before & in_service_after
    # a service start keeps its target (the target rule re-chooses only out of service)
    kept = target_after == target_before
    approach = ~in_service_before & (target_before >= 0) & kept
    return approach, service_start
