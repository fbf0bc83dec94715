"""Energy helpers: the EC model in closed form, shaft power from the propeller model."""

from __future__ import annotations

import math

import pytest
import torch

from torchrl_auv.physics.energy import (
    EC_MAX_SPEED,
    HOVER_POWER,
    decision_power,
    episode_energy_consumption,
    moving_power,
    shaft_power,
)
from torchrl_auv.physics.remus100 import propeller_forces

F64 = torch.float64


def _ec_closed_form(v: float) -> float:
    drag = 0.7 * 60 * v**2 / 2
    efficiency = -0.081 * v**3 + 0.215 * v**2 - 0.01 * v + 0.541
    return drag * v / efficiency + 15


@pytest.mark.parametrize("speed", [0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 2.5536])
def test_moving_power_closed_form(speed):
    expected = _ec_closed_form(speed)
    assert moving_power(torch.tensor(speed, dtype=F64)).item() == pytest.approx(expected, rel=1e-12)
    assert moving_power(speed).item() == pytest.approx(expected, rel=1e-6)  # plain floats too


def test_moving_power_values_and_range():
    assert moving_power(torch.tensor(0.0)).item() == 15.0  # hotel load only
    assert moving_power(torch.tensor(2.5536, dtype=F64)).item() == pytest.approx(629.925, abs=1e-3)
    v = torch.linspace(0.0, 3.0, 301, dtype=F64)
    assert (moving_power(v).diff() > 0).all()  # monotone up to 3 m/s
    eta = -0.081 * EC_MAX_SPEED**3 + 0.215 * EC_MAX_SPEED**2 - 0.01 * EC_MAX_SPEED + 0.541
    assert abs(eta) < 1e-9  # the model's upper speed limit is the efficiency's root
    assert moving_power(torch.tensor(EC_MAX_SPEED + 0.1, dtype=F64)).item() < 0


def test_decision_power_and_episode_ec():
    assert HOVER_POWER == 105.0
    speed = torch.tensor([[2.0, 2.0, 1.0, 0.0], [1.5, 1.5, 1.5, 1.5]], dtype=F64)
    hovering = torch.tensor([[False, True, False, True], [True, True, True, True]])
    power = decision_power(speed, hovering)
    expected = [
        [_ec_closed_form(2.0), 105.0, _ec_closed_form(1.0), 105.0],
        [105.0] * 4,
    ]
    torch.testing.assert_close(power, torch.tensor(expected, dtype=F64))
    ec = episode_energy_consumption(speed, hovering)
    assert ec[0].item() == pytest.approx((_ec_closed_form(2.0) + _ec_closed_form(1.0)) / 2)
    assert math.isnan(ec[1].item())  # never moved: no non-hovering decision to average
    ec_all = episode_energy_consumption(speed, hovering, include_hovering=True)
    torch.testing.assert_close(ec_all, power.mean(-1))
    with pytest.raises(ValueError, match="speed and hovering"):
        episode_energy_consumption(speed, hovering[:, :2])


def test_shaft_power_is_two_pi_n_q():
    n = torch.tensor([0.0, 800.0, 1525.0, 2000.0, -1000.0], dtype=F64)
    speed = torch.tensor([0.0, 1.2, 2.5536, 2.5536, 0.5], dtype=F64)
    power = shaft_power(n, speed)
    n_sat = n.clamp(-1525.0, 1525.0)
    _, torque = propeller_forces(n_sat, speed)
    torch.testing.assert_close(power, 2 * math.pi * n_sat / 60 * torque)
    assert power[0].item() == 0.0  # zero at 0 rpm
    assert (power[1:] > 0).all()  # positive forward, and the shaft still takes power in reverse
    assert power[2] == power[3]  # saturated at 1525 rpm, as in the dynamics


def test_shaft_power_at_cruise():
    """Steady REMUS-100 cruise: 1525 rpm at 2.5536 m/s (spec Sec. 9)."""
    power = shaft_power(torch.tensor(1525.0, dtype=F64), torch.tensor(2.5536, dtype=F64))
    # closed form: rho D^5 (K_Q0 + (K_Qmax - K_Q0) J / J_max) n_s^2 * 2 pi n_s, J = 0.944 U/(n_s D)
    n_s, diameter, rho = 1525.0 / 60, 0.14, 1026.0
    j = 0.944 * 2.5536 / (n_s * diameter)
    kq = 0.0700 + (0.0312 - 0.0700) / 0.6632 * j
    assert power.item() == pytest.approx(2 * math.pi * rho * diameter**5 * kq * n_s**3, rel=1e-6)
    assert power.item() == pytest.approx(172.9, abs=0.05)
    # order of magnitude: a REMUS-100 needs ~100-200 W of propulsion at 2.5 m/s; the EC model,
    # which also counts losses and 15 W hotel load, asks 3.6 times that
    assert 100 < power.item() < 250
    assert moving_power(torch.tensor(2.5536, dtype=F64)).item() / power.item() == pytest.approx(
        3.64, abs=0.01
    )
    # at rest the propeller torque is larger (J = 0), so is the power
    assert shaft_power(torch.tensor(1525.0), torch.tensor(0.0)).item() > power.item()
