"""A top view of the data-collection scene as an RGB array (plain numpy, no plotting library).

:func:`top_view` draws one scene of :class:`~torchrl_auv.envs.DataCollectionEnv` from its
simulator state (``td["sim"]``): the seabed's depth as shades of blue, the area's edge, the
sensor nodes (filled by the data waiting in their buffers, relative to the fullest), each AUV's
track so far, the AUV (a disc with a heading tick, ringed while in service) and a line to its
assigned node, and the surface vessel (ASV). North is up, east to the right, as in the env's NED
frame (``x`` north, ``y`` east, metres). Used by the gymnasium view's ``render_mode="rgb_array"``
(so gymnasium's ``RecordVideo`` records episodes).

>>> from torchrl_auv.envs import DataCollectionEnv
>>> env = DataCollectionEnv(batch_size=[], seed=0)
>>> frame = top_view(env.reset()["sim"], env.config.area_m, size=128)
>>> frame.shape, frame.dtype
((128, 128, 3), dtype('uint8'))
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Sequence

import numpy as np
from tensordict import TensorDictBase

__all__ = ["AUV_COLOURS", "top_view"]

#: one colour per AUV (RGB), repeated beyond eight AUVs
AUV_COLOURS = np.array(
    [
        [228, 26, 28],
        [255, 127, 0],
        [152, 78, 163],
        [77, 175, 74],
        [166, 86, 40],
        [247, 129, 191],
        [153, 153, 153],
        [255, 255, 51],
    ],
    dtype=np.uint8,
)
_EDGE = np.array([40, 40, 40], np.uint8)
_NODE = np.array([0, 0, 0], np.uint8)
_ASV = np.array([255, 255, 255], np.uint8)
_MARGIN = 0.15  # view beyond the area, as a fraction of its size on each side


class _Canvas:
    """Metres (north, east) to pixels (row, column) and the drawing primitives."""

    def __init__(self, area_m: Sequence[float], size: int) -> None:
        self.size = size
        north, east = float(area_m[0]), float(area_m[1])
        span = max(north, east) * (1 + 2 * _MARGIN)
        self.scale = size / span  # pixels per metre
        self.origin = np.array([-_MARGIN * north, -_MARGIN * east])  # (north, east) of pixel 0
        self.image = np.zeros((size, size, 3), np.uint8)

    def pixel(self, north_east: np.ndarray) -> np.ndarray:
        """(row, col) float pixel coordinates of points ``[..., 2]`` in metres."""
        ne = (np.asarray(north_east, np.float64) - self.origin) * self.scale
        return np.stack([self.size - ne[..., 0], ne[..., 1]], -1)

    def disc(self, centre: np.ndarray, radius_px: float, colour, *, ring: float = 0) -> None:
        row, col = self.pixel(centre)
        lo_r, hi_r = int(max(row - radius_px - 1, 0)), int(min(row + radius_px + 2, self.size))
        lo_c, hi_c = int(max(col - radius_px - 1, 0)), int(min(col + radius_px + 2, self.size))
        if lo_r >= hi_r or lo_c >= hi_c:
            return
        rr, cc = np.mgrid[lo_r:hi_r, lo_c:hi_c]
        dist = np.hypot(rr + 0.5 - row, cc + 0.5 - col)
        mask = dist <= radius_px
        if ring:
            mask &= dist >= radius_px - ring
        self.image[lo_r:hi_r, lo_c:hi_c][mask] = colour

    def line(self, start: np.ndarray, end: np.ndarray, colour) -> None:
        a, b = self.pixel(start), self.pixel(end)
        n = int(np.ceil(np.abs(b - a).max())) + 1
        points = np.rint(a + np.linspace(0, 1, n)[:, None] * (b - a) - 0.5).astype(int)
        inside = ((points >= 0) & (points < self.size)).all(-1)
        self.image[points[inside, 0], points[inside, 1]] = colour

    def dots(self, points: np.ndarray, colour) -> None:
        """One pixel per point ``[..., 2]`` (metres), those inside the image."""
        rc = np.floor(self.pixel(np.asarray(points).reshape(-1, 2))).astype(int)
        inside = ((rc >= 0) & (rc < self.size)).all(-1)
        self.image[rc[inside, 0], rc[inside, 1]] = colour


@functools.lru_cache(maxsize=8)
def _background(area_m: tuple[float, float], size: int, depth_bytes: bytes, grid: int):
    """The seabed and the area's edge (the same for every decision of a scene: cached)."""
    canvas = _Canvas(area_m, size)
    depth = np.frombuffer(depth_bytes, np.float64).reshape(grid, grid)
    _seabed(canvas, depth, area_m)
    corners = np.array([[0, 0], [area_m[0], 0], [area_m[0], area_m[1]], [0, area_m[1]], [0, 0]])
    for start, end in itertools.pairwise(corners):
        canvas.line(start, end, _EDGE)
    return canvas.image


