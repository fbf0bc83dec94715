"""Ocean: current statistics, wave energy and spectrum, depth decay, determinism and bad input."""

from __future__ import annotations

import dataclasses
import math

import pytest
import torch

from torchrl_auv.physics import remus100
from torchrl_auv.physics.ocean import (
    GRAVITY,
    SEA_STATES,
    SeaState,
    current_at,
    get_sea_state,
    jonswap_spectrum,
    reset_ocean,
    step_ocean,
    surface_elevation_at,
    water_velocity_at,
)

F64 = torch.float64


def _gen(seed: int = 0) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


def _fine_grid(sea: SeaState, low: float = 0.05, high: float = 30.0) -> torch.Tensor:
    wp = 2 * math.pi / sea.wave_tp
    return torch.linspace(low * wp, high * wp, 400001, dtype=F64)


# --------------------------------------------------------------------------- presets


def test_presets_match_the_spec_table():
    ideal, es, ves = SEA_STATES["ideal"], SEA_STATES["es"], SEA_STATES["ves"]
    assert (ideal.current_mean, ideal.current_sigma, ideal.wave_hs) == (0.0, 0.0, 0.0)
    assert ideal.usbl_noise_fraction == 0.001
    assert (es.current_mean, es.current_sigma, es.current_time_constant) == (0.5, 0.1, 60.0)
    assert (es.wave_hs, es.wave_tp, es.wave_gamma, es.usbl_noise_fraction) == (4, 10, 3.3, 0.005)
    assert (ves.current_mean, ves.current_sigma, ves.current_time_constant) == (1.0, 0.2, 60.0)
    assert (ves.wave_hs, ves.wave_tp, ves.wave_gamma, ves.usbl_noise_fraction) == (6, 12, 3.3, 0.01)
    for sea in SEA_STATES.values():
        assert sea.usbl_bearing_sigma == pytest.approx(math.radians(0.1))
        assert get_sea_state(sea.name) is sea
        assert get_sea_state(sea) is sea


# --------------------------------------------------------------------------- current


@pytest.mark.parametrize("name", ["es", "ves"])
def test_stationary_draw_has_the_preset_mean_and_std(name):
    sea = SEA_STATES[name]
    n = 4096
    state = reset_ocean(sea, (n,), generator=_gen(), dtype=F64)
    speed = state["current_speed"]
    # standard errors of the sample mean and of the sample standard deviation
    se_mean, se_std = sea.current_sigma / math.sqrt(n), sea.current_sigma / math.sqrt(2 * n)
    assert abs(speed.mean().item() - sea.current_mean) < 4 * se_mean
    assert abs(speed.std().item() - sea.current_sigma) < 4 * se_std
    offset = state["current_direction"] - state["current_direction_mean"]
    assert abs(offset.mean().item()) < 4 * sea.current_direction_sigma / math.sqrt(n)
    assert abs(offset.std().item() - sea.current_direction_sigma) < (
        4 * sea.current_direction_sigma / math.sqrt(2 * n)
    )
    # the mean direction is uniform on [-pi, pi): mean ~ 0, variance ~ pi^2 / 3
    mean_dir = state["current_direction_mean"]
    assert mean_dir.min() >= -math.pi and mean_dir.max() < math.pi
    assert abs(mean_dir.var().item() - math.pi**2 / 3) < 0.1 * math.pi**2 / 3


@pytest.mark.parametrize("name", ["es", "ves"])
def test_long_chains_time_average_and_autocorrelation(name):
    """256 chains x 2000 steps of 5 s (167 time constants each): time statistics of the chain."""
    sea = SEA_STATES[name]
    h, steps = 5.0, 2000
    state = reset_ocean(sea, (256,), generator=_gen(), dtype=F64)
    gen = _gen(1)
    speeds = []
    for _ in range(steps):
        state = step_ocean(state, sea, h, generator=gen)
        speeds.append(state["current_speed"])
    x = torch.stack(speeds, -1)  # [chains, time]
    assert state["time"][0].item() == pytest.approx(h * steps)
    # effective number of independent samples ~ chains * duration / (2 T)
    n_eff = 256 * steps * h / (2 * sea.current_time_constant)
    assert abs(x.mean().item() - sea.current_mean) < 4 * sea.current_sigma / math.sqrt(n_eff)
    assert x.std().item() == pytest.approx(sea.current_sigma, rel=0.03)
    anomaly = x - sea.current_mean
    for lag in (1, 12):  # 5 s and 60 s = one time constant
        rho = (anomaly[:, lag:] * anomaly[:, :-lag]).mean() / (anomaly * anomaly).mean()
        assert rho.item() == pytest.approx(math.exp(-lag * h / sea.current_time_constant), abs=0.02)
    # the direction drifts the same way, about the scene's mean direction
    direction = state["current_direction"] - state["current_direction_mean"]
    assert direction.std().item() == pytest.approx(sea.current_direction_sigma, rel=0.2)


