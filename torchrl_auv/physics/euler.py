r"""zyx Euler-angle matrices as a few batched operations (``R(\Theta)`` and ``T(\Theta)``).

Every entry of the body-to-NED rotation :math:`R` and of the angular-rate map :math:`T` is a
signed sum of at most two products of the trig factors :math:`1, c_\phi, c_\theta, c_\psi,
s_\phi, s_\theta, s_\psi, t_\theta = s_\theta / c_\theta, 1 / c_\theta`. The tables below
spell them out; they are turned once into index and sign tensors, so that building both
matrices costs three gathers, three products and one sum whatever the batch size (eager torch
spends about a microsecond per operation on a small batch, so the 40-odd scalar operations
of the textbook form dominated a one-vehicle step).

.. math::

    R = \begin{bmatrix}
        c_\psi c_\theta & -s_\psi c_\phi + c_\psi s_\theta s_\phi
            & s_\psi s_\phi + c_\psi c_\phi s_\theta \\
        s_\psi c_\theta & c_\psi c_\phi + s_\phi s_\theta s_\psi
            & -c_\psi s_\phi + s_\theta s_\psi c_\phi \\
        -s_\theta & c_\theta s_\phi & c_\theta c_\phi \end{bmatrix},\qquad
    T = \begin{bmatrix} 1 & s_\phi t_\theta & c_\phi t_\theta \\ 0 & c_\phi & -s_\phi \\
        0 & s_\phi / c_\theta & c_\phi / c_\theta \end{bmatrix}

(:math:`T` is singular at :math:`\theta = \pm 90°`; nothing guards against it, as in Fossen's
simulator.)
"""

from __future__ import annotations

import torch

__all__ = ["euler_matrices", "trig_factors"]

#: The factor names, in the order of :func:`trig_factors`' last dimension.
FACTORS = ("1", "c_phi", "c_th", "c_psi", "s_phi", "s_th", "s_psi", "t_th", "sec_th")

#: R then T, row by row: each entry a sum of signed products ("0" for a zero entry).
ENTRIES = (
    "c_psi*c_th",
    "-s_psi*c_phi + c_psi*s_th*s_phi",
    "s_psi*s_phi + c_psi*c_phi*s_th",
    "s_psi*c_th",
    "c_psi*c_phi + s_phi*s_th*s_psi",
    "-c_psi*s_phi + s_th*s_psi*c_phi",
    "-s_th",
    "c_th*s_phi",
    "c_th*c_phi",
    "1",
    "s_phi*t_th",
    "c_phi*t_th",
    "0",
    "c_phi",
    "-s_phi",
    "0",
    "s_phi*sec_th",
    "c_phi*sec_th",
)


def _tables() -> tuple[torch.Tensor, torch.Tensor]:
    """``(index [3, 36], signs [36])`` from :data:`ENTRIES`: row ``f`` of ``index`` holds the
    ``f``-th factor of every term (two terms per entry, padded with ``1``; a missing term has
    the sign 0)."""
    index = torch.zeros(3, 2 * len(ENTRIES), dtype=torch.long)
    signs = torch.zeros(2 * len(ENTRIES))
    for e, entry in enumerate(ENTRIES):
        if entry == "0":
            continue
        terms = entry.replace("- ", "+ -").split(" + ")
        for t, term in enumerate(terms):
            signs[2 * e + t] = -1.0 if term.startswith("-") else 1.0
            for f, name in enumerate(term.lstrip("-").split("*")):
                index[f, 2 * e + t] = FACTORS.index(name)
    return index, signs


_INDEX, _SIGNS = _tables()
_CACHE: dict[tuple[torch.dtype, torch.device, bool], tuple[torch.Tensor, torch.Tensor]] = {}


def trig_factors(cos: torch.Tensor, sin: torch.Tensor) -> torch.Tensor:
    """The factors of :data:`FACTORS`, ``[*B, 9]``, from the cosines and sines of
    ``(phi, theta, psi)`` (each ``[*B, 3]``)."""
    one = torch.ones_like(cos[..., :1])
    tan_sec = torch.cat((sin[..., 1:2], one), -1) / cos[..., 1:2]
    return torch.cat((one, cos, sin, tan_sec), -1)


def euler_matrices(factors: torch.Tensor, *, rotation_only: bool = False) -> torch.Tensor:
    r"""``[*B, 2, 3, 3]``: :math:`R` and :math:`T` (module docstring) from :func:`trig_factors`;
    ``[*B, 3, 3]``, :math:`R` alone, with ``rotation_only``.

    Examples:
        >>> import math
        >>> angles = torch.tensor([0.0, 0.0, math.pi / 2])
        >>> m = euler_matrices(trig_factors(angles.cos(), angles.sin()))
        >>> m[0].round(decimals=6) + 0.0  # R: body x points east
        tensor([[ 0., -1.,  0.],
                [ 1.,  0.,  0.],
                [ 0.,  0.,  1.]])
    """
    key = (factors.dtype, factors.device, rotation_only)
    tables = _CACHE.get(key)
    if tables is None:
        terms = 18 if rotation_only else 36
        tables = _CACHE[key] = (
            _INDEX[:, :terms].to(factors.device),
            _SIGNS[:terms].to(dtype=factors.dtype, device=factors.device),
        )
    index, signs = tables
    products = factors.index_select(-1, index[0]) * factors.index_select(-1, index[1])
    products = products * factors.index_select(-1, index[2]) * signs
    entries = products.unflatten(-1, (-1, 2)).sum(-1)  # each entry: its two signed terms
    return entries.unflatten(-1, (3, 3) if rotation_only else (2, 3, 3))
