"""Small tensor helpers shared by the physics and estimation modules."""

from __future__ import annotations

import torch

__all__ = ["FUSE_ROWS", "fusing", "small_matmul"]

#: Under ``torch.compile``, products with at most this many rows are written out elementwise.
FUSE_ROWS = 64


def fusing(a: torch.Tensor) -> bool:
    """Whether a product with ``a`` on the left is being compiled for few rows (at most
    :data:`FUSE_ROWS`): there a library matmul's launch and buffers cost more than its flops,
    while a broadcast product and sum fuses into the kernel around it."""
    return torch.compiler.is_compiling() and a.numel() // max(a.shape[-1], 1) <= FUSE_ROWS


def small_matmul(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """``a @ b`` for a small inner dimension, batched like ``@``.

    Eager, or compiled for many rows: the matmul. Compiled for few rows (:func:`fusing`): a
    broadcast product and a sum, which inductor fuses with its neighbours (a library matmul
    would be a separate call, with its own buffers, at every physics step).

    >>> a, b = torch.rand(4, 2, 3), torch.rand(4, 3, 5)
    >>> torch.allclose(small_matmul(a, b), a @ b)
    True
    """
    if fusing(a) and a.ndim >= 2 and b.ndim >= 2:
        return (a.unsqueeze(-1) * b.unsqueeze(-3)).sum(-2)
    return a @ b