def test_one_step_autocorrelation_is_exact_for_any_step():
    sea = SEA_STATES["ves"]
    n = 20000
    state = reset_ocean(sea, (n,), generator=_gen(), dtype=F64)
    for h in (0.05, 5.0, 60.0):
        nxt = step_ocean(state, sea, h, generator=_gen(3))
        x0 = state["current_speed"] - sea.current_mean
        x1 = nxt["current_speed"] - sea.current_mean
        rho = (x0 * x1).mean() / (x0 * x0).mean()
        assert rho.item() == pytest.approx(math.exp(-h / 60.0), abs=4 / math.sqrt(n))
        assert x1.std().item() == pytest.approx(sea.current_sigma, rel=0.03)  # stays stationary


def test_frozen_current_and_fixed_direction():
    sea = SeaState(
        current_mean=0.3,
        current_sigma=0.1,
        current_time_constant=math.inf,
        current_direction_mean=0.5,
        current_direction_sigma=0.1,
    )
    state = reset_ocean(sea, (64,), generator=_gen(), dtype=F64)
    assert torch.equal(state["current_direction_mean"], torch.full((64,), 0.5, dtype=F64))
    assert state["current_speed"].std() > 0  # drawn per episode ...
    later = step_ocean(state, sea, 10.0, generator=_gen(1))
    torch.testing.assert_close(later["current_speed"], state["current_speed"])  # ... then frozen
    torch.testing.assert_close(later["current_direction"], state["current_direction"])


def test_ideal_is_still_water_and_still_batched():
    state = reset_ocean("ideal", (5, 2), generator=_gen())
    gen = _gen(1)
    for _ in range(3):
        state = step_ocean(state, "ideal", 0.05, generator=gen)
    assert state.batch_size == (5, 2) and state["wave_amplitude"].shape == (5, 2, 100)
    position = (torch.rand(5, 2, 3, generator=_gen(2)) - 0.3) * 30  # some above the surface
    assert torch.equal(current_at(state, position), torch.zeros(5, 2, 3))  # [V, beta, w_down]
    assert torch.equal(water_velocity_at(state, position), torch.zeros(5, 2, 3))
    assert torch.equal(surface_elevation_at(state, position), torch.zeros(5, 2))
    assert not torch.signbit(current_at(state, position)).any()  # +0, not -0 or pi
    finite = reset_ocean("ideal", (5, 2), generator=_gen(), water_depth=40.0)
    assert torch.equal(current_at(finite, position), torch.zeros(5, 2, 3))
    assert not torch.signbit(current_at(finite, position)).any()


def test_ideal_current_drives_remus_exactly_like_no_current():
    state = reset_ocean("ideal", (3,), generator=_gen(), dtype=F64)
    eta = torch.zeros(3, 6, dtype=F64)
    # the third vehicle moves backwards with w = -0.0: atan2(-0, u_r < 0) = -pi, and a vertical
    # water velocity of -0 (instead of +0) would turn it into +pi (PVS's reverse-flow quirk)
    nu = torch.tensor(
        [[0.0] * 6, [1.0, 0.1, -0.05, 0, 0, 0.01], [-0.2, 0, -0.0, 0, 0, 0]], dtype=F64
    )
    act = torch.zeros(3, 3, dtype=F64)
    cmd = torch.tensor([[0.1, -0.05, 1525.0]] * 3, dtype=F64)
    with_ocean = remus100.step(eta, nu, act, cmd, current_at(state, eta[:, :3]), 0.05)
    without = remus100.step(eta, nu, act, cmd, torch.zeros(3, 2, dtype=F64), 0.05)
    for a, b in zip(with_ocean, without, strict=True):
        assert torch.equal(a, b)


# --------------------------------------------------------------------------- waves


@pytest.mark.parametrize("name", ["es", "ves"])
@pytest.mark.parametrize("grid", [(10, 10), (1, 1), (7, 3), (24, 16)])
def test_wave_components_carry_the_significant_wave_height(name, grid):
    sea = SEA_STATES[name]
    nf, nd = grid
    state = reset_ocean(sea, (3, 2), generator=_gen(), dtype=F64, n_frequencies=nf, n_directions=nd)
    assert state["wave_amplitude"].shape == (3, 2, nf * nd)
    m0 = (state["wave_amplitude"] ** 2 / 2).sum(-1)
    hs = 4 * m0.sqrt()  # per scene, in a batch
    torch.testing.assert_close(hs, torch.full((3, 2), sea.wave_hs, dtype=F64), rtol=1e-12, atol=0)
    single = reset_ocean(sea, (), generator=_gen(5), n_frequencies=nf, n_directions=nd)
    assert 4 * math.sqrt((single["wave_amplitude"] ** 2 / 2).sum().item()) == pytest.approx(
        sea.wave_hs, rel=1e-5
    )


