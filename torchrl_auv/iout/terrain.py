r"""Smooth random seabed: a depth grid drawn from a generator, looked up bilinearly.

A scene's seabed is a sum of ``K`` random plane cosine waves evaluated on a regular
``G x G`` grid over the area,

.. math::

    h(x, y) = \sum_{k=1}^{K} a_k \cos(k_{x,k} x + k_{y,k} y + \varphi_k),\qquad
    |k_k| = 2\pi/\ell_k,\ \ell_k \sim U(\ell_{min}, \ell_{max}),\ a_k \propto \ell_k,

then scaled per scene so that the grid's minimum and maximum are exactly the configured seabed
depth range (39-58 m). Between grid points the depth is bilinear, so every lookup stays inside
the range. Points outside the area read the nearest edge.
"""

from __future__ import annotations

import math

import torch
from tensordict import TensorDict

from torchrl_auv.iout.config import IoUTConfig

__all__ = ["make_terrain", "seabed_depth"]


def make_terrain(
    config: IoUTConfig,
    batch_shape: tuple[int, ...] | torch.Size,
    *,
    generator: torch.Generator,
    dtype: torch.dtype = torch.float32,
    device: torch.device | str | None = None,
) -> TensorDict:
    """Draw a random seabed per scene.

    Args:
        config: task configuration (area, depth range, grid size, modes, wavelengths).
        batch_shape: scene batch shape ``[*B]``.
        generator: the only source of randomness.
        dtype: floating dtype of the grid.
        device: device of the grid (the generator's device).

    Returns:
        TensorDict with batch ``[*B]`` and key ``"depth"``: ``[*B, G, G]`` seabed depth (m,
        positive down); ``depth[..., i, j]`` is at ``x = i * area_x / (G - 1)``,
        ``y = j * area_y / (G - 1)``.

    Examples:
        >>> g = torch.Generator().manual_seed(0)
        >>> terrain = make_terrain(IoUTConfig(), (2,), generator=g)
        >>> terrain["depth"].shape
        torch.Size([2, 41, 41])
        >>> round(terrain["depth"].min().item(), 3), round(terrain["depth"].max().item(), 3)
        (39.0, 58.0)
    """
    shape = torch.Size(batch_shape)
    k, g_pts = config.terrain_modes, config.terrain_grid_points

    def uniform(low: float, high: float) -> torch.Tensor:
        u = torch.rand((*shape, k), generator=generator, dtype=dtype, device=device)
        return low + (high - low) * u

    wavelength = uniform(*config.terrain_wavelength_range_m)
    direction = uniform(-math.pi, math.pi)
    phase = uniform(-math.pi, math.pi)
    amplitude = uniform(0.5, 1.0) * wavelength
    wavenumber = 2.0 * math.pi / wavelength
    x = torch.linspace(0.0, config.area_m[0], g_pts, dtype=dtype, device=device)
    y = torch.linspace(0.0, config.area_m[1], g_pts, dtype=dtype, device=device)
    kx = (wavenumber * torch.cos(direction))[..., None, None]
    ky = (wavenumber * torch.sin(direction))[..., None, None]
    arg = kx * x[:, None] + ky * y[None, :] + phase[..., None, None]  # [*B, K, G, G]
    field = (amplitude[..., None, None] * torch.cos(arg)).sum(-3)
    flat = field.flatten(-2)
    low = flat.amin(-1)[..., None, None]
    span = (flat.amax(-1)[..., None, None] - low).clamp_min(torch.finfo(dtype).tiny)
    d_min, d_max = config.seabed_depth_range_m
    depth = d_min + (d_max - d_min) * (field - low) / span
    return TensorDict({"depth": depth}, batch_size=shape, device=device)


def seabed_depth(
    terrain: TensorDict, x: torch.Tensor, y: torch.Tensor, config: IoUTConfig
) -> torch.Tensor:
    r"""Bilinear seabed depth (m) at horizontal positions ``(x, y)`` (m).

    Args:
        terrain: from :func:`make_terrain`, batch ``[*B]``.
        x: north coordinates (m), ``[*B, ...]`` (any trailing shape, same as ``y``).
        y: east coordinates (m), ``[*B, ...]``.
        config: the configuration the terrain was made with (area size).

    Returns:
        Seabed depth (m), shaped like ``x``; positions outside the area are clamped onto it,
        a NaN coordinate (a diverged vehicle) gives NaN.

    Examples:
        >>> cfg = IoUTConfig()
        >>> terrain = make_terrain(cfg, (), generator=torch.Generator().manual_seed(0))
        >>> corner = seabed_depth(terrain, torch.tensor([0.0]), torch.tensor([0.0]), cfg)
        >>> bool(corner == terrain["depth"][0, 0])
        True
    """
    grid = terrain["depth"]
    g_pts = grid.shape[-1]
    batch = grid.shape[:-2]
    if x.shape != y.shape or x.shape[: len(batch)] != batch:
        raise ValueError(
            f"x and y must share a shape [*B, ...] with B = {tuple(batch)}, got {tuple(x.shape)} "
            f"and {tuple(y.shape)}"
        )
    flat_x = x.reshape(*batch, -1)
    flat_y = y.reshape(*batch, -1)
    lost = flat_x.isnan() | flat_y.isnan()  # a diverged vehicle: NaN depth, not a bad index
    u = (flat_x.nan_to_num(0.0) / config.area_m[0] * (g_pts - 1)).clamp(0.0, g_pts - 1)
    v = (flat_y.nan_to_num(0.0) / config.area_m[1] * (g_pts - 1)).clamp(0.0, g_pts - 1)
    i0 = u.floor().clamp(max=g_pts - 2).long()
    j0 = v.floor().clamp(max=g_pts - 2).long()
    fu, fv = u - i0, v - j0
    table = grid.reshape(*batch, g_pts * g_pts)

    def at(i: torch.Tensor, j: torch.Tensor) -> torch.Tensor:
        return torch.gather(table, -1, i * g_pts + j)

    depth = (
        (1 - fu) * (1 - fv) * at(i0, j0)
        + fu * (1 - fv) * at(i0 + 1, j0)
        + (1 - fu) * fv * at(i0, j0 + 1)
        + fu * fv * at(i0 + 1, j0 + 1)
    )
    return depth.masked_fill(lost, float("nan")).reshape(x.shape)
