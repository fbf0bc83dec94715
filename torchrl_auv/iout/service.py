r"""Scene reset and the per-decision update of the sensor network (arrivals, service, targets).

**State** (a TensorDict with batch ``[*B]``, returned new by every function, inputs untouched):

=====================================  ==============  ============================================
key                                    shape           meaning
=====================================  ==============  ============================================
``("terrain", "depth")``               ``[*B, G, G]``  seabed depth grid (m)
``("nodes", "position")``              ``[*B, M, 3]``  node positions, NED (m)
``("nodes", "rate")``                  ``[*B, M]``     Poisson rate (packets/decision)
``("nodes", "buffer")``                ``[*B, M]``     buffer fill (packets)
``("nodes", "services")``              ``[*B, M]``     services completed in the episode (int64)
``("auvs", "target")``                 ``[*B, N]``     target node index, ``-1`` for none (int64)
``("auvs", "in_service")``             ``[*B, N]``     hovering in service during the next decision
``("auvs", "service_remaining")``      ``[*B, N]``     hover time left (s)
``("auvs", "service_rate")``           ``[*B, N]``     link rate of the ongoing service (bit/s)
``("auvs", "target_distance")``        ``[*B, N]``     3-D distance to the target (m), 0 if none
``("auvs", "delivery_age")``           ``[*B, N]``     decisions since the AUV last delivered data
                                                       (``config.age_scale`` at reset: none yet)
``"decision"``                         ``[*B]``        decisions taken (int64)
=====================================  ==============  ============================================

**One decision** (:func:`step`), given the true AUV positions at its end:

1. Poisson arrivals into every buffer; overflow counted (:func:`~torchrl_auv.iout.data_arrivals`).
2. AUVs that were in service held station during the decision: their hover time decreases by
   ``decision_dt_s``; at or below 0 the service completes: the node's buffer (including the
   packets that arrived meanwhile) is emptied and its service count grows by one. The time
   in service during the decision is ``min(hover time left, decision_dt_s)`` (the last
   decision of a service counts its fraction).
3. Every other AUV with a target within ``service_radius_m`` (3-D) starts service: it will
   hover for

   .. math::

       T = \frac{Q\, b_i / C_{max}}{R(d)}\ \mathrm{s},

   with :math:`b_i` the buffer now and :math:`R(d)` the link rate at the distance now, both
   frozen for the service (the vehicle holds station, so the distance barely changes). A
   service thus occupies :math:`\max(1, \lceil T / \Delta t \rceil)` decisions at the rate
   :math:`R(d)`, the last one for its fraction. The decision in which the service starts is
   a moving one.
4. Each AUV's delivery age becomes 0 if it delivered data in the decision (time in service
   above 0), else grows by one decision.
5. Targets are re-chosen (:mod:`~torchrl_auv.iout.targets`) for every AUV not in service
   (``retarget_every_decision=True``, the group's heuristic), or only for AUVs without one,
   among the nodes filled to at least ``refill_fraction`` of capacity.

The env should hold an AUV on station during the decisions its ``in_service`` flag is set.
"""

from __future__ import annotations

import math

import torch
from tensordict import TensorDict

from torchrl_auv.iout.config import IoUTConfig
from torchrl_auv.iout.link import link_rate
from torchrl_auv.iout.nodes import data_arrivals, sample_nodes
from torchrl_auv.iout.safety import collision_mask, violation_mask
from torchrl_auv.iout.targets import NO_TARGET, assign_targets, gather_nodes, priority
from torchrl_auv.iout.terrain import make_terrain

__all__ = ["reset_state", "sample_auv_start", "step"]


