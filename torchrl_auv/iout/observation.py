r"""Task features of each AUV for the agent's observation (all of order one).

Computed from the positions the agent may see (the Kalman estimate, not the truth), its own
measurements (altimeter, current estimate) and the task state. ``D`` is the area diagonal,
``h_max`` the deepest seabed, ``T_max`` the hover time of a full buffer at the edge of the
service radius, :math:`Q / R(r_s)`; ``(X, Y)`` the area's size:

=====  ==========================  ==========================================================
idx    name                        value
=====  ==========================  ==========================================================
0-2    ``target_offset``           target minus AUV position / (area x, area y, h_max); 0 if none
3      ``target_distance``         3-D distance to the target / D; 0 if none
4      ``target_fill``             target buffer fill b / C_max
5      ``target_rate``             target arrival rate / the largest rate
6      ``has_target``              1 if the AUV has a target
7      ``in_service``              1 if hovering in service during the next decision
8      ``hover_left``              hover time left / T_max
9      ``altitude``                altitude above the seabed / h_max (the altimeter's reading
                                   when given, else the map's seabed under the position)
10     ``depth``                   depth / h_max
11-13  ``nearest_auv_offset``      nearest other AUV minus this one / D; 0 if alone
14     ``nearest_auv_distance``    min(1, its distance / (10 x collision distance)); 1 if alone
15     ``service_count``           services completed so far / M (can exceed 1: nodes refill)
16     ``time_fraction``           decisions taken / decisions per episode
17-20  ``edge_*``                  signed distance to the area's edges, x / X, (X - x) / X,
                                   y / Y, (Y - y) / Y (negative outside the area)
21-22  ``current_*``               the AUV's estimate of the current, north and east (m/s)
23     ``delivery_age``            decisions since the AUV last delivered data /
                                   ``config.age_scale``, at most 1 (task v3: the cost's
                                   mission term reads it, :mod:`~torchrl_auv.iout.reward`)
=====  ==========================  ==========================================================
"""

from __future__ import annotations

import torch
from tensordict import TensorDict

from torchrl_auv.iout.config import IoUTConfig
from torchrl_auv.iout.link import link_rate
from torchrl_auv.iout.targets import gather_nodes
from torchrl_auv.iout.terrain import seabed_depth

__all__ = ["OBSERVATION_FEATURES", "task_observation"]

OBSERVATION_FEATURES = (
    "target_offset_x",
    "target_offset_y",
    "target_offset_z",
    "target_distance",
    "target_fill",
    "target_rate",
    "has_target",
    "in_service",
    "hover_left",
    "altitude",
    "depth",
    "nearest_auv_offset_x",
    "nearest_auv_offset_y",
    "nearest_auv_offset_z",
    "nearest_auv_distance",
    "service_count",
    "time_fraction",
    "edge_x_low",
    "edge_x_high",
    "edge_y_low",
    "edge_y_high",
    "current_north",
    "current_east",
    "delivery_age",
)


