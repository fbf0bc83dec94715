"""The Euler-matrix table against the rotations composed by hand and the rate map's definition."""

import math

import torch

from torchrl_auv.physics.euler import euler_matrices, trig_factors
from torchrl_auv.physics.remus100 import kinematics, rotation_matrix

F64 = torch.float64


def _rz_ry_rx(phi: float, theta: float, psi: float) -> torch.Tensor:
    c, s = math.cos, math.sin
    rz = torch.tensor([[c(psi), -s(psi), 0], [s(psi), c(psi), 0], [0, 0, 1]], dtype=F64)
    ry = torch.tensor([[c(theta), 0, s(theta)], [0, 1, 0], [-s(theta), 0, c(theta)]], dtype=F64)
    rx = torch.tensor([[1, 0, 0], [0, c(phi), -s(phi)], [0, s(phi), c(phi)]], dtype=F64)
    return rz @ ry @ rx


def test_rotation_is_rz_ry_rx_and_rate_map_inverts_the_euler_rates():
    gen = torch.Generator().manual_seed(0)
    angles = (torch.rand(32, 3, generator=gen, dtype=F64) - 0.5) * torch.tensor(
        [2.0, 2.8, 6.0], dtype=F64
    )  # pitch within +-80 deg
    matrices = euler_matrices(trig_factors(angles.cos(), angles.sin()))
    for k in range(angles.shape[0]):
        phi, theta, psi = angles[k].tolist()
        torch.testing.assert_close(matrices[k, 0], _rz_ry_rx(phi, theta, psi), rtol=0, atol=1e-14)
        # T maps body rates to Euler rates: its inverse takes Euler rates to body rates
        inverse = torch.tensor(
            [
                [1, 0, -math.sin(theta)],
                [0, math.cos(phi), math.cos(theta) * math.sin(phi)],
                [0, -math.sin(phi), math.cos(theta) * math.cos(phi)],
            ],
            dtype=F64,
        )
        torch.testing.assert_close(
            matrices[k, 1] @ inverse, torch.eye(3, dtype=F64), rtol=0, atol=1e-12
        )
    torch.testing.assert_close(rotation_matrix(angles), matrices[:, 0], rtol=0, atol=0)


def test_kinematics_applies_r_to_velocity_and_t_to_rates():
    gen = torch.Generator().manual_seed(1)
    eta = torch.randn(5, 6, generator=gen, dtype=F64) * 0.4
    nu = torch.randn(5, 6, generator=gen, dtype=F64)
    matrices = euler_matrices(trig_factors(eta[:, 3:].cos(), eta[:, 3:].sin()))
    expected = torch.cat(
        ((matrices[:, 0] @ nu[:, :3, None])[..., 0], (matrices[:, 1] @ nu[:, 3:, None])[..., 0]),
        -1,
    )
    torch.testing.assert_close(kinematics(eta, nu), expected, rtol=0, atol=1e-14)
    # broadcast batch dims, as step's inputs do
    assert kinematics(eta[:1], nu).shape == (5, 6)
