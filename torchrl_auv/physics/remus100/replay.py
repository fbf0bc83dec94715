"""Replay a reference CSV through the model: ``python -m torchrl_auv.cli.remus100 replay IN.csv
OUT.csv`` starts from row 0's state and applies each later row's commands, one step of ``dt``
(0.05 s) per row, writing the simulated rows in the same format.

**The CSV format** (one row per step, a header row first; the repository's reference runs
of Fossen's Python Vehicle Simulator, ``tests/data/remus100/``, are in it):

=================================  ========================================  =============
column                             meaning                                   unit
=================================  ========================================  =============
step, t                            step index k and k x dt                   -, s
cmd_delta_r, cmd_delta_s, cmd_n    rudder, stern-plane and propeller         rad, rad, rpm
                                   commands applied in the step that
                                   produced the row (nan on row 0)
Vc, beta_c                         current speed and direction               m/s, rad
x, y, z                            NED position, z down                      m
phi, theta, psi                    Euler angles (zyx), not wrapped           rad
u, v, w, p, q, r                   body-frame velocity and angular rates     m/s, rad/s
delta_r, delta_s, n                actuator states after the step            rad, rad, rpm
=================================  ========================================  =============

Other columns are copied through; a missing column is a ``ValueError`` naming it.
"""

from __future__ import annotations

import csv
from collections.abc import Sequence

import torch

from torchrl_auv.physics.remus100.dynamics import step

# Column names of the reference CSV format, in state order (eta, nu, actuators).
ETA_COLUMNS = ("x", "y", "z", "phi", "theta", "psi")
NU_COLUMNS = ("u", "v", "w", "p", "q", "r")
ACTUATOR_COLUMNS = ("delta_r", "delta_s", "n")
COMMAND_COLUMNS = ("cmd_delta_r", "cmd_delta_s", "cmd_n")
CURRENT_COLUMNS = ("Vc", "beta_c")
STATE_COLUMNS = ETA_COLUMNS + NU_COLUMNS + ACTUATOR_COLUMNS


# -- replay CLI ---------------------------------------------------------------------------
def _read_rows(path: str) -> tuple[list[str], list[dict[str, str]]]:
    with open(path, newline="") as handle:
        reader = csv.DictReader(handle)
        rows = list(reader)
        header = list(reader.fieldnames or [])
    missing = [
        c
        for c in ("step", "t", *COMMAND_COLUMNS, *CURRENT_COLUMNS, *STATE_COLUMNS)
        if c not in header
    ]
    if missing:
        raise ValueError(f"{path}: missing columns {missing}")
    if len(rows) < 1:
        raise ValueError(f"{path}: no rows")
    return header, rows


def replay(
    in_path: str, out_path: str, *, dtype: torch.dtype = torch.float64, dt: float = 0.05
) -> None:
    """Simulate a reference CSV's commands from its row-0 state and write the same format.

    Only row 0's state columns are read; every later row contributes its command and current
    columns, and the written state columns are simulated. Floats are written with ``repr``
    (shortest round-trip). ``dt`` is the step of the reference format (0.05 s).
    """
    header, rows = _read_rows(in_path)

    def column_block(row: dict[str, str], names: Sequence[str]) -> torch.Tensor:
        return torch.tensor([float(row[n]) for n in names], dtype=torch.float64).to(dtype)

    eta = column_block(rows[0], ETA_COLUMNS)
    nu = column_block(rows[0], NU_COLUMNS)
    act = column_block(rows[0], ACTUATOR_COLUMNS)
    out_rows = []
    for k, row in enumerate(rows):
        if k > 0:
            command = column_block(row, COMMAND_COLUMNS)
            current = column_block(row, CURRENT_COLUMNS)
            eta, nu, act = step(eta, nu, act, command, current, dt)
        state = torch.cat((eta, nu, act)).to(torch.float64).tolist()
        out = {name: row[name] for name in header}
        out.update({name: repr(value) for name, value in zip(STATE_COLUMNS, state, strict=True)})
        out_rows.append(out)
    with open(out_path, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=header, lineterminator="\n")
        writer.writeheader()
        writer.writerows(out_rows)
