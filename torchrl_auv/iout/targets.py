r"""The target rule: which sensor node each AUV heads for.

An AUV ``j`` values node ``i`` by the priority (``b_i`` buffer fill, ``C_max`` capacity,
``d_ij`` the 3-D AUV-node distance in m)

.. math::

    p_{ij} = w_\lambda\,\lambda_i \frac{b_i}{C_{max}} - w_d\, d_{ij},
    \qquad w_\lambda = 1,\ w_d = 0.05\ \mathrm{m^{-1}}.

**Eligible** nodes are those whose buffer holds at least ``refill_fraction`` of ``C_max``
(spec v2: a served node becomes a target again once it has refilled above 10 %, so a node can
be served many times per episode while an AUV cannot farm services on a just-emptied node)
and that are not held by another AUV (in service, or keeping its target).

**Assignment** is greedy over (AUV, node) pairs so that two AUVs never share a target: take the
pair of highest priority among the AUVs to assign and the eligible nodes, assign it, remove
that AUV and that node, repeat. For one AUV this is exactly its highest-priority eligible node.
Ties go to the lowest AUV index, then the lowest node index. An AUV left without an eligible
node gets the target ``-1``. The greedy loop runs ``N`` (number of AUVs, tiny) rounds of
batched tensor ops; nothing loops over scenes or nodes.
"""

from __future__ import annotations

import torch

from torchrl_auv.iout.config import IoUTConfig

__all__ = ["NO_TARGET", "assign_targets", "gather_nodes", "priority"]

NO_TARGET = -1  # target index of an AUV without a target


def priority(
    auv_positions: torch.Tensor,
    node_positions: torch.Tensor,
    rate: torch.Tensor,
    buffer: torch.Tensor,
    config: IoUTConfig,
) -> torch.Tensor:
    r"""Priority :math:`p_{ij}` of every node for every AUV (module docstring).

    Args:
        auv_positions: ``[*B, N, 3]`` NED positions (m).
        node_positions: ``[*B, M, 3]`` NED positions (m).
        rate: ``[*B, M]`` arrival rates (packets/decision).
        buffer: ``[*B, M]`` buffer fills (packets).
        config: weights and capacity.

    Returns:
        ``[*B, N, M]`` priorities.

    Examples:
        >>> p = priority(torch.zeros(1, 3), torch.tensor([[0.0, 0.0, 10.0]]),
        ...              torch.tensor([4.0]), torch.tensor([2500.0]), IoUTConfig())
        >>> p.tolist()  # 4 * 0.5 - 0.05 * 10
        [[1.5]]
    """
    distance = torch.linalg.vector_norm(
        auv_positions[..., :, None, :] - node_positions[..., None, :, :], dim=-1
    )
    value = config.priority_rate_weight * rate * buffer / config.buffer_capacity
    return value[..., None, :] - config.priority_distance_weight * distance


def assign_targets(
    scores: torch.Tensor, eligible: torch.Tensor, needs_target: torch.Tensor
) -> torch.Tensor:
    """Greedy one-to-one assignment of nodes to AUVs (module docstring).

    Args:
        scores: ``[*B, N, M]`` priorities.
        eligible: ``[*B, M]`` bool, nodes that may be assigned.
        needs_target: ``[*B, N]`` bool, AUVs to assign.

    Returns:
        ``[*B, N]`` int64 node index per AUV; ``-1`` for AUVs not assigned (not in
        ``needs_target``, or no eligible node left).

    Examples:
        >>> scores = torch.tensor([[3.0, 1.0, 0.0], [2.9, 2.0, 0.0]])  # both prefer node 0
        >>> assign_targets(scores, torch.ones(3, dtype=torch.bool), torch.ones(2, dtype=torch.bool))
        tensor([0, 1])
    """
    n_auv, n_node = scores.shape[-2], scores.shape[-1]
    neg_inf = torch.tensor(float("-inf"), dtype=scores.dtype, device=scores.device)
    masked = torch.where(eligible[..., None, :] & needs_target[..., :, None], scores, neg_inf)
    target = torch.full(needs_target.shape, NO_TARGET, dtype=torch.long, device=scores.device)
    auv_ids = torch.arange(n_auv, device=scores.device)
    node_ids = torch.arange(n_node, device=scores.device)
    for _ in range(n_auv):  # N rounds (N is the tiny number of AUVs), batched over scenes
        best, flat = masked.flatten(-2).max(-1)
        found = best > neg_inf
        auv, node = flat // n_node, flat % n_node
        chosen = found[..., None] & (auv_ids == auv[..., None])  # [*B, N]
        target = torch.where(chosen, node[..., None], target)
        taken_row = chosen[..., :, None]
        taken_col = (found[..., None] & (node_ids == node[..., None]))[..., None, :]
        masked = torch.where(taken_row | taken_col, neg_inf, masked)
    return target


def gather_nodes(values: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Per-AUV values of the targeted nodes.

    Args:
        values: ``[*B, M]`` or ``[*B, M, D]`` node values.
        target: ``[*B, N]`` node index per AUV (``-1`` reads node 0; mask it yourself).

    Returns:
        ``[*B, N]`` or ``[*B, N, D]``.

    Examples:
        >>> gather_nodes(torch.tensor([10.0, 20.0, 30.0]), torch.tensor([2, 0]))
        tensor([30., 10.])
    """
    index = target.clamp_min(0)
    if values.dim() == target.dim():
        return torch.gather(values, -1, index)
    index = index[..., None].expand(*index.shape, values.shape[-1])
    return torch.gather(values, -2, index)
