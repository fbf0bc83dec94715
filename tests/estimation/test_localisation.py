"""Sensors and the localisation filter in closed loop: the KF beats raw USBL fixes."""

from __future__ import annotations

import math

import pytest
import torch

from torchrl_auv.control import make_controller
from torchrl_auv.estimation import Localiser, SensorNoise, compass, depth_sensor, dvl, usbl_fix
from torchrl_auv.physics import ocean
from torchrl_auv.physics.simulation import step_in_ocean


def test_usbl_noise_scales_with_slant_range():
    gen = torch.Generator().manual_seed(0)
    n = 20000
    asv = torch.zeros(n, 3)
    for rng in (50.0, 200.0):
        pos = torch.tensor([rng, 0.0, 0.0]).expand(n, 3)
        fix, cov, valid = usbl_fix(pos, asv, 0.01, math.radians(0.1), gen)
        range_error = fix.norm(dim=-1) - rng
        assert range_error.std().item() == pytest.approx(0.01 * rng, rel=0.05)
        assert valid.all()
        torch.testing.assert_close(cov[0, 0, 0], torch.tensor((0.01 * rng) ** 2))
    _, _, valid = usbl_fix(pos, asv, 0.01, 0.0, gen, dropout=0.3)
    assert valid.float().mean().item() == pytest.approx(0.7, abs=0.02)


def test_onboard_sensor_noise_levels(global_rng_guard):
    gen = torch.Generator().manual_seed(1)
    noise = SensorNoise()
    with global_rng_guard:
        v = dvl(torch.zeros(50000, 6), noise.dvl, gen)
        d = depth_sensor(torch.zeros(50000), noise.depth, gen)
        c = compass(torch.zeros(50000), noise.compass, gen)
    assert v.std().item() == pytest.approx(0.03, rel=0.03)
    assert d.std().item() == pytest.approx(0.05, rel=0.03)
    assert c.std().item() == pytest.approx(math.radians(0.5), rel=0.03)


def test_filtered_position_beats_raw_usbl_over_300_s_in_extreme_sea():
    """Closed loop at 20 Hz, USBL once per second from an ASV at the surface, 'es'."""
    gen = torch.Generator().manual_seed(2)
    sea = ocean.get_sea_state("es")
    batch, dt = 4, 0.05
    ctrl = make_controller("pid")
    noise = SensorNoise()
    loc = Localiser(noise)
    eta = torch.zeros(batch, 6)
    eta[:, 2] = 15.0
    nu = torch.zeros(batch, 6)
    nu[:, 0] = 1.5
    act = torch.tensor([0.0, 0.0, 1200.0]).expand(batch, 3).clone()
    sea_td = ocean.reset_ocean(sea, (batch,), generator=gen)
    memory = ctrl.init_memory((batch,))
    mean, cov = loc.init(eta[:, :3], position_sigma=1.0, velocity=torch.zeros(batch, 3))
    setpoint = torch.tensor([15.0, 0.6, 1200.0]).expand(batch, 3)
    kf_sq, usbl_sq, fixes = 0.0, 0.0, 0
    for k in range(round(300 / dt)):
        command, memory = ctrl(setpoint, eta, nu, memory, dt)
        sea_td = ocean.step_ocean(sea_td, sea, dt, generator=gen)
        eta, nu, act = step_in_ocean(eta, nu, act, command, sea_td, dt)
        mean, cov = loc.predict(mean, cov, dt)
        attitude = torch.stack((eta[:, 3], eta[:, 4], compass(eta[:, 5], noise.compass, gen)), -1)
        mean, cov = loc.update_onboard(
            mean, cov, dvl(nu, noise.dvl, gen), attitude, depth_sensor(eta[:, 2], noise.depth, gen)
        )
        if (k + 1) % 20 == 0:
            asv = torch.cat([eta[:, :2], torch.zeros(batch, 1)], -1)  # ASV keeps station above
            asv = asv + torch.tensor([30.0, 0.0, 0.0])  # ... with an offset
            fix, fix_cov, valid = usbl_fix(
                eta[:, :3], asv, sea.usbl_noise_fraction, sea.usbl_bearing_sigma, gen
            )
            mean, cov = loc.update_usbl(mean, cov, fix, fix_cov, valid)
            kf_sq += (mean[:, :3] - eta[:, :3]).square().sum(-1).mean().item()
            usbl_sq += (fix - eta[:, :3]).square().sum(-1).mean().item()
            fixes += 1
    kf_rms, usbl_rms = math.sqrt(kf_sq / fixes), math.sqrt(usbl_sq / fixes)
    assert torch.isfinite(mean).all()
    assert kf_rms < usbl_rms, (kf_rms, usbl_rms)
    assert torch.equal(cov, cov.transpose(-1, -2))


def test_bad_input():
    gen = torch.Generator()
    with pytest.raises(ValueError, match="dropout"):
        usbl_fix(torch.zeros(3), torch.ones(3), 0.01, 0.0, gen, dropout=1.5)
    with pytest.raises(ValueError, match="asv_position"):
        usbl_fix(torch.zeros(2, 3), torch.ones(3), 0.01, 0.0, gen)
    with pytest.raises(ValueError, match="accel_sigma"):
        Localiser(accel_sigma=0.0)
    with pytest.raises(ValueError, match="dvl"):
        SensorNoise(dvl=-1.0)