@pytest.mark.parametrize("name", ["es", "ves"])
def test_continuous_spectrum_integral_and_peak(name):
    sea = SEA_STATES[name]
    omega = _fine_grid(sea)
    spectrum = jonswap_spectrum(omega, sea.wave_hs, sea.wave_tp, sea.wave_gamma)
    m0 = torch.trapezoid(spectrum, omega).item()
    assert 4 * math.sqrt(m0) == pytest.approx(sea.wave_hs, rel=1e-3)
    assert omega[spectrum.argmax()].item() == pytest.approx(2 * math.pi / sea.wave_tp, rel=1e-3)
    # independent check: DNV-RP-C205 normalisation A_gamma = 1 - 0.287 ln(gamma) (approximate)
    wp, gamma = 2 * math.pi / sea.wave_tp, sea.wave_gamma
    sigma = torch.where(omega <= wp, 0.07, 0.09)
    pm = 5 / 16 * sea.wave_hs**2 * wp**4 * omega**-5 * torch.exp(-1.25 * (omega / wp) ** -4)
    dnv = (
        (1 - 0.287 * math.log(gamma))
        * pm
        * gamma ** torch.exp(-0.5 * ((omega - wp) / (sigma * wp)) ** 2)
    )
    torch.testing.assert_close(spectrum, dnv, rtol=0.01, atol=1e-3 * spectrum.max().item())


def test_frequencies_are_stratified_in_equal_energy_bins():
    sea = SEA_STATES["es"]
    nf, nd = 10, 10
    state = reset_ocean(sea, (50,), generator=_gen(), dtype=F64, n_frequencies=nf, n_directions=nd)
    omega = _fine_grid(sea)
    spectrum = jonswap_spectrum(omega, sea.wave_hs, sea.wave_tp, sea.wave_gamma)
    cdf = torch.cat([torch.zeros(1, dtype=F64), torch.cumulative_trapezoid(spectrum, omega)])
    cdf = cdf / cdf[-1]
    w = state["wave_frequency"].reshape(50, nf, nd)
    idx = torch.searchsorted(omega, w.contiguous())
    quantile = cdf[idx]  # F(omega_j), to the fine grid's resolution
    lower = torch.arange(nf, dtype=F64).view(nf, 1) / nf
    assert (quantile >= lower - 1e-3).all() and (quantile <= lower + 1 / nf + 1e-3).all()
    # within a bin the quantiles are uniform: mean at the bin centre
    centre = (quantile - lower).mean().item() * nf
    assert centre == pytest.approx(0.5, abs=0.02)
    # every component has its own frequency (keeps the sea ergodic)
    assert (state["wave_frequency"].sort(-1).values.diff(dim=-1) > 0).all()
    # deep-water dispersion and cos^2 spreading about the mean current direction
    torch.testing.assert_close(state["wave_number"], state["wave_frequency"] ** 2 / GRAVITY)
    offset = state["wave_direction"] - state["current_direction_mean"].unsqueeze(-1)
    assert offset.abs().max().item() < math.pi / 2
    energy = (state["wave_amplitude"] ** 2 / 2).reshape(50, nf, nd)
    expected = torch.cos(offset.reshape(50, nf, nd)) ** 2
    torch.testing.assert_close(
        energy / energy.sum(-1, keepdim=True), expected / expected.sum(-1, keepdim=True)
    )


def test_component_velocity_moment_matches_spectrum_m2():
    """E[sum a^2 w^2 / 2] = m2 of the spectrum the sampler represents ([0.2, 12] w_p)."""
    sea = SEA_STATES["es"]
    n = 4096
    state = reset_ocean(sea, (n,), generator=_gen(), dtype=F64)
    m2_scene = ((state["wave_amplitude"] * state["wave_frequency"]) ** 2 / 2).sum(-1)
    omega = _fine_grid(sea, 0.2, 12.0)
    spectrum = jonswap_spectrum(omega, sea.wave_hs, sea.wave_tp, sea.wave_gamma)
    m2 = torch.trapezoid(omega**2 * spectrum, omega).item()
    se = m2_scene.std().item() / math.sqrt(n)
    assert abs(m2_scene.mean().item() - m2) < 4 * se
    assert se < 0.01 * m2


