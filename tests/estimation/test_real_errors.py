"""The localisation errors a real system has (``docs/spec/data_collection.md``, "Localisation"
v2): the ASV's GNSS error, the wave-driven bearing error, USBL dropouts, DVL bottom lock, the
altimeter; and the filter's position error they give, per sea state.

Expected values come from closed forms (the Gauss-Markov process's stationary variance
:math:`\\sigma^2` and lag-:math:`h` autocorrelation :math:`e^{-h/T}`; binomial frequencies),
from filterpy's ``KalmanFilter`` for the gated DVL update, and from statistics of many draws.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import torch
from filterpy.kalman import KalmanFilter

from torchrl_auv.control import make_controller
from torchrl_auv.envs.vehicles import VehicleStack
from torchrl_auv.estimation import (
    Localiser,
    SensorNoise,
    altimeter,
    dvl_bottom_lock,
    gnss_error_init,
    gnss_error_step,
    total_bearing_sigma,
    usbl_fix,
    usbl_fix_from_asv,
)
from torchrl_auv.physics import ocean
from torchrl_auv.physics.ocean import SEA_STATES, SeaState

F64 = torch.float64


# -- the presets' values ---------------------------------------------------------------------
def test_presets_carry_the_documented_localisation_errors():
    ideal, es, ves = SEA_STATES["ideal"], SEA_STATES["es"], SEA_STATES["ves"]
    assert (ideal.usbl_dropout, es.usbl_dropout, ves.usbl_dropout) == (0.0, 0.05, 0.20)
    assert ideal.usbl_attitude_sigma == 0.0
    assert es.usbl_attitude_sigma == pytest.approx(math.radians(0.5))
    assert ves.usbl_attitude_sigma == pytest.approx(math.radians(0.75))
    assert [s.gnss_sigma for s in (ideal, es, ves)] == [1.0, 1.5, 2.0]  # the spec's 1-2 m
    assert {s.gnss_time_constant for s in (ideal, es, ves)} == {60.0}
    # the bearing noise grows with Hs: instrument 0.1 deg and the attitude residual in quadrature
    sigmas = [math.degrees(total_bearing_sigma(s)) for s in (ideal, es, ves)]
    assert sigmas == pytest.approx([0.1, math.hypot(0.1, 0.5), math.hypot(0.1, 0.75)])
    assert sigmas[0] < sigmas[1] < sigmas[2]
    # a hand-built sea state has none of these errors
    custom = SeaState()
    assert (custom.usbl_dropout, custom.usbl_attitude_sigma, custom.gnss_sigma) == (0, 0, 0)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("usbl_dropout", 1.5),
        ("usbl_dropout", -0.1),
        ("usbl_dropout", math.nan),
        ("usbl_attitude_sigma", -0.01),
        ("usbl_attitude_sigma", math.inf),
        ("gnss_sigma", -1.0),
        ("gnss_sigma", math.nan),
        ("gnss_time_constant", 0.0),
    ],
)
def test_sea_state_validation_names_the_new_fields(field, value):
    with pytest.raises(ValueError, match=f"SeaState.{field}"):
        SeaState(**{field: value})


def test_bad_sensor_input():
    with pytest.raises(ValueError, match="dvl_range"):
        SensorNoise(dvl_range=0.0)
    with pytest.raises(ValueError, match="altimeter"):
        SensorNoise(altimeter=-0.1)
    gen = torch.Generator()
    with pytest.raises(ValueError, match="time_constant"):
        gnss_error_step(torch.zeros(2), 1.0, 0.0, 1.0, gen)
    with pytest.raises(ValueError, match="sigma"):
        gnss_error_init((2,), -1.0, gen)


# -- the ASV's GNSS error --------------------------------------------------------------------
def test_gnss_error_is_stationary_with_the_gauss_markov_autocorrelation():
    """40 000 independent processes (20 000 x north/east), sigma 1.5 m, T = 60 s, stepped by
    5 s: the variance stays sigma^2 from the first draw on, the lag-1 autocorrelation is
    e^(-5/60) = 0.920 and the lag-12 (60 s) one e^(-1) = 0.368."""
    gen = torch.Generator().manual_seed(0)
    sigma, tau, dt = 1.5, 60.0, 5.0
    errors = [gnss_error_init((20000, 2), sigma, gen, dtype=F64)]
    for _ in range(12):
        errors.append(gnss_error_step(errors[-1], sigma, tau, dt, gen))
    path = torch.stack(errors).reshape(13, -1)  # [time, process]
    # standard error of a variance estimate: sigma^2 sqrt(2/n) = 0.016 (0.7 %)
    for k in (0, 1, 12):
        assert path[k].var().item() == pytest.approx(sigma**2, rel=0.03)
        assert path[k].mean().item() == pytest.approx(0.0, abs=0.03)

    def corr(a, b):
        return torch.corrcoef(torch.stack((a, b)))[0, 1].item()

    # standard error of a correlation estimate: (1 - rho^2)/sqrt(n) < 0.005
    assert corr(path[0], path[1]) == pytest.approx(math.exp(-dt / tau), abs=0.01)
    assert corr(path[5], path[6]) == pytest.approx(math.exp(-dt / tau), abs=0.01)
    assert corr(path[0], path[12]) == pytest.approx(math.exp(-1.0), abs=0.02)
    # frozen (T = inf) and switched off (sigma = 0)
    e = torch.randn(4, 2, generator=gen)
    assert torch.equal(gnss_error_step(e, 1.0, math.inf, 1.0, gen), e)
    assert not gnss_error_init((4, 2), 0.0, gen).any()
    assert not gnss_error_step(torch.zeros(4, 2), 0.0, 60.0, 1.0, gen).any()


def test_a_fix_is_biased_by_exactly_the_asvs_gnss_error():
    """No acoustic noise (range fraction 0, bearing 0, no range floor): the fix is the true
    position plus the ASV's GNSS error (north, east; the vertical is untouched), and the
    covariance gains sigma_gnss^2 on its north and east variances only."""
    gen = torch.Generator().manual_seed(1)
    n = 6
    position = torch.randn(n, 3, generator=gen, dtype=F64) * 50 + torch.tensor([0, 0, 60.0])
    asv = torch.cat([torch.randn(n, 2, generator=gen, dtype=F64) * 30, torch.zeros(n, 1)], -1)
    error = torch.randn(n, 2, generator=gen, dtype=F64) * 1.3
    fix, cov, valid = usbl_fix(
        position, asv, 0.0, 0.0, gen, min_range_sigma=0.0, asv_error=error, asv_error_sigma=1.3
    )
    want = torch.cat([error, torch.zeros(n, 1, dtype=F64)], -1)
    torch.testing.assert_close(fix - position, want, rtol=0, atol=1e-9)
    assert valid.all()
    _, cov_plain, _ = usbl_fix(position, asv, 0.0, 0.0, gen, min_range_sigma=0.0)
    added = torch.diag(torch.tensor([1.69, 1.69, 0.0], dtype=F64)).expand(n, 3, 3)
    torch.testing.assert_close(cov - cov_plain, added, rtol=0, atol=1e-12)
    # a 3-D error shifts all three coordinates
    error3 = torch.tensor([0.5, -0.7, 0.2], dtype=F64).expand(n, 3)
    fix3, _, _ = usbl_fix(position, asv, 0.0, 0.0, gen, min_range_sigma=0.0, asv_error=error3)
    torch.testing.assert_close(fix3 - position, error3, rtol=0, atol=1e-9)
    # the sea-state entry point: the same bias with the sea state's (here zero) acoustic noise
    # but for usbl_fix's 1 cm range-noise floor (5 sigma: 0.05 m)
    quiet = SeaState(usbl_noise_fraction=0.0, usbl_bearing_sigma=0.0, gnss_sigma=1.3)
    fix_sea, cov_sea, _ = usbl_fix_from_asv(position, asv, error, quiet, gen)
    torch.testing.assert_close(fix_sea, fix, rtol=0, atol=0.05)
    assert cov_sea[:, 0, 0].min().item() >= 1.69


def test_dropout_frequency_per_preset_and_the_same_draws_for_every_dropout():
    """usbl_fix_from_asv loses the preset's fraction of fixes: 0, 5 %, 20 % (binomial standard
    error at n = 40 000 below 0.002; tolerance 0.01). The fix itself and the generator's state
    afterwards do not depend on the dropout (common random numbers across sea states)."""
    n = 40000
    position = torch.tensor([40.0, 10.0, 30.0]).expand(n, 3)
    asv = torch.zeros(n, 3)
    gnss = torch.zeros(n, 2)
    fixes, states = [], []
    for name, lost in (("ideal", 0.0), ("es", 0.05), ("ves", 0.20)):
        gen = torch.Generator().manual_seed(2)
        sea = dataclasses.replace(
            SEA_STATES[name], usbl_noise_fraction=0.001, usbl_attitude_sigma=0.0
        )
        fix, _, valid = usbl_fix_from_asv(position, asv, gnss, sea, gen)
        assert (1 - valid.float().mean().item()) == pytest.approx(lost, abs=0.01), name
        fixes.append(fix)
        states.append(gen.get_state())
    assert torch.equal(fixes[0], fixes[1]) and torch.equal(fixes[0], fixes[2])
    assert torch.equal(states[0], states[1]) and torch.equal(states[0], states[2])


def test_bearing_noise_of_the_sea_state_shows_in_the_fixes():
    """Many fixes at a horizontal line of sight in ``ves``: the azimuth spread is the total
    bearing sigma hypot(0.1, 0.75) deg = 0.757 deg, not the instrument's 0.1 deg."""
    n = 20000
    gen = torch.Generator().manual_seed(3)
    position = torch.tensor([100.0, 0.0, 0.0], dtype=F64).expand(n, 3)
    asv = torch.zeros(n, 3, dtype=F64)
    fix, cov, _ = usbl_fix_from_asv(
        position, asv, torch.zeros(n, 2, dtype=F64), SEA_STATES["ves"], gen
    )
    azimuth = torch.atan2(fix[:, 1], fix[:, 0])
    want = math.radians(math.hypot(0.1, 0.75))
    assert azimuth.std().item() == pytest.approx(want, rel=0.03)
    # the filter is told: the east variance is (100 m * sigma_b)^2 + the GNSS (2 m)^2
    assert cov[0, 1, 1].item() == pytest.approx((100 * want) ** 2 + 2.0**2, rel=1e-9)


