"""USBL fixes: covariance by hand, off-axis spread growing with range, dropout.

Reference: the ``usbl_fix`` docstring and ``docs/spec/data_collection.md`` ("Localisation"):
range noise :math:`\\sigma_\\rho = f\\rho`, bearing noise :math:`\\sigma_b` on azimuth and
elevation, covariance :math:`\\sigma_\\rho^2 \\hat\\ell\\hat\\ell^\\top + (\\rho\\sigma_b)^2
(I - \\hat\\ell\\hat\\ell^\\top)`: a bearing error of :math:`\\sigma_b` rad at range
:math:`\\rho` moves the fix sideways by :math:`\\rho\\sigma_b` (small-angle arc length), so the
lateral standard deviation grows linearly with range.
"""

from __future__ import annotations

import math

import pytest
import torch

from torchrl_auv.estimation import Localiser, usbl_fix

F64 = torch.float64


def test_covariance_by_hand_at_a_known_relative_position():
    # line of sight (30, 40, 120) m: range 130 m, unit vector (3, 4, 12) / 13
    # f = 1 %: sigma_rho = 1.3 m, variance 1.69; sigma_b = 2 mrad: lateral sigma 0.26 m, var 0.0676
    # cov = 0.0676 I + (1.69 - 0.0676) / 169 * [3 4 12]^T [3 4 12] = 0.0676 I + 0.0096 * (...)
    asv = torch.tensor([5.0, -7.0, 0.0], dtype=F64)
    position = asv + torch.tensor([30.0, 40.0, 120.0], dtype=F64)
    _, cov, valid = usbl_fix(position, asv, 0.01, 0.002, torch.Generator().manual_seed(0))
    expected = torch.tensor(
        [
            [0.0676 + 0.0864, 0.1152, 0.3456],
            [0.1152, 0.0676 + 0.1536, 0.4608],
            [0.3456, 0.4608, 0.0676 + 1.3824],
        ],
        dtype=F64,
    )
    torch.testing.assert_close(cov, expected, rtol=1e-12, atol=1e-12)
    assert valid.item()

    # four times farther along the same line: every standard deviation grows fourfold, so the
    # eigenvalues are (0.26 * 4)^2 twice (lateral) and (1.3 * 4)^2 (along the line)
    far = asv + 4 * torch.tensor([30.0, 40.0, 120.0], dtype=F64)
    _, cov_far, _ = usbl_fix(far, asv, 0.01, 0.002, torch.Generator().manual_seed(0))
    eig = torch.linalg.eigvalsh(cov_far)
    torch.testing.assert_close(
        eig, torch.tensor([1.04**2, 1.04**2, 5.2**2], dtype=F64), rtol=1e-10, atol=1e-12
    )


def test_lateral_spread_grows_with_range_and_matches_the_covariance():
    """Many draws at a horizontal line of sight (elevation 0, where an azimuth error of
    sigma_b moves the fix by exactly rho sigma_b to first order): the spread along the line is
    f rho, across it rho sigma_b horizontally and vertically; the bearing spread stays sigma_b."""
    n, fraction, sigma_b = 20000, 0.002, 0.01
    bearing = math.radians(30.0)
    along = torch.tensor([math.cos(bearing), math.sin(bearing), 0.0], dtype=F64)
    across = torch.tensor([-math.sin(bearing), math.cos(bearing), 0.0], dtype=F64)
    down = torch.tensor([0.0, 0.0, 1.0], dtype=F64)
    asv = torch.tensor([10.0, 20.0, 0.0], dtype=F64).expand(n, 3)
    gen = torch.Generator().manual_seed(4)
    lateral_std = {}
    for rng in (50.0, 200.0):
        position = asv + rng * along
        fix, cov, _ = usbl_fix(position, asv, fraction, sigma_b, gen)
        error = fix - position
        expected = ((along, fraction * rng), (across, rng * sigma_b), (down, rng * sigma_b))
        for axis, sigma in expected:
            assert (error @ axis).std().item() == pytest.approx(sigma, rel=0.03)
            assert (axis @ cov[0] @ axis).sqrt().item() == pytest.approx(sigma, rel=1e-9)
        lateral_std[rng] = (error @ across).std().item()
        rel = fix - asv
        azimuth_error = torch.atan2(rel[:, 1], rel[:, 0]) - bearing
        assert azimuth_error.std().item() == pytest.approx(sigma_b, rel=0.03)
        elevation_error = torch.asin(rel[:, 2] / rel.norm(dim=-1))
        assert elevation_error.std().item() == pytest.approx(sigma_b, rel=0.03)
    assert lateral_std[200.0] / lateral_std[50.0] == pytest.approx(4.0, rel=0.05)


def test_dropout_flags_lost_fixes_and_the_filter_ignores_them():
    """Documented: ``dropout`` is the probability that a fix is lost and ``valid`` [*B] bool
    says which fixes arrived. The covariance formula does not depend on dropout, so a lost fix
    still carries the documented (finite, positive-definite) covariance, and the Localiser's
    masked update leaves the estimate of a vehicle whose fix was lost exactly unchanged."""
    n = 4000
    asv = torch.zeros(n, 3, dtype=F64)
    position = torch.tensor([30.0, 40.0, 120.0], dtype=F64).expand(n, 3)
    fix, cov, valid = usbl_fix(
        position, asv, 0.01, 0.002, torch.Generator().manual_seed(5), dropout=0.25
    )
    assert valid.dtype == torch.bool and valid.shape == (n,)
    # binomial: mean 0.75, standard deviation sqrt(0.75 * 0.25 / 4000) = 0.0068
    assert valid.float().mean().item() == pytest.approx(0.75, abs=0.03)
    lost = ~valid
    assert torch.isfinite(fix[lost]).all()
    _, cov_expected, _ = usbl_fix(position[:1], asv[:1], 0.01, 0.002, torch.Generator())
    torch.testing.assert_close(cov[lost], cov_expected.expand(int(lost.sum()), 3, 3))
    assert (torch.linalg.eigvalsh(cov[lost]) > 0).all()

    gen = torch.Generator().manual_seed(6)
    assert not usbl_fix(position, asv, 0.01, 0.002, gen, dropout=1.0)[2].any()
    assert usbl_fix(position, asv, 0.01, 0.002, gen, dropout=0.0)[2].all()

    loc = Localiser()
    mean, kf_cov = loc.init(position + 5.0, position_sigma=10.0, velocity=torch.zeros(n, 3))
    new_mean, new_cov = loc.update_usbl(mean, kf_cov, fix, cov, valid)
    assert torch.equal(new_mean[lost], mean[lost]) and torch.equal(new_cov[lost], kf_cov[lost])
    # an arrived fix (sigma ~ 1.3 m) pulls a 10 m-sigma estimate most of the way to it
    moved = (new_mean[valid, :3] - fix[valid]).norm(dim=-1)
    assert (moved < 0.2 * (mean[valid, :3] - fix[valid]).norm(dim=-1)).all()