@pytest.mark.parametrize("name", ["es", "ves"])
def test_time_series_variance_matches_spectrum(name):
    """At a fixed point, time variances of elevation and surface velocity equal m0 and m2."""
    sea = SEA_STATES[name]
    scenes, times = 8, torch.arange(0.0, 3600.0, 0.7, dtype=F64)
    base = reset_ocean(sea, (scenes,), generator=_gen(), dtype=F64)
    series = base.unsqueeze(-1).expand(scenes, times.numel()).clone()
    series["time"] = times.expand(scenes, -1).clone()
    position = torch.zeros(scenes, times.numel(), 3, dtype=F64)
    elevation = surface_elevation_at(series, position)
    velocity = water_velocity_at(series, position)
    m0 = sea.wave_hs**2 / 16
    assert elevation.var(-1).mean().item() == pytest.approx(m0, rel=0.05)
    # each scene alone is close too (distinct frequencies keep the sea ergodic)
    assert ((elevation.var(-1) / m0 - 1).abs() < 0.2).all()
    m2_scene = ((base["wave_amplitude"] * base["wave_frequency"]) ** 2 / 2).sum(-1)
    horizontal = velocity[..., 0].var(-1) + velocity[..., 1].var(-1)
    torch.testing.assert_close(horizontal, m2_scene, rtol=0.15, atol=0)
    # deep water: the vertical velocity has the same variance as the horizontal one
    torch.testing.assert_close(velocity[..., 2].var(-1), m2_scene, rtol=0.15, atol=0)


def test_orbital_velocity_decays_exponentially_with_depth():
    sea = SeaState(name="one", wave_hs=2.0, wave_tp=8.0)
    state = reset_ocean(sea, (), generator=_gen(), dtype=F64, n_frequencies=1, n_directions=1)
    k = state["wave_number"][0].item()
    assert k == pytest.approx(state["wave_frequency"][0].item() ** 2 / GRAVITY)
    for phase in (0.0, 1.0, 2.5):
        fixed = state.clone()
        fixed["wave_phase"] = torch.full((1,), phase, dtype=F64)

        def at(z, fixed=fixed):
            return water_velocity_at(fixed, torch.tensor([3.0, -2.0, z], dtype=F64))

        shallow, deep = at(2.0), at(12.0)
        torch.testing.assert_close(deep, shallow * math.exp(-k * 10.0), rtol=1e-12, atol=1e-15)
        torch.testing.assert_close(at(-3.0), at(0.0), rtol=0, atol=0)  # above the surface
    # the orbit at the surface has radius a: speed a*omega
    surface = water_velocity_at(state, torch.zeros(3, dtype=F64))
    a_omega = (state["wave_amplitude"] * state["wave_frequency"])[0]
    torch.testing.assert_close(surface.norm(), a_omega)


def test_current_at_matches_water_velocity_and_includes_waves():
    state = reset_ocean("ves", (8,), generator=_gen(), dtype=F64)
    pos = torch.rand(8, 3, generator=_gen(1), dtype=F64) * 40
    speed_dir = current_at(state, pos)
    velocity = water_velocity_at(state, pos)
    torch.testing.assert_close(speed_dir[:, 0] * torch.cos(speed_dir[:, 1]), velocity[:, 0])
    torch.testing.assert_close(speed_dir[:, 0] * torch.sin(speed_dir[:, 1]), velocity[:, 1])
    assert (speed_dir[:, 1].abs() <= math.pi).all()
    gm = torch.stack(
        (
            state["current_speed"] * torch.cos(state["current_direction"]),
            state["current_speed"] * torch.sin(state["current_direction"]),
        ),
        -1,
    )
    assert ((velocity[:, :2] - gm).norm(dim=-1) > 1e-3).all()  # waves add to the current
    very_deep = pos.clone()
    very_deep[:, 2] = 2000.0
    torch.testing.assert_close(water_velocity_at(state, very_deep)[:, :2], gm)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_dtypes_follow_the_arguments(dtype):
    state = reset_ocean("es", (2, 3), generator=_gen(), dtype=dtype)
    state = step_ocean(state, "es", 0.05, generator=_gen(1))
    for key, value in state.items():
        assert value.dtype == (F64 if key == "time" else dtype), key
    pos = torch.zeros(2, 3, 3, dtype=dtype)
    assert current_at(state, pos).dtype == dtype and current_at(state, pos).shape == (2, 3, 3)
    assert water_velocity_at(state, pos).shape == (2, 3, 3)


