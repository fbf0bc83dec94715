"""Environment limits: depth clamping and the divergence guard."""

from __future__ import annotations

import math

import pytest
import torch

from torchrl_auv.physics.limits import depth_limits, diverged
from torchrl_auv.physics.remus100 import rotation_matrix


def test_depth_clamped_and_outward_velocity_removed():
    eta = torch.tensor([[0, 0, -0.5, 0, 0.3, 0.4], [0, 0, 45.0, 0.1, 0.2, 0], [0, 0, 10, 0, 0, 0]])
    nu = torch.tensor([[1.5, 0.1, -0.2, 0, 0, 0], [1.0, 0, 0.3, 0, 0, 0], [1.0, 0, 0.1, 0, 0, 0]])
    seabed = torch.tensor([40.0, 40.0, 40.0])
    eta2, nu2, surf, bed = depth_limits(eta, nu, seabed)
    assert surf.tolist() == [True, False, False] and bed.tolist() == [False, True, False]
    assert eta2[:, 2].tolist() == [0.0, 40.0, 10.0]
    v_ned = (rotation_matrix(eta[:, 3:]) @ nu2[:, :3].unsqueeze(-1)).squeeze(-1)
    assert v_ned[0, 2].abs() < 1e-6 and v_ned[1, 2].abs() < 1e-6  # no motion out of the water
    torch.testing.assert_close(nu2[2], nu[2])  # untouched inside the water column
    speed_h = lambda v: v[:2].norm()  # noqa: E731
    orig_ned = (rotation_matrix(eta[:, 3:]) @ nu[:, :3].unsqueeze(-1)).squeeze(-1)
    torch.testing.assert_close(speed_h(v_ned[0]), speed_h(orig_ned[0]))


def test_inward_velocity_kept_at_surface():
    eta = torch.tensor([0.0, 0.0, -0.1, 0.0, 0.0, 0.0])
    nu = torch.tensor([1.0, 0.0, 0.5, 0.0, 0.0, 0.0])  # moving down: back into the water
    _, nu2, surf, _ = depth_limits(eta, nu, 30.0)
    assert surf.item() and nu2[2].item() == 0.5


def test_diverged_flags():
    eta = torch.zeros(5, 6)
    nu = torch.zeros(5, 6)
    nu[1, 0] = float("inf")
    nu[2, 0] = 7.0
    nu[3, 5] = 4.0
    eta[4, 4] = math.radians(85)
    assert diverged(eta, nu).tolist() == [False, True, True, True, True]
    act = torch.zeros(5, 3)
    act[0, 2] = float("nan")
    assert diverged(eta, nu, act)[0].item()


def test_diverged_flags_roll_beyond_its_limit():
    """Documented: |roll| beyond ``max_abs_roll`` (default 80 deg) is absurd, either side."""
    eta = torch.zeros(6, 6)
    eta[:, 3] = torch.tensor([85.0, -85.0, 79.0, -79.0, 0.0, 120.0]).deg2rad()
    nu = torch.zeros(6, 6)
    assert diverged(eta, nu).tolist() == [True, True, False, False, False, True]
    # a custom limit: 35 deg is beyond 30 deg, 25 deg is not; pitch and rates stay quiet
    eta2 = torch.zeros(2, 6)
    eta2[:, 3] = torch.tensor([35.0, -25.0]).deg2rad()
    got = diverged(eta2, torch.zeros(2, 6), max_abs_roll=math.radians(30))
    assert got.tolist() == [True, False]
    with pytest.raises(ValueError, match="max_abs_roll"):
        diverged(eta2, torch.zeros(2, 6), max_abs_roll=0.0)


def test_bad_arguments():
    with pytest.raises(ValueError, match="seabed_depth"):
        depth_limits(torch.zeros(6), torch.zeros(6), 0.0)
    with pytest.raises(ValueError, match="max_speed"):
        diverged(torch.zeros(6), torch.zeros(6), max_speed=-1.0)
    with pytest.raises(ValueError, match="eta and nu"):
        depth_limits(torch.zeros(5), torch.zeros(6), 10.0)
