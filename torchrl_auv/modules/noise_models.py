r"""Noise models :math:`\epsilon_\theta(x_t, t, s)` for the diffusion proposer (paper eq. 4, 6).

Both models see the noisy action chunk :math:`x_t` ``[*B, H, A]`` and a conditioning vector
:math:`c = [\mathrm{MLP}(s),\ \mathrm{MLP}(\mathrm{sin/cos}(t))]` (the paper's
Concat[MLP(state), TimeEmb(t)]). Every residual block is FiLM-modulated by :math:`c`:
:math:`h \leftarrow h + f(\gamma(c) \odot \mathrm{norm}(h) + \beta(c))`. The affine maps
:math:`\gamma, \beta` are linear in :math:`c`, so they split into a state part, computed once per
proposal by :meth:`condition`, and a time part, computed once per denoising step for the whole
batch; a denoising step then costs only the blocks themselves.

* :class:`TemporalUNet1d` (the paper's U-Net): 1-D convolutions over the horizon ``H`` with
  ``len(channels)`` levels, down-sampling by 2 between levels (``H`` must be divisible by
  ``2 ** (levels - 1)``) and skip connections.
* :class:`MLPNoiseModel`: residual MLP on the flattened chunk (works for ``H = 1``).
"""

from __future__ import annotations

import math

import torch
from torch import nn

__all__ = ["MLPNoiseModel", "SinusoidalEmbedding", "TemporalUNet1d", "make_noise_model"]


class SinusoidalEmbedding(nn.Module):
    """``[sin(t w_k), cos(t w_k)]`` with ``w_k = 10000^{-k/(d/2)}`` (Vaswani et al.), ``[*, d]``.

    >>> SinusoidalEmbedding(8)(torch.tensor([0.0, 10.0])).shape
    torch.Size([2, 8])
    """

    def __init__(self, dim: int) -> None:
        super().__init__()
        if dim < 2 or dim % 2:
            raise ValueError(f"dim must be an even int >= 2, got {dim}")
        half = dim // 2
        freqs = torch.exp(-math.log(10000.0) * torch.arange(half) / max(half - 1, 1))
        self.register_buffer("freqs", freqs, persistent=False)

    def forward(self, t: torch.Tensor) -> torch.Tensor:
        angle = t.to(self.freqs.dtype).unsqueeze(-1) * self.freqs
        return torch.cat([angle.sin(), angle.cos()], -1)


class _Conditioner(nn.Module):
    """State and time encoders plus the FiLM maps of every block, split into state and time
    parts (``film(c) = W_s MLP(s) + W_t MLP(emb(t)) + b``, equal to a linear map of the
    concatenation)."""

    def __init__(self, state_dim: int, cond_dim: int, block_dims: list[int]) -> None:
        super().__init__()
        self.state_mlp = nn.Sequential(
            nn.Linear(state_dim, cond_dim), nn.Mish(), nn.Linear(cond_dim, cond_dim)
        )
        self.time_mlp = nn.Sequential(
            SinusoidalEmbedding(cond_dim),
            nn.Linear(cond_dim, cond_dim),
            nn.Mish(),
            nn.Linear(cond_dim, cond_dim),
        )
        total = 2 * sum(block_dims)
        self.state_film = nn.Linear(cond_dim, total)
        self.time_film = nn.Linear(cond_dim, total, bias=False)
        self.block_dims = block_dims

    def state_part(self, state: torch.Tensor) -> torch.Tensor:
        return self.state_film(nn.functional.mish(self.state_mlp(state)))

    def time_part(self, t: torch.Tensor) -> torch.Tensor:
        return self.time_film(nn.functional.mish(self.time_mlp(t)))

    def split(self, film: torch.Tensor) -> list[tuple[torch.Tensor, torch.Tensor]]:
        out, start = [], 0
        for d in self.block_dims:
            scale, shift = film[..., start : start + d], film[..., start + d : start + 2 * d]
            out.append((scale, shift))
            start += 2 * d
        return out