# -- DVL bottom lock --------------------------------------------------------------------------
def _filterpy_update(mean, cov, z, h, r):
    kf = KalmanFilter(dim_x=6, dim_z=len(z))
    kf.x, kf.P = mean.numpy().reshape(6, 1).copy(), cov.numpy().copy()
    kf.H = h
    kf.update(np.asarray(z).reshape(-1, 1), R=r)
    return kf.x.ravel(), kf.P


def test_the_dvl_update_is_skipped_exactly_without_bottom_lock():
    """Altitudes around the 30 m range: with lock the filter takes the DVL velocity (rotated to
    NED) and the depth, as filterpy's update with H = [v_N v_E v_D z] rows and the documented
    diagonal R; without it, the depth alone (filterpy with H = the z row): the DVL reading
    leaves estimate and covariance untouched there."""
    gen = torch.Generator().manual_seed(4)
    altitude = torch.tensor([5.0, 29.99, 30.0, 30.01, 80.0, math.nan], dtype=F64)
    locked = dvl_bottom_lock(altitude)
    assert locked.tolist() == [True, True, True, False, False, False]
    n = len(altitude)
    a = torch.randn(n, 6, 6, generator=gen, dtype=F64)
    cov = a @ a.transpose(-1, -2) + 0.5 * torch.eye(6, dtype=F64)
    mean = torch.randn(n, 6, generator=gen, dtype=F64)
    velocity = torch.randn(n, 3, generator=gen, dtype=F64) + torch.tensor([1.5, 0, 0])
    attitude = torch.randn(n, 3, generator=gen, dtype=F64) * torch.tensor([0.1, 0.1, 2.0])
    depth = torch.rand(n, generator=gen, dtype=F64) * 20
    noise = SensorNoise()
    loc = Localiser(noise)
    got_mean, got_cov = loc.update_onboard(mean, cov, velocity, attitude, depth, dvl_valid=locked)
    for i in range(n):
        c, s = torch.cos(attitude[i]), torch.sin(attitude[i])  # roll, pitch, yaw by hand
        rz = torch.tensor([[c[2], -s[2], 0], [s[2], c[2], 0], [0, 0, 1]], dtype=F64)
        ry = torch.tensor([[c[1], 0, s[1]], [0, 1, 0], [-s[1], 0, c[1]]], dtype=F64)
        rx = torch.tensor([[1, 0, 0], [0, c[0], -s[0]], [0, s[0], c[0]]], dtype=F64)
        v_ned = (rz @ ry @ rx @ velocity[i]).numpy()
        if locked[i]:
            var_v = noise.dvl**2 + (noise.compass * np.hypot(v_ned[0], v_ned[1])) ** 2
            h = np.zeros((4, 6))
            h[0, 3] = h[1, 4] = h[2, 5] = h[3, 2] = 1.0
            r = np.diag([var_v, var_v, noise.dvl**2, noise.depth**2])
            z = [*v_ned, depth[i].item()]
        else:
            h = np.zeros((1, 6))
            h[0, 2] = 1.0
            r = np.array([[noise.depth**2]])
            z = [depth[i].item()]
        want_mean, want_cov = _filterpy_update(mean[i], cov[i], z, h, r)
        np.testing.assert_allclose(got_mean[i].numpy(), want_mean, rtol=0, atol=1e-9)
        np.testing.assert_allclose(got_cov[i].numpy(), want_cov, rtol=0, atol=1e-9)
    # unlocked: the DVL reading does not matter at all; locked: it does
    other = velocity + 5.0
    alt_mean, alt_cov = loc.update_onboard(mean, cov, other, attitude, depth, dvl_valid=locked)
    assert torch.equal(alt_mean[~locked], got_mean[~locked])
    assert torch.equal(alt_cov[~locked], got_cov[~locked])
    assert not torch.isclose(alt_mean[locked], got_mean[locked]).all(-1).any()
    # an all-True mask is the ungated update, bit for bit
    full = loc.update_onboard(mean, cov, velocity, attitude, depth)
    gated = loc.update_onboard(
        mean, cov, velocity, attitude, depth, dvl_valid=torch.ones(n, dtype=torch.bool)
    )
    assert torch.equal(full[0], gated[0]) and torch.equal(full[1], gated[1])


