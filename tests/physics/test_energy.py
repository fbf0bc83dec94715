"""Energy helpers: the EC model in closed form, shaft power from the propeller model."""

from __future__ import annotations

import math

import pytest
import torch

from torchrl_auv.physics.energy import HOVER_POWER, moving_power, shaft_power
from torchrl_auv.physics.remus100 import propeller_forces


@pytest.mark.parametrize("speed", [0.5, 1.0, 1.5, 2.0, 2.5])
def test_moving_power_closed_form(speed):
    drag = 0.7 * 60 * speed**2 / 2
    efficiency = -0.081 * speed**3 + 0.215 * speed**2 - 0.01 * speed + 0.541
    expected = drag * speed / efficiency + 15
    assert moving_power(torch.tensor(speed, dtype=torch.float64)).item() == pytest.approx(expected)
    assert HOVER_POWER == 105.0


def test_shaft_power_is_two_pi_n_q():
    n = torch.tensor([0.0, 800.0, 1525.0, 2000.0], dtype=torch.float64)
    speed = torch.tensor([0.0, 1.2, 2.5536, 2.5536], dtype=torch.float64)
    power = shaft_power(n, speed)
    _, torque = propeller_forces(n.clamp(max=1525.0), speed)
    expected = 2 * math.pi * n.clamp(max=1525.0) / 60 * torque
    torch.testing.assert_close(power, expected)
    assert power[0].item() == 0.0 and (power[1:] > 0).all()
    assert power[2] == power[3]  # saturated at 1525 rpm
    assert 100 < power[2].item() < 250  # a ~2.5 m/s REMUS-100 draws order 100 W at the shaft