def sample_auv_start(
    terrain: TensorDict, config: IoUTConfig, *, generator: torch.Generator
) -> torch.Tensor:
    """Start positions: AUVs evenly on a circle around a random centre (ours).

    The centre is uniform at least ``auv_start_margin_m`` inside the area, the circle has the
    radius ``auv_start_spread_m`` and a random rotation, the depths are uniform in
    ``auv_start_depth_range_m``. With the defaults, two AUVs start 20 m apart (well above the
    5 m collision distance; up to six AUVs stay at least 10 m apart).

    Args:
        terrain: seabed of the scenes, batch ``[*B]`` (sets dtype and device).
        config: task configuration.
        generator: the only source of randomness.

    Returns:
        ``[*B, N, 3]`` NED positions (m).

    Examples:
        >>> from torchrl_auv.iout import make_terrain
        >>> cfg, g = IoUTConfig(), torch.Generator().manual_seed(0)
        >>> pos = sample_auv_start(make_terrain(cfg, (4,), generator=g), cfg, generator=g)
        >>> pos.shape, round((pos[:, 0, :2] - pos[:, 1, :2]).norm(dim=-1).min().item(), 3)
        (torch.Size([4, 2, 3]), 20.0)
    """
    depth = terrain["depth"]
    dtype, device = depth.dtype, depth.device
    batch = depth.shape[:-2]
    n = config.num_auvs

    def uniform(low: float, high: float, *size: int) -> torch.Tensor:
        u = torch.rand((*batch, *size), generator=generator, dtype=dtype, device=device)
        return low + (high - low) * u

    margin = config.auv_start_margin_m
    centre_x = uniform(margin, config.area_m[0] - margin, 1)
    centre_y = uniform(margin, config.area_m[1] - margin, 1)
    angle = uniform(-math.pi, math.pi, 1) + 2 * math.pi / n * torch.arange(
        n, dtype=dtype, device=device
    )
    z = uniform(*config.auv_start_depth_range_m, n)
    x = centre_x + config.auv_start_spread_m * torch.cos(angle)
    y = centre_y + config.auv_start_spread_m * torch.sin(angle)
    return torch.stack((x, y, z), -1)


def _distance_to_targets(
    auv_positions: torch.Tensor, node_positions: torch.Tensor, target: torch.Tensor
) -> torch.Tensor:
    gap = auv_positions - gather_nodes(node_positions, target)
    distance = torch.linalg.vector_norm(gap, dim=-1)
    return torch.where(target >= 0, distance, torch.zeros_like(distance))


def _retarget(
    nodes: TensorDict,
    target: torch.Tensor,
    in_service: torch.Tensor,
    auv_positions: torch.Tensor,
    config: IoUTConfig,
) -> torch.Tensor:
    """New ``[*B, N]`` targets: AUVs not in service (or without a target) choose again."""
    needs = ~in_service
    if not config.retarget_every_decision:
        needs = needs & (target < 0)
    n_node = nodes.batch_size[-1]
    node_ids = torch.arange(n_node, device=target.device)
    holders = (~needs & (target >= 0))[..., None]
    held = (holders & (target[..., None] == node_ids)).any(-2)
    refilled = nodes["buffer"] >= config.refill_fraction * config.buffer_capacity
    eligible = refilled & ~held
    scores = priority(auv_positions, nodes["position"], nodes["rate"], nodes["buffer"], config)
    chosen = assign_targets(scores, eligible, needs)
    return torch.where(needs, chosen, target)