def test_clock_does_not_drift_over_an_episode():
    state = reset_ocean("es", (), generator=_gen())
    gen = _gen(1)
    for _ in range(20000):  # 1000 s at 20 Hz
        state = step_ocean(state, "es", 0.05, generator=gen)
    assert state["time"].item() == pytest.approx(1000.0, abs=1e-9)


# --------------------------------------------------------------------------- randomness


def test_determinism_and_no_global_rng(global_rng_guard):
    global_state = torch.random.get_rng_state().clone()
    with global_rng_guard:
        runs = []
        for _ in range(2):
            gen = _gen(7)
            state = reset_ocean("es", (4,), generator=gen)
            state = step_ocean(state, "es", 0.05, generator=gen)
            runs.append((state, current_at(state, torch.zeros(4, 3))))
    assert torch.equal(torch.random.get_rng_state(), global_state)
    assert (runs[0][0] == runs[1][0]).all()
    assert torch.equal(runs[0][1], runs[1][1])
    other = reset_ocean("es", (4,), generator=_gen(9))
    assert not torch.equal(other["wave_phase"], runs[0][0]["wave_phase"])


def test_common_random_numbers_across_sea_states():
    es = reset_ocean("es", (16,), generator=_gen(3), dtype=F64)
    ves = reset_ocean("ves", (16,), generator=_gen(3), dtype=F64)
    ideal = reset_ocean("ideal", (16,), generator=_gen(3), dtype=F64)
    torch.testing.assert_close(es["wave_phase"], ves["wave_phase"])
    torch.testing.assert_close(es["current_direction_mean"], ideal["current_direction_mean"])
    z_es = (es["current_speed"] - 0.5) / 0.1
    z_ves = (ves["current_speed"] - 1.0) / 0.2
    torch.testing.assert_close(z_es, z_ves)
    # frequencies at the same energy quantiles scale with the peak frequency (same gamma)
    torch.testing.assert_close(es["wave_frequency"] * 10.0, ves["wave_frequency"] * 12.0)


def test_step_returns_a_new_tensordict_and_leaves_the_input_alone():
    state = reset_ocean("es", (4,), generator=_gen())
    before = state.clone()
    out = step_ocean(state, "es", 0.05, generator=_gen(1))
    assert out is not state
    assert (state == before).all()
    assert not torch.equal(out["current_speed"], state["current_speed"])


# --------------------------------------------------------------------------- bad input


def test_bad_names_and_arguments():
    with pytest.raises(ValueError, match=r"sea_state must be one of \['es', 'ideal', 'ves'\]"):
        get_sea_state("stormy")
    with pytest.raises(ValueError, match="sea_state"):
        reset_ocean("ES", (2,), generator=_gen())
    state = reset_ocean("es", (2,), generator=_gen())
    for dt in (-0.1, 0.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="dt"):
            step_ocean(state, "es", dt, generator=_gen())
    for position in (torch.zeros(2, 2), torch.zeros(3, 3), torch.zeros(3), torch.zeros(2, 3, 1)):
        with pytest.raises(ValueError, match="position_ned"):
            current_at(state, position)
        with pytest.raises(ValueError, match="position_ned"):
            water_velocity_at(state, position)
    with pytest.raises(ValueError, match="generator"):
        reset_ocean("es", (2,), generator=None)
    with pytest.raises(ValueError, match="generator"):
        step_ocean(state, "es", 0.05, generator=0)
    with pytest.raises(ValueError, match="n_frequencies"):
        reset_ocean("es", (2,), generator=_gen(), n_frequencies=0)
    with pytest.raises(ValueError, match="n_directions"):
        reset_ocean("es", (2,), generator=_gen(), n_directions=-1)
    with pytest.raises(ValueError, match="dtype"):
        reset_ocean("es", (2,), generator=_gen(), dtype=torch.int64)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("current_mean", -0.1),
        ("current_sigma", -1.0),
        ("current_sigma", math.nan),
        ("current_time_constant", 0.0),
        ("current_direction_sigma", -0.1),
        ("current_direction_mean", math.inf),
        ("wave_hs", -1.0),
        ("wave_tp", 0.0),
        ("wave_gamma", 0.5),
        ("usbl_noise_fraction", -0.01),
        ("usbl_bearing_sigma", math.inf),
        ("name", 3),
    ],
)
def test_sea_state_validation_names_the_field(field, value):
    with pytest.raises(ValueError, match=f"SeaState.{field}"):
        SeaState(**{field: value})


def test_sea_state_is_frozen():
    with pytest.raises(dataclasses.FrozenInstanceError):
        SEA_STATES["es"].wave_hs = 1.0
