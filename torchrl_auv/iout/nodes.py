r"""Sensor nodes on the seabed: placement, arrival rates, buffers and Poisson data arrivals.

Node ``i`` lies at a uniform ``(x_i, y_i)`` in the area on the seabed (``z_i`` = seabed depth
there), draws its arrival rate :math:`\lambda_i` uniformly from the configured set
(4, 6, 9, 12 packets per decision) and starts with a uniform integer fill in
``[0, 1000]`` packets. Each decision adds :math:`a_i \sim \mathrm{Poisson}(\lambda_i)` packets;
what does not fit in the capacity :math:`C_{max}` overflows and is counted (``N_DO``):

.. math::

    o_i = \max(0,\ b_i + a_i - C_{max}),\qquad b_i \leftarrow \min(b_i + a_i,\ C_{max}).
"""

from __future__ import annotations

import torch
from tensordict import TensorDict

from torchrl_auv.iout.config import IoUTConfig
from torchrl_auv.iout.terrain import seabed_depth

__all__ = ["data_arrivals", "sample_nodes"]


def sample_nodes(
    terrain: TensorDict, config: IoUTConfig, *, generator: torch.Generator
) -> TensorDict:
    """Draw the sensor nodes of each scene.

    Args:
        terrain: seabed from :func:`~torchrl_auv.iout.make_terrain`, batch ``[*B]``; sets the
            dtype and device.
        config: task configuration.
        generator: the only source of randomness.

    Returns:
        TensorDict with batch ``[*B, M]`` and keys ``"position"`` ``[*B, M, 3]`` (NED, m, on
        the seabed), ``"rate"`` (packets/decision), ``"buffer"`` (packets, integer-valued
        floats) and ``"services"`` (completed services of the node in this episode, int64, all 0).

    Examples:
        >>> from torchrl_auv.iout import make_terrain
        >>> cfg, g = IoUTConfig(), torch.Generator().manual_seed(0)
        >>> nodes = sample_nodes(make_terrain(cfg, (3,), generator=g), cfg, generator=g)
        >>> nodes.batch_size, nodes["position"].shape
        (torch.Size([3, 60]), torch.Size([3, 60, 3]))
        >>> sorted(set(nodes["rate"].flatten().tolist())) == [4.0, 6.0, 9.0, 12.0]
        True
    """
    depth = terrain["depth"]
    dtype, device = depth.dtype, depth.device
    batch = torch.Size(depth.shape[:-2])
    shape = (*batch, config.num_sensors)
    x = config.area_m[0] * torch.rand(shape, generator=generator, dtype=dtype, device=device)
    y = config.area_m[1] * torch.rand(shape, generator=generator, dtype=dtype, device=device)
    z = seabed_depth(terrain, x, y, config)
    rates = torch.tensor(config.arrival_rates, dtype=dtype, device=device)
    choice = torch.randint(len(config.arrival_rates), shape, generator=generator, device=device)
    low, high = config.initial_fill_range
    fill = torch.randint(low, high + 1, shape, generator=generator, device=device).to(dtype)
    return TensorDict(
        {
            "position": torch.stack((x, y, z), -1),
            "rate": rates[choice],
            "buffer": fill,
            "services": torch.zeros(shape, dtype=torch.long, device=device),
        },
        batch_size=shape,
        device=device,
    )


def data_arrivals(
    buffer: torch.Tensor,
    rate: torch.Tensor,
    capacity: float,
    *,
    generator: torch.Generator | None,
    arrivals: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """One decision of Poisson arrivals into the node buffers, with overflow.

    Args:
        buffer: current fills (packets), ``[*B, M]``.
        rate: Poisson rates (packets/decision), ``[*B, M]``.
        capacity: buffer capacity ``C_max`` (packets).
        generator: the only source of randomness, unless ``arrivals`` is given.
        arrivals: the decision's arrivals ``[*B, M]`` (packets), drawn ahead (e.g. of a
            compiled step) with ``torch.poisson(rate.expand_as(buffer), generator=g)``.

    Returns:
        ``(buffer, overflow)``: new fills ``[*B, M]`` (at most ``capacity``) and the packets
        that did not fit, ``[*B, M]``.

    Examples:
        >>> g = torch.Generator().manual_seed(0)
        >>> new, lost = data_arrivals(torch.tensor([0.0, 4999.0]), torch.tensor([0.0, 50.0]),
        ...                           5000, generator=g)
        >>> new.tolist(), bool(lost[1] > 0), float(lost[0])
        ([0.0, 5000.0], True, 0.0)
    """
    if arrivals is None:
        if generator is None:
            raise ValueError("generator must be a torch.Generator when arrivals is not given")
        arrivals = torch.poisson(rate.expand_as(buffer), generator=generator)
    elif arrivals.shape != buffer.shape:
        raise ValueError(
            f"arrivals must be shaped like buffer {tuple(buffer.shape)}, "
            f"got {tuple(arrivals.shape)}"
        )
    total = buffer + arrivals
    overflow = (total - capacity).clamp_min(0.0)
    return total - overflow, overflow