class _NoiseModel(nn.Module):
    """Common interface: ``condition(state)`` once, then ``denoise(x, t, cond)`` per step."""

    horizon: int
    action_dim: int

    def condition(self, state: torch.Tensor) -> torch.Tensor:
        """State part of the FiLM parameters, ``[*B, F]`` (once per proposal)."""
        return self.conditioner.state_part(state)

    def forward(self, x: torch.Tensor, t: torch.Tensor, state: torch.Tensor) -> torch.Tensor:
        """Predicted noise for ``x`` ``[*B, H, A]`` at steps ``t`` ``[*B]`` given ``state``."""
        return self.denoise(x, t, self.condition(state))

    def denoise(self, x: torch.Tensor, t: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        film = cond + self.conditioner.time_part(t)
        return self._blocks(x, self.conditioner.split(film))

    def _blocks(self, x, films):  # pragma: no cover - abstract
        raise NotImplementedError


class MLPNoiseModel(_NoiseModel):
    """Residual MLP noise model on the flattened chunk ``[*B, H * A]``.

    Args:
        state_dim: conditioning state size.
        action_dim: ``A``; horizon: ``H``.
        hidden: width of the residual blocks; depth: number of blocks.
        cond_dim: width of the state and time encodings.

    >>> model = MLPNoiseModel(10, 3, horizon=8, hidden=64, depth=2, cond_dim=32)
    >>> model(torch.zeros(4, 8, 3), torch.tensor([0, 1, 2, 3]), torch.zeros(4, 10)).shape
    torch.Size([4, 8, 3])
    """

    def __init__(
        self,
        state_dim: int,
        action_dim: int,
        *,
        horizon: int = 8,
        hidden: int = 128,
        depth: int = 3,
        cond_dim: int = 64,
    ) -> None:
        super().__init__()
        _check_sizes(
            state_dim=state_dim,
            action_dim=action_dim,
            horizon=horizon,
            hidden=hidden,
            depth=depth,
            cond_dim=cond_dim,
        )
        self.horizon, self.action_dim = horizon, action_dim
        self.conditioner = _Conditioner(state_dim, cond_dim, [hidden] * depth)
        self.inp = nn.Linear(horizon * action_dim, hidden)
        self.norms = nn.ModuleList(
            nn.LayerNorm(hidden, elementwise_affine=False) for _ in range(depth)
        )
        self.mlps = nn.ModuleList(
            nn.Sequential(nn.Linear(hidden, hidden), nn.Mish(), nn.Linear(hidden, hidden))
            for _ in range(depth)
        )
        self.out = nn.Sequential(nn.Mish(), nn.Linear(hidden, horizon * action_dim))

    def _blocks(self, x, films):
        h = self.inp(x.flatten(-2))
        for norm, mlp, (scale, shift) in zip(self.norms, self.mlps, films, strict=True):
            h = h + mlp(norm(h) * (1 + scale) + shift)
        return self.out(h).unflatten(-1, (self.horizon, self.action_dim))


class _ConvBlock(nn.Module):
    def __init__(self, channels: int, kernel: int = 3) -> None:
        super().__init__()
        self.norm = nn.GroupNorm(1, channels, affine=False)
        self.conv1 = nn.Conv1d(channels, channels, kernel, padding=kernel // 2)
        self.conv2 = nn.Conv1d(channels, channels, kernel, padding=kernel // 2)

    def forward(self, h, scale, shift):
        z = self.norm(h) * (1 + scale.unsqueeze(-1)) + shift.unsqueeze(-1)
        return h + self.conv2(nn.functional.mish(self.conv1(nn.functional.mish(z))))


class TemporalUNet1d(_NoiseModel):
    """1-D temporal U-Net over the action horizon with FiLM conditioning.

    Levels have ``channels[i]`` channels; each has one FiLM residual block on the way down and
    one on the way up, with stride-2 down-sampling between levels and skip connections.

    Args:
        state_dim: conditioning state size.
        action_dim: ``A``; horizon: ``H`` (divisible by ``2 ** (len(channels) - 1)``).
        channels: channels per level, e.g. ``(64, 128)``.
        cond_dim: width of the state and time encodings.

    >>> model = TemporalUNet1d(10, 3, horizon=8, channels=(32, 64), cond_dim=32)
    >>> model(torch.zeros(2, 8, 3), torch.tensor([5, 6]), torch.zeros(2, 10)).shape
    torch.Size([2, 8, 3])
    """

    def __init__(
        self,
        state_dim: int,
        action_dim: int,
        *,
        horizon: int = 8,
        channels: tuple[int, ...] = (64, 128),
        cond_dim: int = 128,
    ) -> None:
        super().__init__()
        _check_sizes(state_dim=state_dim, action_dim=action_dim, horizon=horizon, cond_dim=cond_dim)
        if len(channels) < 1 or min(channels) < 1:
            raise ValueError(f"channels must be a non-empty tuple of ints >= 1, got {channels}")
        factor = 2 ** (len(channels) - 1)
        if horizon % factor:
            raise ValueError(
                f"horizon must be divisible by 2 ** (levels - 1) = {factor} for "
                f"{len(channels)} levels, got {horizon}"
            )
        self.horizon, self.action_dim = horizon, action_dim
        levels = list(channels)
        self.conditioner = _Conditioner(state_dim, cond_dim, levels + levels[::-1])
        self.inp = nn.Conv1d(action_dim, levels[0], 3, padding=1)
        self.down_blocks = nn.ModuleList(_ConvBlock(c) for c in levels)
        self.downs = nn.ModuleList(
            nn.Conv1d(levels[i], levels[i + 1], 3, stride=2, padding=1)
            for i in range(len(levels) - 1)
        )
        self.up_blocks = nn.ModuleList(_ConvBlock(c) for c in levels[::-1])
        self.ups = nn.ModuleList(
            nn.ConvTranspose1d(levels[i + 1], levels[i], 4, stride=2, padding=1)
            for i in reversed(range(len(levels) - 1))
        )
        self.out = nn.Conv1d(levels[0], action_dim, 1)

    def _blocks(self, x, films):
        batch = x.shape[:-2]
        h = self.inp(x.reshape(-1, *x.shape[-2:]).transpose(-1, -2))
        flat = [(s.reshape(-1, s.shape[-1]), b.reshape(-1, b.shape[-1])) for s, b in films]
        flat = [(s.expand(h.shape[0], -1), b.expand(h.shape[0], -1)) for s, b in flat]
        n = len(self.down_blocks)
        skips = []
        for i, block in enumerate(self.down_blocks):
            h = block(h, *flat[i])
            if i < n - 1:
                skips.append(h)
                h = self.downs[i](h)
        for j, block in enumerate(self.up_blocks):
            if j > 0:
                h = self.ups[j - 1](h) + skips.pop()
            h = block(h, *flat[n + j])
        return self.out(h).transpose(-1, -2).reshape(*batch, self.horizon, self.action_dim)


def _check_sizes(**sizes: int) -> None:
    for name, value in sizes.items():
        if not (isinstance(value, int) and value >= 1):
            raise ValueError(f"{name} must be an int >= 1, got {value!r}")


def make_noise_model(
    kind: str, state_dim: int, action_dim: int, *, horizon: int, **kwargs: object
) -> _NoiseModel:
    """``"unet"`` -> :class:`TemporalUNet1d`, ``"mlp"`` -> :class:`MLPNoiseModel`.

    >>> make_noise_model("mlp", 4, 2, horizon=1).horizon
    1
    """
    if kind == "unet":
        return TemporalUNet1d(state_dim, action_dim, horizon=horizon, **kwargs)
    if kind == "mlp":
        return MLPNoiseModel(state_dim, action_dim, horizon=horizon, **kwargs)
    raise ValueError(f"noise_model must be 'unet' or 'mlp', got {kind!r}")