def reset_state(
    config: IoUTConfig,
    batch_shape: tuple[int, ...] | torch.Size,
    *,
    generator: torch.Generator,
    dtype: torch.dtype = torch.float32,
    device: torch.device | str | None = None,
) -> tuple[TensorDict, torch.Tensor]:
    """A fresh scene per batch entry: terrain, nodes, AUV start positions and first targets.

    Args:
        config: task configuration.
        batch_shape: scene batch shape ``[*B]``.
        generator: the only source of randomness (same seed, same scenes).
        dtype: floating dtype of the state.
        device: device of the state.

    Returns:
        ``(state, auv_positions)``: the state (module docstring) and ``[*B, N, 3]`` start
        positions (m).

    Examples:
        >>> state, pos = reset_state(IoUTConfig(), (2,), generator=torch.Generator().manual_seed(0))
        >>> state["auvs", "target"].shape, bool((state["auvs", "target"] >= 0).all())
        (torch.Size([2, 2]), True)
        >>> bool((state["auvs", "target"][:, 0] != state["auvs", "target"][:, 1]).all())
        True
    """
    shape = torch.Size(batch_shape)
    terrain = make_terrain(config, shape, generator=generator, dtype=dtype, device=device)
    nodes = sample_nodes(terrain, config, generator=generator)
    positions = sample_auv_start(terrain, config, generator=generator)
    auv_shape = (*shape, config.num_auvs)
    in_service = torch.zeros(auv_shape, dtype=torch.bool, device=device)
    target = torch.full(auv_shape, NO_TARGET, dtype=torch.long, device=device)
    target = _retarget(nodes, target, in_service, positions, config)
    zeros = torch.zeros(auv_shape, dtype=dtype, device=device)
    auvs = TensorDict(
        {
            "target": target,
            "in_service": in_service,
            "service_remaining": zeros,
            "service_rate": zeros.clone(),
            "target_distance": _distance_to_targets(positions, nodes["position"], target),
            "delivery_age": torch.full(auv_shape, config.age_scale, dtype=dtype, device=device),
        },
        batch_size=auv_shape,
        device=device,
    )
    state = TensorDict(
        {
            "terrain": terrain,
            "nodes": nodes,
            "auvs": auvs,
            "decision": torch.zeros(shape, dtype=torch.long, device=device),
        },
        batch_size=shape,
        device=device,
    )
    return state, positions


