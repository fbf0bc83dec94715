"""Kalman filter: agreement with filterpy, missing fixes, symmetric positive definiteness."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from filterpy.kalman import KalmanFilter

from torchrl_auv.estimation.kalman import kf_predict, kf_update, kf_update_sequential


def _random_spd(n, gen):
    a = torch.randn(n, n, generator=gen, dtype=torch.float64)
    return a @ a.T + n * torch.eye(n, dtype=torch.float64)


def test_agrees_with_filterpy_over_a_random_sequence_with_missing_fixes():
    gen = torch.Generator().manual_seed(0)
    n, m, steps = 6, 3, 200
    f = torch.eye(n, dtype=torch.float64) + 0.05 * torch.randn(
        n, n, generator=gen, dtype=torch.float64
    )
    q = 0.01 * _random_spd(n, gen)
    h = torch.randn(m, n, generator=gen, dtype=torch.float64)
    b = torch.randn(n, 2, generator=gen, dtype=torch.float64)
    kf = KalmanFilter(dim_x=n, dim_z=m, dim_u=2)
    kf.F, kf.Q, kf.H, kf.B = f.numpy(), q.numpy(), h.numpy(), b.numpy()
    kf.x = np.zeros((n, 1))
    kf.P = np.eye(n) * 4.0
    mean = torch.zeros(n, dtype=torch.float64)
    cov = torch.eye(n, dtype=torch.float64) * 4.0
    worst = 0.0
    for k in range(steps):
        u = torch.randn(2, generator=gen, dtype=torch.float64)
        kf.predict(u=u.numpy().reshape(2, 1))
        mean, cov = kf_predict(mean, cov, f, q, b, u)
        r = _random_spd(m, gen) * 0.1
        z = torch.randn(m, generator=gen, dtype=torch.float64)
        present = k % 3 != 0  # every third fix missing
        if present:
            kf.update(z.numpy().reshape(m, 1), R=r.numpy())
        mean, cov = kf_update(mean, cov, z, h, r, mask=torch.tensor(present))
        worst = max(
            worst, np.abs(kf.x.ravel() - mean.numpy()).max(), np.abs(kf.P - cov.numpy()).max()
        )
    assert worst < 1e-9, worst


def test_batched_update_matches_per_element_and_respects_mask():
    gen = torch.Generator().manual_seed(1)
    batch, n, m = 5, 4, 2
    mean = torch.randn(batch, n, generator=gen, dtype=torch.float64)
    cov = torch.stack([_random_spd(n, gen) for _ in range(batch)])
    h = torch.randn(batch, m, n, generator=gen, dtype=torch.float64)
    r = torch.stack([_random_spd(m, gen) for _ in range(batch)])
    z = torch.randn(batch, m, generator=gen, dtype=torch.float64)
    mask = torch.tensor([True, False, True, True, False])
    new_mean, new_cov = kf_update(mean, cov, z, h, r, mask=mask)
    for i in range(batch):
        single_mean, single_cov = kf_update(mean[i], cov[i], z[i], h[i], r[i])
        if mask[i]:
            torch.testing.assert_close(new_mean[i], single_mean)
            torch.testing.assert_close(new_cov[i], single_cov)
        else:
            assert torch.equal(new_mean[i], mean[i]) and torch.equal(new_cov[i], cov[i])


def test_covariance_stays_spd_and_finite_under_extreme_inputs():
    gen = torch.Generator().manual_seed(2)
    mean = torch.zeros(64, 6)
    cov = torch.eye(6).expand(64, 6, 6) * 1e-6
    f = torch.eye(6)
    h = torch.cat([torch.eye(3), torch.zeros(3, 3)], 1)
    for _ in range(100):
        mean, cov = kf_predict(mean, cov, f, 1e-8 * torch.eye(6))
        z = torch.randn(64, 3, generator=gen) * 1e4
        r = torch.eye(3) * torch.rand(64, 1, 1, generator=gen) * 1e-3 + 1e-9 * torch.eye(3)
        mean, cov = kf_update(mean, cov, z, h, r)
    assert torch.isfinite(mean).all() and torch.isfinite(cov).all()
    torch.testing.assert_close(cov, cov.transpose(-1, -2))
    assert (torch.linalg.eigvalsh(cov.double()) > -1e-9).all()


def test_bad_shapes_raise():
    with pytest.raises(ValueError, match="mean"):
        kf_predict(torch.zeros(3), torch.eye(4), torch.eye(4), torch.eye(4))
    with pytest.raises(ValueError, match="measurement"):
        kf_update(torch.zeros(4), torch.eye(4), torch.zeros(2), torch.zeros(3, 4), torch.eye(3))


def test_sequential_scalar_updates_equal_the_joint_update():
    gen = torch.Generator().manual_seed(4)
    batch, n = 7, 6
    mean = torch.randn(batch, n, generator=gen, dtype=torch.float64)
    cov = torch.stack([_random_spd(n, gen) for _ in range(batch)])
    indices = (3, 4, 5, 2)
    z = torch.randn(batch, 4, generator=gen, dtype=torch.float64)
    variances = torch.rand(batch, 4, generator=gen, dtype=torch.float64) + 0.1
    h = torch.zeros(4, n, dtype=torch.float64)
    for row, col in enumerate(indices):
        h[row, col] = 1.0
    joint = kf_update(mean, cov, z, h, torch.diag_embed(variances))
    sequential = kf_update_sequential(mean, cov, z, indices, variances)
    torch.testing.assert_close(sequential[0], joint[0], atol=1e-10, rtol=0)
    torch.testing.assert_close(sequential[1], joint[1], atol=1e-10, rtol=0)


def test_shared_and_batched_transition_give_the_same_prediction():
    gen = torch.Generator().manual_seed(6)
    mean = torch.randn(5, 6, generator=gen, dtype=torch.float64)
    cov = torch.stack([_random_spd(6, gen) for _ in range(5)])
    f = torch.randn(6, 6, generator=gen, dtype=torch.float64)
    q = _random_spd(6, gen)
    shared = kf_predict(mean, cov, f, q)
    batched = kf_predict(mean, cov, f.expand(5, 6, 6), q)
    torch.testing.assert_close(shared[1], batched[1], atol=1e-10, rtol=0)
