"""The vehicle in its ocean: eager and compiled agree, and the current acts on the vehicle."""

from __future__ import annotations

import pytest
import torch

from torchrl_auv.physics import ocean, remus100
from torchrl_auv.physics.simulation import compiled_step_in_ocean, step_in_ocean


def _state(n):
    gen = torch.Generator().manual_seed(0)
    sea = ocean.reset_ocean("ves", (n,), generator=gen)
    eta = torch.zeros(n, 6)
    eta[:, 2] = 5.0
    nu = torch.zeros(n, 6)
    nu[:, 0] = 1.0
    act = torch.zeros(n, 3)
    cmd = torch.tensor([[0.1, -0.05, 1200.0]]).expand(n, 3)
    return eta, nu, act, cmd, sea


def test_step_in_ocean_uses_current_at_the_vehicle():
    eta, nu, act, cmd, sea = _state(3)
    out = step_in_ocean(eta, nu, act, cmd, sea, 0.05)
    ref = remus100.step(eta, nu, act, cmd, ocean.current_at(sea, eta[:, :3]), 0.05)
    for o, r in zip(out, ref, strict=True):
        torch.testing.assert_close(o, r, atol=0, rtol=0)
    still = remus100.step(eta, nu, act, cmd, torch.zeros(3, 2), 0.05)
    assert not torch.allclose(out[1], still[1])  # the ves current changes the accelerations


def test_step_in_ocean_takes_the_local_water_depth():
    eta, nu, act, cmd, _ = _state(3)
    sea = ocean.reset_ocean(
        "ves", (3,), generator=torch.Generator().manual_seed(0), water_depth=45.0
    )
    local = torch.tensor([40.0, 45.0, 58.0])
    out = step_in_ocean(eta, nu, act, cmd, sea, 0.05, water_depth=local)
    current = ocean.current_at(sea, eta[:, :3], water_depth=local)
    assert current.shape == (3, 3) and (current[:, 2] != 0).all()  # vertical orbital velocity
    ref = remus100.step(eta, nu, act, cmd, current, 0.05)
    for o, r in zip(out, ref, strict=True):
        torch.testing.assert_close(o, r, atol=0, rtol=0)
    default = step_in_ocean(eta, nu, act, cmd, sea, 0.05)  # the scene's 45 m
    assert torch.equal(default[1][1], out[1][1]) and not torch.equal(default[1][0], out[1][0])
    compiled = compiled_step_in_ocean(eta, nu, act, cmd, sea, 0.05, water_depth=local)
    for c, o in zip(compiled, out, strict=True):
        torch.testing.assert_close(c, o, atol=1e-4, rtol=1e-5)


def test_compiled_matches_eager():
    eta, nu, act, cmd, sea = _state(4)
    eager = step_in_ocean(eta, nu, act, cmd, sea, 0.05)
    compiled = compiled_step_in_ocean(eta, nu, act, cmd, sea, 0.05)
    for e, c in zip(eager, compiled, strict=True):
        torch.testing.assert_close(c, e, atol=1e-4, rtol=1e-5)


def test_compiled_checks_batch():
    eta, nu, act, cmd, sea = _state(4)
    with pytest.raises(ValueError, match="ocean_state batch"):
        compiled_step_in_ocean(eta[:2], nu[:2], act[:2], cmd[:2], sea, 0.05)
