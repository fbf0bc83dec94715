"""Ocean: current statistics, wave energy, depth decay, determinism and bad input."""

from __future__ import annotations

import math

import pytest
import torch

from torchrl_auv.physics.ocean import (
    SEA_STATES,
    SeaState,
    current_at,
    get_sea_state,
    jonswap_spectrum,
    reset_ocean,
    step_ocean,
    water_velocity_at,
)


def _gen(seed=0):
    return torch.Generator().manual_seed(seed)


@pytest.mark.parametrize("name", ["es", "ves"])
def test_stationary_current_mean_and_std(name):
    sea = SEA_STATES[name]
    n = 20000
    state = reset_ocean(sea, (n,), generator=_gen(), dtype=torch.float64)
    gen = _gen(1)
    for _ in range(40):  # stays stationary while stepping
        state = step_ocean(state, sea, 0.5, generator=gen)
    speed = state["current_speed"]
    se_mean = sea.current_sigma / math.sqrt(n)
    assert abs(speed.mean().item() - sea.current_mean) < 4 * se_mean
    assert speed.std().item() == pytest.approx(sea.current_sigma, rel=0.03)
    offset = state["current_direction"] - state["current_direction_mean"]
    assert offset.std().item() == pytest.approx(sea.current_direction_sigma, rel=0.03)


def test_gauss_markov_autocorrelation_is_exact():
    sea = SEA_STATES["ves"]
    n, h = 20000, 5.0
    state = reset_ocean(sea, (n,), generator=_gen(), dtype=torch.float64)
    nxt = step_ocean(state, sea, h, generator=_gen(3))
    x0 = state["current_speed"] - sea.current_mean
    x1 = nxt["current_speed"] - sea.current_mean
    rho = (x0 * x1).mean() / (x0 * x0).mean()
    expected = math.exp(-h / sea.current_time_constant)
    assert rho.item() == pytest.approx(expected, abs=4 / math.sqrt(n))


def test_ideal_is_still_water():
    state = reset_ocean("ideal", (5,), generator=_gen())
    state = step_ocean(state, "ideal", 0.05, generator=_gen(1))
    velocity = water_velocity_at(state, torch.rand(5, 3, generator=_gen(2)) * 30)
    assert torch.equal(velocity, torch.zeros(5, 3))


@pytest.mark.parametrize("name", ["es", "ves"])
def test_wave_components_carry_the_significant_wave_height(name):
    sea = SEA_STATES[name]
    state = reset_ocean(sea, (3, 2), generator=_gen(), dtype=torch.float64)
    m0 = (state["wave_amplitude"] ** 2 / 2).sum(-1)
    hs = 4 * m0.sqrt()
    torch.testing.assert_close(
        hs, torch.full((3, 2), sea.wave_hs, dtype=torch.float64), rtol=0.05, atol=0
    )
    # and the continuous spectrum integrates to the same H_s (within 5 %)
    wp = 2 * math.pi / sea.wave_tp
    omega = torch.linspace(0.05 * wp, 30 * wp, 200001, dtype=torch.float64)
    spectrum = jonswap_spectrum(omega, sea.wave_hs, sea.wave_tp, sea.wave_gamma)
    assert 4 * torch.trapezoid(spectrum, omega).sqrt().item() == pytest.approx(
        sea.wave_hs, rel=0.05
    )


def test_surface_elevation_variance_matches_spectrum():
    """Time-averaged variance of the sampled sea surface equals m0 = Hs^2 / 16."""
    sea = SEA_STATES["es"]
    state = reset_ocean(sea, (64,), generator=_gen(), dtype=torch.float64)
    t = torch.arange(0, 3600, 0.5, dtype=torch.float64)
    chi = -state["wave_frequency"].unsqueeze(-1) * t + state["wave_phase"].unsqueeze(-1)
    elevation = (state["wave_amplitude"].unsqueeze(-1) * torch.cos(chi)).sum(-2)
    assert elevation.var().item() == pytest.approx(sea.wave_hs**2 / 16, rel=0.1)


def test_orbital_velocity_decays_exponentially_with_depth():
    sea = SeaState(name="one", wave_hs=2.0, wave_tp=8.0)
    state = reset_ocean(
        sea, (), generator=_gen(), dtype=torch.float64, n_frequencies=1, n_directions=1
    )
    k = state["wave_number"][0].item()
    phase_zero = state.copy()
    phase_zero["wave_phase"] = torch.zeros(1, dtype=torch.float64)
    shallow = water_velocity_at(phase_zero, torch.tensor([0.0, 0.0, 2.0], dtype=torch.float64))
    deep = water_velocity_at(phase_zero, torch.tensor([0.0, 0.0, 12.0], dtype=torch.float64))
    ratio = deep[:2].norm() / shallow[:2].norm()
    assert ratio.item() == pytest.approx(math.exp(-k * 10.0), rel=1e-9)


def test_current_at_matches_water_velocity():
    state = reset_ocean("ves", (8,), generator=_gen(), dtype=torch.float64)
    pos = torch.rand(8, 3, generator=_gen(1), dtype=torch.float64) * 40
    speed_dir = current_at(state, pos)
    velocity = water_velocity_at(state, pos)
    torch.testing.assert_close(speed_dir[:, 0] * torch.cos(speed_dir[:, 1]), velocity[:, 0])
    torch.testing.assert_close(speed_dir[:, 0] * torch.sin(speed_dir[:, 1]), velocity[:, 1])


def test_determinism_and_no_global_rng(global_rng_guard):
    with global_rng_guard:
        a = step_ocean(reset_ocean("es", (4,), generator=_gen(7)), "es", 0.05, generator=_gen(8))
        b = step_ocean(reset_ocean("es", (4,), generator=_gen(7)), "es", 0.05, generator=_gen(8))
    assert (a == b).all()
    c = reset_ocean("es", (4,), generator=_gen(9))
    assert not torch.equal(c["wave_phase"], a["wave_phase"])


def test_step_does_not_modify_input():
    state = reset_ocean("es", (4,), generator=_gen())
    before = state.clone()
    step_ocean(state, "es", 0.05, generator=_gen(1))
    assert (state == before).all()


def test_bad_input():
    with pytest.raises(ValueError, match="sea_state"):
        get_sea_state("stormy")
    with pytest.raises(ValueError, match="dt"):
        step_ocean(reset_ocean("es", (2,), generator=_gen()), "es", -0.1, generator=_gen())
    with pytest.raises(ValueError, match="position_ned"):
        current_at(reset_ocean("es", (2,), generator=_gen()), torch.zeros(2, 2))
    with pytest.raises(ValueError, match="current_sigma"):
        SeaState(current_sigma=-1.0)
    with pytest.raises(ValueError, match="generator"):
        reset_ocean("es", (2,), generator=None)