# -- altimeter ---------------------------------------------------------------------------------
def test_altimeter_noise_and_range():
    gen = torch.Generator().manual_seed(5)
    n = 50000
    reading, valid = altimeter(torch.full((n,), 12.0, dtype=F64), 0.1, gen)
    assert valid.all()
    assert reading.mean().item() == pytest.approx(12.0, abs=0.003)  # standard error 0.0004
    assert reading.std().item() == pytest.approx(0.1, rel=0.03)
    edge = torch.tensor([29.0, 30.0, 30.5, 200.0, math.nan], dtype=F64)
    reading, valid = altimeter(edge, 0.0, gen)
    assert valid.tolist() == [True, True, False, False, False]
    assert reading.tolist() == [29.0, 30.0, 30.0, 30.0, 30.0]  # no echo: its range, flagged
    reading, valid = altimeter(edge, 0.0, gen, max_range=50.0)
    assert valid.tolist() == [True, True, True, False, False]
    z = torch.tensor([1.0, -2.0], dtype=F64)
    reading, _ = altimeter(torch.tensor([5.0, 6.0], dtype=F64), 0.1, None, standard_normal=z)
    torch.testing.assert_close(reading, torch.tensor([5.1, 5.8], dtype=F64))


# -- end to end: the filter's position error per sea state -------------------------------------
def _closed_loop(preset: str, seabed: float, decisions: int, n: int = 8, seed: int = 0):
    """``n`` REMUS-100s at 15 m depth on PID heading/depth setpoints (VehicleStack, 20 Hz,
    DVL gated by altitude), one USBL fix per decision (1 s) from an ASV at the surface 30 m
    north of each AUV (the AUVTrackingEnv geometry) with the preset's errors and the ASV's
    GNSS error stepped per fix. Returns the KF's position errors ``[decisions, n]`` (m, after
    the fix) and the raw fixes' errors (NaN for lost fixes)."""
    sea = ocean.get_sea_state(preset)
    gen = torch.Generator().manual_seed(seed)
    stack = VehicleStack(sea, make_controller("pid"))
    eta = torch.zeros(n, 6)
    eta[:, 2] = 15.0
    eta[:, 5] = torch.linspace(-3.0, 3.0, n)
    nu = torch.zeros(n, 6)
    nu[:, 0] = 1.5
    act = torch.zeros(n, 3)
    act[:, 2] = 1200.0
    vehicles = stack.init(eta, nu, act)
    sea_td = ocean.reset_ocean(sea, (n,), generator=gen)
    gnss = gnss_error_init((n, 2), sea.gnss_sigma, gen)
    kf_errors, usbl_errors = [], []
    for k in range(decisions):
        heading = torch.linspace(-3.0, 3.0, n) + 0.5 * math.sin(k / 40)
        setpoint = torch.stack((torch.full((n,), 15.0), heading, torch.full((n,), 1200.0)), -1)
        vehicles, sea_td, _ = stack.decide(vehicles, setpoint, sea_td, seabed, generator=gen)
        truth = vehicles["truth", "eta"][:, :3]
        asv = torch.stack((truth[:, 0] + 30.0, truth[:, 1], torch.zeros(n)), -1)
        gnss = gnss_error_step(gnss, sea.gnss_sigma, sea.gnss_time_constant, 1.0, gen)
        fix, fix_cov, valid = usbl_fix_from_asv(truth, asv, gnss, sea, gen)
        mean, cov = stack.localiser.update_usbl(
            vehicles["kf", "mean"], vehicles["kf", "cov"], fix, fix_cov, valid
        )
        vehicles["kf", "mean"], vehicles["kf", "cov"] = mean, cov
        kf_errors.append((mean[:, :3] - truth).norm(dim=-1))
        usbl_errors.append(torch.where(valid, (fix - truth).norm(dim=-1), math.nan))
    return torch.stack(kf_errors), torch.stack(usbl_errors)