def task_observation(
    state: TensorDict,
    auv_positions: torch.Tensor,
    config: IoUTConfig,
    *,
    altitude: torch.Tensor | None = None,
    current: torch.Tensor | None = None,
    horizon: int | None = None,
) -> torch.Tensor:
    """Task features per AUV (module docstring), ``[*B, N, 24]``.

    Args:
        state: task state from :func:`~torchrl_auv.iout.reset_state` / :func:`~.step`.
        auv_positions: ``[*B, N, 3]`` NED positions the agent sees (m).
        config: task configuration.
        altitude: ``[*B, N]`` measured altitude above the seabed (m); default: the map's
            seabed under ``auv_positions``.
        current: ``[*B, N, 2]`` (or ``[*B, 2]``, shared) current estimate, north and east
            (m/s); default 0.
        horizon: decisions per episode for ``time_fraction`` (default
            ``config.episode_decisions``).

    Returns:
        ``[*B, N, len(OBSERVATION_FEATURES)]`` in the dtype of ``auv_positions``.

    Examples:
        >>> from torchrl_auv.iout import reset_state
        >>> cfg = IoUTConfig()
        >>> state, pos = reset_state(cfg, (3,), generator=torch.Generator().manual_seed(0))
        >>> obs = task_observation(state, pos, cfg)
        >>> obs.shape, bool(obs.abs().max() <= 1.0)
        (torch.Size([3, 2, 24]), True)
    """
    dtype = auv_positions.dtype
    nodes, auvs = state["nodes"], state["auvs"]
    target = auvs["target"]
    has = target >= 0
    h_max = config.seabed_depth_range_m[1]
    diagonal = config.area_diagonal_m
    scale = auv_positions.new_tensor([config.area_m[0], config.area_m[1], h_max])

    def masked(value: torch.Tensor) -> torch.Tensor:
        mask = has[..., None] if value.dim() > has.dim() else has
        return torch.where(mask, value, torch.zeros_like(value)).to(dtype)

    offset = gather_nodes(nodes["position"], target).to(dtype) - auv_positions
    distance = torch.linalg.vector_norm(offset, dim=-1)
    fill = gather_nodes(nodes["buffer"], target) / config.buffer_capacity
    rate = gather_nodes(nodes["rate"], target) / max(max(config.arrival_rates), 1e-12)
    edge_rate = link_rate(auv_positions.new_tensor(config.service_radius_m), config)
    hover_max = config.data_volume_bits / edge_rate
    x, y, z = auv_positions.unbind(-1)
    if altitude is None:
        altitude = seabed_depth(state["terrain"], x, y, config).to(dtype) - z

    n = auv_positions.shape[-2]
    gaps = auv_positions[..., None, :, :] - auv_positions[..., :, None, :]  # [*B, N, N, 3]
    gap_norm = torch.linalg.vector_norm(gaps, dim=-1)
    eye = torch.eye(n, dtype=torch.bool, device=auv_positions.device)
    gap_norm = torch.where(eye, torch.inf, gap_norm)
    nearest_distance, nearest = gap_norm.min(-1)
    nearest_offset = torch.gather(gaps, -2, nearest[..., None, None].expand(*nearest.shape, 1, 3))
    nearest_offset = nearest_offset.squeeze(-2) / diagonal
    if n == 1:
        nearest_offset = torch.zeros_like(nearest_offset)
    closeness = (nearest_distance / (10.0 * config.collision_distance_m)).clamp(max=1.0)

    services = nodes["services"].sum(-1).to(dtype) / nodes["services"].shape[-1]
    time = state["decision"].to(dtype) / (config.episode_decisions if horizon is None else horizon)
    per_scene = torch.stack((services, time), -1)[..., None, :].expand(*has.shape, 2)
    size_x, size_y = config.area_m
    edges = torch.stack((x / size_x, (size_x - x) / size_x, y / size_y, (size_y - y) / size_y), -1)
    if current is None:
        current = torch.zeros((*has.shape, 2), dtype=dtype, device=auv_positions.device)
    elif current.dim() == has.dim():  # one estimate per scene
        current = current[..., None, :].expand(*has.shape, 2)
    features = torch.cat(
        [
            masked(offset / scale),
            masked(distance / diagonal)[..., None],
            masked(fill)[..., None],
            masked(rate)[..., None],
            has.to(dtype)[..., None],
            auvs["in_service"].to(dtype)[..., None],
            (auvs["service_remaining"] / hover_max).to(dtype)[..., None],
            (altitude / h_max)[..., None],
            (z / h_max)[..., None],
            nearest_offset,
            closeness[..., None],
            per_scene,
            edges.to(dtype),
            current.to(dtype),
            (auvs["delivery_age"] / config.age_scale).clamp(max=1.0).to(dtype)[..., None],
        ],
        -1,
    )
    return features
