"""REMUS-100 model: reference trajectories, batching, gradients, quirks of the spec, bad input."""

from __future__ import annotations

import csv
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from torchrl_auv.physics import remus100
from torchrl_auv.physics.remus100 import Remus100Params, dynamics, propeller_forces, step
from torchrl_auv.physics.remus100.replay import (
    ACTUATOR_COLUMNS,
    COMMAND_COLUMNS,
    CURRENT_COLUMNS,
    ETA_COLUMNS,
    NU_COLUMNS,
)

# The reference trajectories ship with the tests (tests/data/remus100/README.md);
# TORCHRL_AUV_REFERENCE_DIR points elsewhere.
REFERENCE_DIR = Path(
    os.environ.get(
        "TORCHRL_AUV_REFERENCE_DIR", Path(__file__).resolve().parents[1] / "data" / "remus100"
    )
)
REFERENCE_FILES = sorted(REFERENCE_DIR.glob("*.csv"))
DT = 0.05
DEG = math.pi / 180


def _load(path: Path) -> dict[str, torch.Tensor]:
    with open(path, newline="") as handle:
        rows = list(csv.DictReader(handle))

    def block(names):
        return torch.tensor([[float(r[n]) for n in names] for r in rows], dtype=torch.float64)

    return {
        "eta": block(ETA_COLUMNS),
        "nu": block(NU_COLUMNS),
        "act": block(ACTUATOR_COLUMNS),
        "cmd": block(COMMAND_COLUMNS),
        "cur": block(CURRENT_COLUMNS),
    }


def _rollout(data, dtype):
    eta, nu, act = (data[k][0].to(dtype) for k in ("eta", "nu", "act"))
    etas, nus, acts = [eta], [nu], [act]
    for k in range(1, data["eta"].shape[0]):
        eta, nu, act = step(eta, nu, act, data["cmd"][k].to(dtype), data["cur"][k].to(dtype), DT)
        etas.append(eta)
        nus.append(nu)
        acts.append(act)
    return torch.stack(etas).double(), torch.stack(nus).double(), torch.stack(acts).double()


def test_reference_files_present():
    assert len(REFERENCE_FILES) >= 4, f"no reference CSVs under {REFERENCE_DIR}"


@pytest.mark.parametrize("path", REFERENCE_FILES, ids=lambda p: p.stem)
def test_reference_rollout_float64(path):
    data = _load(path)
    eta, nu, act = _rollout(data, torch.float64)
    torch.testing.assert_close(eta, data["eta"], atol=1e-9, rtol=0)
    torch.testing.assert_close(nu, data["nu"], atol=1e-9, rtol=0)
    torch.testing.assert_close(act, data["act"], atol=1e-9, rtol=0)


@pytest.mark.parametrize("path", REFERENCE_FILES, ids=lambda p: p.stem)
def test_reference_rollout_float32(path):
    data = _load(path)
    eta, _, _ = _rollout(data, torch.float32)
    position_error = (eta[:, :3] - data["eta"][:, :3]).abs().max().item()
    angle_error = (eta[:, 3:] - data["eta"][:, 3:]).abs().max().item()
    assert position_error < 0.05, position_error
    assert angle_error < 1e-3, angle_error


@pytest.mark.parametrize("path", REFERENCE_FILES, ids=lambda p: p.stem)
def test_reference_one_step_batched(path):
    """All 1200 one-step predictions of a file in one batched call, to 1e-11."""
    data = _load(path)
    eta, nu, act = step(
        data["eta"][:-1], data["nu"][:-1], data["act"][:-1], data["cmd"][1:], data["cur"][1:], DT
    )
    torch.testing.assert_close(eta, data["eta"][1:], atol=1e-11, rtol=0)
    torch.testing.assert_close(nu, data["nu"][1:], atol=1e-11, rtol=0)
    torch.testing.assert_close(act, data["act"][1:], atol=1e-11, rtol=0)


@pytest.mark.parametrize("path", REFERENCE_FILES, ids=lambda p: p.stem)
def test_three_wide_current_with_zero_vertical_is_pvs(path):
    """Spec v2: with no vertical water velocity the model is still PVS. A ``[V_c, beta_c, +0]``
    current gives the 2-wide rollout bit for bit, hence the reference to 1e-9."""
    data = _load(path)
    padded = dict(data, cur=torch.cat([data["cur"], torch.zeros_like(data["cur"][:, :1])], -1))
    eta, nu, act = _rollout(padded, torch.float64)
    two = _rollout(data, torch.float64)
    for got, want in zip((eta, nu, act), two, strict=True):
        assert torch.equal(got, want)
    torch.testing.assert_close(eta, data["eta"], atol=1e-9, rtol=0)
    torch.testing.assert_close(nu, data["nu"], atol=1e-9, rtol=0)
    torch.testing.assert_close(act, data["act"], atol=1e-9, rtol=0)