def _summary(errors: torch.Tensor) -> tuple[float, float]:
    errors = errors[~errors.isnan()]
    return errors.mean().item(), errors.quantile(0.95).item()


def test_filter_error_is_metres_in_ves_and_grows_with_the_sea_state_without_bottom_lock():
    """150 decisions (150 s), 8 AUVs, seabed 200 m (no bottom lock, as in AUVTrackingEnv).
    Measured (seeds 0-3): KF mean 1.27-1.44 m in ideal, 1.28-1.50 in es, 1.39-1.62 in ves;
    95th percentile 2.2-3.0, 2.4-3.0, 2.6-3.3 m; ideal < es < ves for every seed. The ASV's
    GNSS error (1 m per axis in every preset) dominates; the same seed gives the same GNSS
    error path in every preset (common random numbers), so the growth is the sea state's."""
    kf = {p: _summary(_closed_loop(p, 200.0, 150)[0]) for p in ("ideal", "es", "ves")}
    assert kf["ideal"][0] < kf["es"][0] < kf["ves"][0], kf
    assert kf["ves"][0] > 0.5, kf  # metres, not the centimetres of a GNSS-free ASV
    assert kf["ves"][1] > 1.5 and kf["ves"][1] < 6.0, kf  # 95th percentile


def test_with_bottom_lock_the_filter_beats_the_raw_fixes_in_every_sea_state():
    """100 decisions, seabed 30 m (altitude 15 m: DVL bottom lock): dead reckoning on the DVL
    lets the filter average the fixes' noise, part of the GNSS error included. Measured
    (seed 0): KF mean ideal 1.31 m vs raw USBL 1.45 m, es 1.33 vs 1.52, ves 1.32 vs 1.61."""
    for preset in ("ideal", "es", "ves"):
        kf, usbl = (_summary(e)[0] for e in _closed_loop(preset, 30.0, 100))
        assert kf < usbl, (preset, kf, usbl)
        assert kf > 0.5, (preset, kf)  # the GNSS error is there in every preset