def _seabed(canvas: _Canvas, depth: np.ndarray, area_m: Sequence[float]) -> None:
    """Depth grid ``[G, G]`` over the area (row = north, column = east) as blues; outside grey."""
    grid, size = depth.shape[0], canvas.size
    rows, cols = np.mgrid[0:size, 0:size]
    north = (size - 0.5 - rows) / canvas.scale + canvas.origin[0]  # each pixel's centre (m)
    east = (cols + 0.5) / canvas.scale + canvas.origin[1]
    i = np.clip(np.rint(north / area_m[0] * (grid - 1)).astype(int), 0, grid - 1)
    j = np.clip(np.rint(east / area_m[1] * (grid - 1)).astype(int), 0, grid - 1)
    shade = (depth[i, j] - depth.min()) / max(float(np.ptp(depth)), 1e-6)  # 0 shallow, 1 deep
    blue = np.stack([60 - 40 * shade, 140 - 80 * shade, 210 - 60 * shade], -1)
    inside = (north >= 0) & (north <= area_m[0]) & (east >= 0) & (east <= area_m[1])
    canvas.image[:] = np.where(inside[..., None], blue, 200).astype(np.uint8)


def top_view(
    sim: TensorDictBase,
    area_m: Sequence[float],
    *,
    size: int = 400,
    tracks: np.ndarray | None = None,
) -> np.ndarray:
    """The scene of one unbatched simulator state as an RGB image.

    Args:
        sim: ``td["sim"]`` of an unbatched :class:`~torchrl_auv.envs.DataCollectionEnv`
            (either layout).
        area_m: the area's (north, east) size in metres (``env.config.area_m``).
        size: the image's side in pixels.
        tracks: the AUVs' past (north, east) positions ``[T, N, 2]`` in metres, drawn as dots.

    Returns:
        ``uint8`` array ``[size, size, 3]``.
    """
    if sim.batch_size.numel() != 1 or sim.batch_dims:
        raise ValueError(f"sim must be one unbatched scene, got batch_size {tuple(sim.batch_size)}")
    if not (isinstance(size, int) and size >= 32):
        raise ValueError(f"size must be an int >= 32 pixels, got {size!r}")
    canvas = _Canvas(area_m, size)
    task = sim["task"]
    depth = np.ascontiguousarray(task["terrain", "depth"].double().numpy())
    area = (float(area_m[0]), float(area_m[1]))
    canvas.image[:] = _background(area, size, depth.tobytes(), depth.shape[0])
    nodes = task["nodes", "position"].double().numpy()[:, :2]
    buffers = task["nodes", "buffer"].double().numpy()
    fill = buffers / max(float(buffers.max()), 1e-9)
    radius = max(size / 160, 1.5)
    for position, level in zip(nodes, fill, strict=True):
        canvas.disc(position, radius, (255 * (1 - level), 255, 255 * (1 - level)))
        canvas.disc(position, radius, _NODE, ring=1)
    eta = sim["truth", "eta"].double().numpy()
    colours = AUV_COLOURS[np.arange(len(eta)) % len(AUV_COLOURS)]
    if tracks is not None:
        tracks = np.asarray(tracks)
        for k, colour in enumerate(colours):
            canvas.dots(tracks[:, k], colour)
    auvs = task["auvs"]
    targets = auvs["target"].numpy()
    in_service = auvs["in_service"].numpy()
    for k, (pose, colour) in enumerate(zip(eta, colours, strict=True)):
        canvas.line(pose[:2], nodes[targets[k]], colour)
        canvas.disc(pose[:2], 2.2 * radius, colour)
        tick = 4 * radius / canvas.scale  # metres
        canvas.line(pose[:2], pose[:2] + tick * np.array([np.cos(pose[5]), np.sin(pose[5])]), _EDGE)
        if in_service[k]:
            canvas.disc(pose[:2], 3.4 * radius, colour, ring=1.2)
    canvas.disc(sim["asv"].double().numpy()[:2], 1.5 * radius, _ASV)
    return canvas.image