def test_zero_vertical_current_keeps_the_sign_of_zero_of_w():
    """Random states (reverse flow included, w = +0 and -0): [V, beta, +0] == [V, beta], bit
    for bit vehicle by vehicle. Batched, w_r = w - 0 is a new contiguous tensor where w was a
    strided view of nu, and torch's atan2 takes its SIMD kernel for contiguous inputs, which
    can differ from the scalar one in the last ulp: equal to rounding there."""
    gen = torch.Generator().manual_seed(11)
    eta, nu, act, cmd, cur = _random_vehicles(256, gen)
    nu[:64, 2] = 0.0
    nu[64:128, 2] = -0.0
    nu[:128, 0] = -0.3  # u_r < 0: atan2(+-0, u_r) = +-pi
    padded = torch.cat([cur, torch.zeros(256, 1, dtype=cur.dtype)], -1)
    for i in range(0, 256, 3):
        single = [x[i] for x in (eta, nu, act, cmd)]
        two, three = step(*single, cur[i], DT), step(*single, padded[i], DT)
        for a, b in zip(two, three, strict=True):
            assert torch.equal(a, b), i
    for a, b in zip(
        step(eta, nu, act, cmd, cur, DT), step(eta, nu, act, cmd, padded, DT), strict=True
    ):
        torch.testing.assert_close(a, b, rtol=1e-15, atol=1e-15)
        assert torch.equal(a[:128], b[:128])  # w = +-0: the sign of zero is kept


def _random_vehicles(n, generator, dtype=torch.float64):
    def uniform(shape, low, high):
        return low + (high - low) * torch.rand(shape, generator=generator, dtype=dtype)

    eta = torch.cat([uniform((n, 3), -50, 50), uniform((n, 3), -0.5, 0.5)], -1)
    nu = torch.cat([uniform((n, 3), -0.5, 2.5), uniform((n, 3), -0.2, 0.2)], -1)
    act = torch.cat([uniform((n, 2), -0.4, 0.4), uniform((n, 1), -1600, 1600)], -1)
    cmd = torch.cat([uniform((n, 2), -0.4, 0.4), uniform((n, 1), -1600, 1600)], -1)
    cur = torch.cat([uniform((n, 1), 0, 1.5), uniform((n, 1), -math.pi, math.pi)], -1)
    return eta, nu, act, cmd, cur


def test_batched_equals_looped():
    gen = torch.Generator().manual_seed(3)
    inputs = _random_vehicles(64, gen)
    batched = step(*inputs, DT)
    for i in range(64):
        single = step(*(x[i] for x in inputs), DT)
        for b, s in zip(batched, single, strict=True):
            torch.testing.assert_close(b[i], s, atol=1e-12, rtol=0)


def test_two_batch_dims_and_broadcast_current():
    gen = torch.Generator().manual_seed(4)
    eta, nu, act, cmd, cur = _random_vehicles(12, gen)
    flat = step(eta, nu, act, cmd, cur[:1].expand(12, 2), DT)
    nested = step(
        eta.view(3, 4, 6), nu.view(3, 4, 6), act.view(3, 4, 3), cmd.view(3, 4, 3), cur[0], DT
    )
    for f, n in zip(flat, nested, strict=True):
        torch.testing.assert_close(n.reshape(f.shape), f, atol=1e-12, rtol=0)


def test_inputs_not_modified_and_dtype_follows():
    gen = torch.Generator().manual_seed(5)
    inputs = [x.float() for x in _random_vehicles(8, gen)]
    copies = [x.clone() for x in inputs]
    out = step(*inputs, DT)
    for x, c in zip(inputs, copies, strict=True):
        assert torch.equal(x, c)
    assert all(o.dtype == torch.float32 for o in out)


def test_gradients_flow_without_nan():
    gen = torch.Generator().manual_seed(6)
    eta, nu, act, cmd, cur = _random_vehicles(16, gen)
    nu[:, 0] = nu[:, 0].abs() + 0.5  # ordinary moving states
    eta.requires_grad_(True)
    nu.requires_grad_(True)
    cmd.requires_grad_(True)
    e1, n1, a1 = step(eta, nu, act, cmd, cur, DT)
    for _ in range(5):
        e1, n1, a1 = step(e1, n1, a1, cmd, cur, DT)
    loss = e1.square().sum() + n1.square().sum() + a1.square().sum()
    grads = torch.autograd.grad(loss, (eta, nu, cmd))
    for g in grads:
        assert torch.isfinite(g).all()
        assert g.abs().sum() > 0