def step(
    state: TensorDict,
    auv_positions: torch.Tensor,
    config: IoUTConfig,
    *,
    generator: torch.Generator | None,
    arrivals: torch.Tensor | None = None,
) -> tuple[TensorDict, TensorDict]:
    """Advance the sensor network by one decision (module docstring).

    Args:
        state: the state at the start of the decision, batch ``[*B]`` (left unchanged).
        auv_positions: true ``[*B, N, 3]`` NED positions at the end of the decision (m).
        config: task configuration.
        generator: the only source of randomness (Poisson arrivals), unless ``arrivals``
            (``[*B, M]`` packets, see :func:`~torchrl_auv.iout.nodes.data_arrivals`) is given.

    Returns:
        ``(state, events)``. ``events`` has batch ``[*B]`` and the keys

        * ``"hovering"`` ``[*B, N]`` bool: in service during this decision;
        * ``"rate"`` ``[*B, N]``: link rate while hovering (bit/s), 0 otherwise;
        * ``"service_time"`` ``[*B, N]``: time in service during the decision (s): the
          decision's length, the fraction left in the last decision of a service, 0 otherwise;
        * ``"completed"``, ``"started"`` ``[*B, N]`` bool: services that ended / began;
        * ``"progress"`` ``[*B, N]``: decrease of the distance to the target held during the
          decision (m), 0 if hovering or without a target;
        * ``"held_distance"`` ``[*B, N]``: 3-D distance at the end of the decision to the
          target held during it (m; 0 without one): where a service ended;
        * ``"target_distance"`` ``[*B, N]``: distance to the (possibly new) target (m), 0 if
          in service or without a target;
        * ``"collision"``, ``"violation"`` ``[*B, N]`` bool (:mod:`~torchrl_auv.iout.safety`);
        * ``"delivery_age"`` ``[*B, N]``: decisions since the AUV last delivered data, after
          this decision (0 if it delivered in it);
        * ``"overflow"`` ``[*B]``: packets lost to full buffers in this decision.

    Examples:
        >>> cfg, g = IoUTConfig(), torch.Generator().manual_seed(0)
        >>> state, pos = reset_state(cfg, (3,), generator=g)
        >>> node = gather_nodes(state["nodes", "position"], state["auvs", "target"])
        >>> parked = node - torch.tensor([0.0, 0.0, 5.0])  # 5 m above each target
        >>> state, events = step(state, parked, cfg, generator=g)
        >>> events["started"].all().item(), state["auvs", "in_service"].all().item()
        (True, True)
    """
    dt = config.decision_dt_s
    nodes, auvs = state["nodes"], state["auvs"]
    node_pos = nodes["position"]
    target = auvs["target"]
    n_node = nodes.batch_size[-1]
    node_ids = torch.arange(n_node, device=target.device)

    # 1. arrivals
    buffer, overflow = data_arrivals(
        nodes["buffer"],
        nodes["rate"],
        config.buffer_capacity,
        generator=generator,
        arrivals=arrivals,
    )

    # 2. ongoing services
    hovering = auvs["in_service"]
    left = auvs["service_remaining"]
    service_time = torch.where(hovering, left.clamp(0.0, dt), torch.zeros_like(left))
    remaining = torch.where(hovering, left - dt, left)
    completed = hovering & (remaining <= 0)
    done_nodes = (completed[..., None] & (target[..., None] == node_ids)).any(-2)
    buffer = torch.where(done_nodes, torch.zeros_like(buffer), buffer)
    services = nodes["services"] + done_nodes.long()
    rate = torch.where(hovering, auvs["service_rate"], torch.zeros_like(auvs["service_rate"]))

    # 3. service starts (moving AUVs that reached their target)
    moving_with_target = ~hovering & (target >= 0)
    distance = _distance_to_targets(auv_positions, node_pos, target)
    progress = torch.where(
        moving_with_target, auvs["target_distance"] - distance, torch.zeros_like(distance)
    )
    started = moving_with_target & (distance < config.service_radius_m)
    start_rate = link_rate(distance, config)
    volume = config.data_volume_bits * gather_nodes(buffer, target) / config.buffer_capacity
    remaining = torch.where(started, volume / start_rate, remaining.clamp_min(0.0))
    remaining = torch.where(completed, torch.zeros_like(remaining), remaining)
    service_rate = torch.where(started, start_rate, auvs["service_rate"])
    service_rate = torch.where(completed, torch.zeros_like(service_rate), service_rate)
    in_service = (hovering & ~completed) | started
    target = torch.where(completed, torch.full_like(target, NO_TARGET), target)

    # 4. the age of each AUV's last delivery (decisions)
    delivery_age = torch.where(service_time > 0, torch.zeros_like(left), auvs["delivery_age"] + 1)

    # 5. targets for the next decision
    new_nodes = TensorDict(
        {"position": node_pos, "rate": nodes["rate"], "buffer": buffer, "services": services},
        batch_size=nodes.batch_size,
        device=nodes.device,
    )
    target = _retarget(new_nodes, target, in_service, auv_positions, config)
    target_distance = _distance_to_targets(auv_positions, node_pos, target)

    new_state = TensorDict(
        {
            "terrain": state["terrain"],
            "nodes": new_nodes,
            "auvs": TensorDict(
                {
                    "target": target,
                    "in_service": in_service,
                    "service_remaining": remaining,
                    "service_rate": service_rate,
                    "target_distance": target_distance,
                    "delivery_age": delivery_age,
                },
                batch_size=auvs.batch_size,
                device=auvs.device,
            ),
            "decision": state["decision"] + 1,
        },
        batch_size=state.batch_size,
        device=state.device,
    )
    events = TensorDict(
        {
            "hovering": hovering,
            "rate": rate,
            "service_time": service_time,
            "completed": completed,
            "started": started,
            "progress": progress,
            "held_distance": distance,
            "target_distance": torch.where(
                in_service, torch.zeros_like(target_distance), target_distance
            ),
            "collision": collision_mask(auv_positions, config),
            "violation": violation_mask(auv_positions, state["terrain"], config),
            "delivery_age": delivery_age,
            "overflow": overflow.sum(-1),
        },
        batch_size=state.batch_size,
        device=state.device,
    )
    return new_state, events