def test_compiled_step_matches_eager():
    gen = torch.Generator().manual_seed(7)
    inputs = [x.float() for x in _random_vehicles(4, gen)]
    eager = step(*inputs, DT)
    compiled = remus100.compiled_step(*inputs, DT)
    for e, c in zip(eager, compiled, strict=True):
        torch.testing.assert_close(c, e, atol=1e-4, rtol=1e-5)


# -- behaviour stated by the spec (held-out scenarios exercise the same physics) ------------
def _run(cmd, seconds, *, current=(0.0, 0.0), eta0=None, nu0=None, act0=None):
    dtype = torch.float64
    eta = torch.zeros(6, dtype=dtype) if eta0 is None else torch.tensor(eta0, dtype=dtype)
    nu = torch.zeros(6, dtype=dtype) if nu0 is None else torch.tensor(nu0, dtype=dtype)
    act = torch.zeros(3, dtype=dtype) if act0 is None else torch.tensor(act0, dtype=dtype)
    cmd_t, cur = torch.tensor(cmd, dtype=dtype), torch.tensor(current, dtype=dtype)
    for _ in range(round(seconds / DT)):
        eta, nu, act = step(eta, nu, act, cmd_t, cur, DT)
    return eta, nu, act


def test_steady_speed_and_roll_at_full_rpm():
    eta, nu, _ = _run((0.0, 0.0, 1525.0), 60)
    assert nu[0].item() == pytest.approx(2.5536, abs=5e-4)
    assert eta[3].item() == pytest.approx(0.01778, abs=2e-4)


def test_stored_actuator_exceeds_limit_but_force_saturates():
    """A 20 deg command settles the *stored* fin at 15 + (20 - 15)/2 = 17.5 deg (h/T = 0.5)."""
    _, _, act = _run((20 * DEG, -20 * DEG, 2000.0), 5)
    assert act[0].item() == pytest.approx(17.5 * DEG, abs=1e-9)
    assert act[1].item() == pytest.approx(-17.5 * DEG, abs=1e-9)
    assert act[2].item() == pytest.approx(1525 + 0.05 * (2000 - 1525), rel=1e-3)
    z3 = torch.zeros(3, dtype=torch.float64)
    z6 = torch.zeros(6, dtype=torch.float64)
    nu = torch.tensor([2.0, 0, 0, 0, 0, 0], dtype=torch.float64)
    beyond = torch.tensor([17.5 * DEG, 0, 0], dtype=torch.float64)
    at_limit = torch.tensor([15 * DEG, 0, 0], dtype=torch.float64)
    nd_beyond, _, _ = dynamics(z6, nu, beyond, z3, torch.zeros(2, dtype=torch.float64))
    nd_limit, _, _ = dynamics(z6, nu, at_limit, z3, torch.zeros(2, dtype=torch.float64))
    torch.testing.assert_close(nd_beyond, nd_limit, atol=0, rtol=0)


def test_rudder_turns_to_starboard_and_stern_plane_dives():
    eta, nu, _ = _run((10 * DEG, 0.0, 1525.0), 20)
    assert nu[5] > 0.05 and eta[5] > 0.5
    eta, _, _ = _run((0.0, 8 * DEG, 1525.0), 10)
    assert eta[4] < -0.2 and eta[2] > 2.0


def test_reverse_rpm_branch_has_no_advance_term():
    n = torch.tensor([-1000.0, -1000.0], dtype=torch.float64)
    speed = torch.tensor([0.0, 2.0], dtype=torch.float64)
    thrust, torque = propeller_forces(n, speed)
    assert thrust[0] == thrust[1] and thrust[0] < 0 and torque[0] < 0
    thrust_fwd, _ = propeller_forces(-n, speed)
    assert thrust_fwd[1] < thrust_fwd[0]  # forward thrust falls with advance speed
    zero, _ = propeller_forces(torch.tensor(0.0), torch.tensor(1.0))
    assert zero.item() == 0.0


def test_head_current_from_rest_uses_atan2():
    """Spec Sec. 8 quirk 1: at rest, psi = 0, 0.5 m/s current from 30 deg: alpha = +pi."""
    p = Remus100Params()
    z6 = torch.zeros(6, dtype=torch.float64)
    act = torch.tensor([0.0, 0.0, 0.0], dtype=torch.float64)
    current = torch.tensor([0.5, 30 * DEG], dtype=torch.float64)
    nu_dot, _, _ = dynamics(z6, z6, act, act, current, p)
    m_inv = torch.tensor(p.mass_matrix_inverse, dtype=torch.float64)
    force = torch.linalg.solve(m_inv, nu_dot - torch.tensor([0.0] * 6, dtype=torch.float64))
    assert force[0].item() == pytest.approx(53, abs=1.5)
    assert force[2].item() == pytest.approx(23, abs=1.5)
    # with a negative zero heave velocity the lift flips sign: atan2(-0, u_r < 0) = -pi
    nu_neg = torch.tensor([0.0, 0.0, -0.0, 0.0, 0.0, 0.0], dtype=torch.float64)
    nu_dot_neg, _, _ = dynamics(z6, nu_neg, act, act, current, p)
    force_neg = torch.linalg.solve(m_inv, nu_dot_neg)
    assert force_neg[2].item() == pytest.approx(-force[2].item(), rel=1e-9)


def test_psi_is_not_wrapped():
    eta, _, _ = _run((10 * DEG, 0.0, 1525.0), 60)
    assert eta[5].item() > math.pi


def test_derived_parameters_match_spec_values():
    p = Remus100Params()
    assert p.mass == pytest.approx(31.029384975800244, rel=1e-15)
    assert p.crossflow_cd == pytest.approx(1.1977288343558283, rel=1e-15)
    assert p.mass_matrix_inverse[3][3] == pytest.approx(6.5935479260017278, rel=1e-12)
    assert p.strip_positions[-1] == 0.7999999999999998


# -- bad input ------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("name", "shape"),
    [
        ("eta", (4, 5)),
        ("nu", (4, 7)),
        ("actuators", (4, 2)),
        ("command", (4,)),
        ("current", (4, 4)),  # 2 ([V_c, beta_c]) or 3 (plus w_c) wide
        ("current", (4, 1)),
    ],
)
def test_wrong_shapes_raise(name, shape):
    args = {
        "eta": torch.zeros(4, 6),
        "nu": torch.zeros(4, 6),
        "actuators": torch.zeros(4, 3),
        "command": torch.zeros(4, 3),
        "current": torch.zeros(4, 2),
    }
    args[name] = torch.zeros(shape)
    with pytest.raises(ValueError, match=name):
        step(**args, dt=DT)


def test_mismatched_batch_dims_raise():
    with pytest.raises(ValueError, match="must broadcast"):
        step(
            torch.zeros(4, 6),
            torch.zeros(3, 6),
            torch.zeros(4, 3),
            torch.zeros(4, 3),
            torch.zeros(4, 2),
            DT,
        )


def test_mismatched_dtypes_raise():
    with pytest.raises(ValueError, match="nu has dtype"):
        step(
            torch.zeros(6),
            torch.zeros(6, dtype=torch.float64),
            torch.zeros(3),
            torch.zeros(3),
            torch.zeros(2),
            DT,
        )


@pytest.mark.parametrize("dt", [-0.05, 0.0, torch.tensor([-0.1])])
def test_non_positive_dt_raises(dt):
    with pytest.raises(ValueError, match="dt"):
        step(torch.zeros(6), torch.zeros(6), torch.zeros(3), torch.zeros(3), torch.zeros(2), dt)


def test_bad_params_raise():
    with pytest.raises(ValueError, match="t_fin"):
        Remus100Params(t_fin=0.0)


# -- replay CLI -----------------------------------------------------------------------------
def _replay(in_path: Path, out_path: Path) -> None:
    subprocess.run(
        [
            sys.executable,
            "-m",
            "torchrl_auv.cli.remus100",
            "replay",
            str(in_path),
            str(out_path),
        ],
        check=True,
        capture_output=True,
    )


def test_replay_cli_reproduces_reference_without_reading_states(tmp_path):
    source = REFERENCE_FILES[-1]
    with open(source, newline="") as handle:
        reader = csv.DictReader(handle)
        header, rows = reader.fieldnames, list(reader)
    state_columns = (*ETA_COLUMNS, *NU_COLUMNS, *ACTUATOR_COLUMNS)
    blinded = tmp_path / "blinded.csv"
    with open(blinded, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=header, lineterminator="\n")
        writer.writeheader()
        for k, row in enumerate(rows):
            writer.writerow({**row, **({c: "nan" for c in state_columns} if k else {})})
    out = tmp_path / "out.csv"
    _replay(blinded, out)
    simulated, reference = _load(out), _load(source)
    for key in ("eta", "nu", "act"):
        torch.testing.assert_close(simulated[key], reference[key], atol=1e-9, rtol=0)
    with open(out) as handle:
        assert handle.readline().strip().split(",") == header
