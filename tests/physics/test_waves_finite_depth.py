"""Finite-depth linear waves (spec v2, "Disturbances"): the dispersion relation and its limits,
the cosh/sinh orbital profiles against Airy theory written out here, the free-surface and
seabed conditions, the near-bed error of deep-water theory, and the vertical water velocity in
the vehicle's relative velocity. Expected values are computed in this file (bisection, math
module, the spec's constants), never read off the implementation."""

from __future__ import annotations

import math

import pytest
import torch

from torchrl_auv.physics import remus100
from torchrl_auv.physics.ocean import (
    SeaState,
    current_at,
    current_from_state,
    reset_ocean,
    seabed_factors,
    surface_elevation_at,
    water_velocity_at,
    wavenumber,
)

F64 = torch.float64
G = 9.81  # m/s^2 (spec)


def _gen(seed: int = 0) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


def _k_bisect(omega: float, h: float) -> float:
    """Root of g k tanh(k h) = omega^2 by bisection (independent of the implementation's Newton).

    Bracket: k > omega^2/g (tanh < 1) and k > omega/sqrt(g h) (x tanh x < x^2); at twice the
    larger of the two the left side already exceeds omega^2."""
    lo = 0.0
    hi = 4.0 * max(omega**2 / G, omega / math.sqrt(G * h))
    assert G * hi * math.tanh(hi * h) > omega**2
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if G * mid * math.tanh(mid * h) > omega**2:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


# --------------------------------------------------------------------------- dispersion


def test_dispersion_relation_holds_for_several_frequencies_and_depths():
    omega = torch.tensor([0.3, 2 * math.pi / 12, 2 * math.pi / 10, 1.0, 2.0], dtype=F64)
    depth = torch.tensor([1.0, 10.0, 39.0, 45.0, 58.0, 500.0], dtype=F64)
    k = wavenumber(omega[:, None], depth)  # broadcast [5, 1] x [6]
    assert k.shape == (5, 6) and k.dtype == F64
    residual = G * k * torch.tanh(k * depth) - omega[:, None] ** 2
    assert residual.abs().max().item() <= 1e-10
    for i, w in enumerate(omega.tolist()):
        for j, h in enumerate(depth.tolist()):
            assert k[i, j].item() == pytest.approx(_k_bisect(w, h), rel=1e-12)


def test_reset_ocean_solves_the_dispersion_relation_per_scene():
    depth = torch.tensor([39.0, 45.0, 58.0], dtype=F64)
    state = reset_ocean("ves", (3,), generator=_gen(), dtype=F64, water_depth=depth)
    deep = reset_ocean("ves", (3,), generator=_gen(), dtype=F64)
    k, omega = state["wave_number"], state["wave_frequency"]
    residual = G * k * torch.tanh(k * depth[:, None]) - omega**2
    assert residual.abs().max().item() <= 1e-10
    assert torch.equal(state["water_depth"], depth)
    assert "water_depth" not in deep.keys()  # deep water: no entry, every entry finite
    # the random draws do not depend on the depth (common random numbers)
    for key in ("wave_frequency", "wave_amplitude", "wave_direction", "wave_phase"):
        assert torch.equal(state[key], deep[key]), key
    # shallower water, shorter waves: k >= omega^2/g, strictly for the long (low-frequency)
    # components; the short ones (kh > ~19) are deep to rounding
    assert (k >= deep["wave_number"]).all()
    assert (k[:, :10] > 1.1 * deep["wave_number"][:, :10]).all()  # the lowest-frequency bin
    torch.testing.assert_close(state["wave_kx"], k * torch.cos(state["wave_direction"]))
    torch.testing.assert_close(state["wave_ky"], k * torch.sin(state["wave_direction"]))
    # a float depth applies to every scene; float32 follows the dtype
    one = reset_ocean("es", (2,), generator=_gen(), water_depth=45.0)
    assert one["wave_number"].dtype == torch.float32
    assert torch.equal(one["water_depth"], torch.full((2,), 45.0))


def test_shallow_and_deep_water_limits():
    omega = 0.5
    # shallow (kh << 1): k -> omega / sqrt(g h); from x tanh x = y = omega^2 h / g,
    # x^2 = y (1 + y/3 + O(y^2)), so k sqrt(g h) / omega - 1 = y/6 + O(y^2)
    for h in (0.01, 0.1, 0.5):
        y = omega**2 * h / G
        k = wavenumber(torch.tensor(omega, dtype=F64), h).item()
        assert k * math.sqrt(G * h) / omega - 1 == pytest.approx(y / 6, rel=1e-2)
    # deep (kh >> 1): k -> omega^2 / g, with k = k0 / tanh(kh) = k0 (1 + 2 e^{-2 k0 h} + ...)
    k0 = omega**2 / G
    for h in (5 / k0, 8 / k0):
        k = wavenumber(torch.tensor(omega, dtype=F64), h).item()
        assert k / k0 - 1 == pytest.approx(2 * math.exp(-2 * k0 * h), rel=1e-2)
    k = wavenumber(torch.tensor(omega, dtype=F64), 40 / k0).item()  # tanh(40) = 1 in float64
    assert k == pytest.approx(k0, rel=1e-15)
    # None and inf are deep water, exactly
    w = torch.tensor([0.3, 0.9], dtype=F64)
    assert torch.equal(wavenumber(w), w**2 / G)
    assert torch.equal(wavenumber(w, math.inf), w**2 / G)
    mixed = wavenumber(w[:, None], torch.tensor([math.inf, 45.0], dtype=F64))
    assert torch.equal(mixed[:, 0], w**2 / G) and (mixed[:, 1] > w**2 / G).all()


# --------------------------------------------------------------------------- orbital velocity


def _one_wave(h: float | None, *, phase: float, time: float, seed: int = 0):
    """One component (Hs 2 m, Tp 10 s) without current, in water of depth ``h``; returns the
    state and its amplitude, frequency and direction (inputs of the formulas below)."""
    sea = SeaState(name="one", wave_hs=2.0, wave_tp=10.0)
    state = reset_ocean(
        sea, (), generator=_gen(seed), dtype=F64, n_frequencies=1, n_directions=1, water_depth=h
    )
    state["wave_phase"] = torch.full((1,), phase, dtype=F64)
    state["time"] = torch.tensor(time, dtype=F64)
    a, w, theta = (
        state[k][0].item() for k in ("wave_amplitude", "wave_frequency", "wave_direction")
    )
    return state, a, w, theta


def _airy(a, w, k, theta, h, x, y, z, t, phase):
    """Linear finite-depth theory written out: (u_N, u_E, u_D) at depth z in water of depth h."""
    chi = k * (x * math.cos(theta) + y * math.sin(theta)) - w * t + phase
    horizontal = a * w * math.cosh(k * (h - z)) / math.sinh(k * h) * math.cos(chi)
    down = -a * w * math.sinh(k * (h - z)) / math.sinh(k * h) * math.sin(chi)
    return horizontal * math.cos(theta), horizontal * math.sin(theta), down


@pytest.mark.parametrize("phase", [0.0, 1.0, 2.5, -2.0])
def test_single_component_matches_airy_theory_from_surface_to_seabed(phase):
    h, t, x, y = 45.0, 7.3, 12.0, -5.0
    state, a, w, theta = _one_wave(h, phase=phase, time=t)
    k = _k_bisect(w, h)
    for z in (0.0, 5.0, 10.0, 30.0, 44.0, 45.0):
        got = water_velocity_at(state, torch.tensor([x, y, z], dtype=F64))
        want = torch.tensor(_airy(a, w, k, theta, h, x, y, z, t, phase), dtype=F64)
        torch.testing.assert_close(got, want, rtol=1e-10, atol=1e-13, msg=f"z = {z}")
    chi = k * (x * math.cos(theta) + y * math.sin(theta)) - w * t + phase
    # surface: horizontal a w coth(kh) cos chi (more than deep water's a w), vertical -a w sin chi
    surface = water_velocity_at(state, torch.tensor([x, y, 0.0], dtype=F64))
    assert surface[:2].norm().item() == pytest.approx(
        a * w / math.tanh(k * h) * abs(math.cos(chi)), rel=1e-10, abs=1e-14
    )
    assert surface[2].item() == pytest.approx(-a * w * math.sin(chi), rel=1e-10, abs=1e-14)
    # seabed: no flow through it; the horizontal velocity a w / sinh(kh) cos chi
    bed = water_velocity_at(state, torch.tensor([x, y, h], dtype=F64))
    assert abs(bed[2].item()) <= 1e-15  # zero to rounding
    assert bed[:2].norm().item() == pytest.approx(
        a * w / math.sinh(k * h) * abs(math.cos(chi)), rel=1e-10, abs=1e-14
    )
    # above the surface the surface value, below the seabed the seabed value
    torch.testing.assert_close(
        water_velocity_at(state, torch.tensor([x, y, -3.0], dtype=F64)), surface, rtol=0, atol=0
    )
    torch.testing.assert_close(
        water_velocity_at(state, torch.tensor([x, y, h + 4.0], dtype=F64)), bed, rtol=0, atol=0
    )


def test_local_depth_sets_the_profile_and_the_scene_depth_the_phase():
    """Slowly varying depth: the profile at the local depth (39 m), the wavenumber of the
    scene's depth (45 m) in the phase."""
    state, a, w, theta = _one_wave(45.0, phase=0.7, time=3.1)
    k45 = _k_bisect(w, 45.0)
    for z in (0.0, 20.0, 39.0):
        got = water_velocity_at(state, torch.tensor([4.0, 9.0, z], dtype=F64), water_depth=39.0)
        want = torch.tensor(_airy(a, w, k45, theta, 39.0, 4.0, 9.0, z, 3.1, 0.7), dtype=F64)
        torch.testing.assert_close(got, want, rtol=1e-10, atol=1e-13)
    # per-point depths broadcast like the batch; current_at reports the same vertical velocity
    batch = reset_ocean("es", (2,), generator=_gen(), dtype=F64, water_depth=45.0)
    position = torch.tensor([[0.0, 0.0, 39.0], [10.0, 0.0, 39.0]], dtype=F64)
    local = torch.tensor([39.0, 58.0], dtype=F64)
    velocity = water_velocity_at(batch, position, water_depth=local)
    assert abs(velocity[0, 2].item()) <= 1e-15 and velocity[1, 2].abs().item() > 1e-3
    torch.testing.assert_close(current_at(batch, position, water_depth=local)[:, 2], velocity[:, 2])


def test_precomputed_seabed_factors_and_hand_made_mappings():
    """current_from_state with seabed_factors added to the mapping (VehicleStack's per-decision
    shortcut) equals the per-call evaluation; a mapping without water_depth is deep water."""
    state = reset_ocean("ves", (4,), generator=_gen(6), dtype=F64, water_depth=45.0)
    position = torch.rand(4, 3, generator=_gen(7), dtype=F64) * 40
    local = torch.tensor([39.0, 45.0, 50.0, math.inf], dtype=F64)
    per_call = current_from_state(dict(state.items()), position, local)
    fast = current_from_state({**state, **seabed_factors(state, local)}, position)
    torch.testing.assert_close(fast, per_call, rtol=0, atol=0)
    torch.testing.assert_close(per_call, current_at(state, position, water_depth=local))
    deep = reset_ocean("ves", (4,), generator=_gen(6), dtype=F64)
    hand_made = {k: v for k, v in deep.items() if k != "water_depth"}
    assert torch.equal(current_from_state(hand_made, position), current_at(deep, position))
    with pytest.raises(ValueError, match="water_depth"):
        seabed_factors(deep)
    factors = seabed_factors(state)
    k = state["wave_number"]
    torch.testing.assert_close(factors["wave_bed_mirror"], torch.exp(-2 * k * 45.0))
    torch.testing.assert_close(
        factors["wave_bed_scale"], 1 / (1 - torch.exp(-2 * k * 45.0)), rtol=1e-13, atol=0
    )


def test_surface_and_seabed_kinematic_conditions_in_a_full_sea():
    """Free surface: the water's upward velocity at z = 0 is d(eta)/dt (linearised); seabed:
    no vertical flow at z = h. A ves sea at 45 m, many components and positions."""
    h = 45.0
    state = reset_ocean("ves", (6,), generator=_gen(4), dtype=F64, water_depth=h)
    xy = torch.rand(6, 2, generator=_gen(5), dtype=F64) * 200
    surface = torch.cat([xy, torch.zeros(6, 1, dtype=F64)], -1)
    dt = 1e-4
    later, earlier = state.clone(), state.clone()
    later["time"] = state["time"] + dt
    earlier["time"] = state["time"] - dt
    rate = (surface_elevation_at(later, surface) - surface_elevation_at(earlier, surface)) / (
        2 * dt
    )
    up = -water_velocity_at(state, surface)[:, 2]
    torch.testing.assert_close(up, rate, rtol=0, atol=1e-7)
    assert up.abs().max().item() > 0.1  # a real check: the sea moves
    bed = torch.cat([xy, torch.full((6, 1), h, dtype=F64)], -1)
    assert water_velocity_at(state, bed)[:, 2].abs().max().item() <= 1e-15


def test_deep_water_is_the_limit_of_finite_depth():
    positions = torch.tensor([[0.0, 0.0, 0.0], [30.0, 5.0, 10.0], [-7.0, 80.0, 50.0]], dtype=F64)
    deep = reset_ocean("ves", (3,), generator=_gen(2), dtype=F64)
    infinite = reset_ocean("ves", (3,), generator=_gen(2), dtype=F64, water_depth=math.inf)
    very = reset_ocean("ves", (3,), generator=_gen(2), dtype=F64, water_depth=1e4)
    reference = water_velocity_at(deep, positions)
    # h = inf is deep water bit for bit, through the state or as the local depth
    assert torch.equal(water_velocity_at(infinite, positions), reference)
    assert torch.equal(water_velocity_at(deep, positions, water_depth=math.inf), reference)
    # a very large finite depth converges to it (e^{-2kh} ~ e^{-560} for the slowest component)
    torch.testing.assert_close(
        water_velocity_at(very, positions), reference, rtol=1e-12, atol=1e-12
    )


def test_near_bed_orbital_velocity_deep_water_underestimates_by_about_a_third():
    """Issue [9/13] finding 7, by hand at the ves peak period (Tp 12 s) in 45 m of water:
    deep water's e^{-k0 z} against cosh(k(h - z)) / sinh(kh) for the horizontal amplitude."""
    h, w = 45.0, 2 * math.pi / 12.0
    k0, k = w**2 / G, _k_bisect(w, h)
    assert k * h == pytest.approx(1.415, abs=1e-3)  # intermediate depth

    def ratio(z):  # deep / finite
        return math.exp(-k0 * z) / (math.cosh(k * (h - z)) / math.sinh(k * h))

    # 5 m above the bed: deep water gives 63 % of the flow, 37 % too little (the finding's
    # "about 35 %"); at the bed itself 55 % (45 % too little); at the surface 89 %
    assert 1 - ratio(40.0) == pytest.approx(0.374, abs=1e-3)
    assert 1 - ratio(45.0) == pytest.approx(0.449, abs=1e-3)
    assert 1 - ratio(0.0) == pytest.approx(0.111, abs=1e-3)
    # the implementation gives the same ratio for its one-component sea at its own frequency
    finite, _, w1, _ = _one_wave(h, phase=0.0, time=0.0)
    deep, _, _, _ = _one_wave(None, phase=0.0, time=0.0)
    k1, k10 = _k_bisect(w1, h), w1**2 / G
    for z in (0.0, 40.0, 45.0):
        point = torch.tensor([0.0, 0.0, z], dtype=F64)  # chi = 0: all horizontal
        got = (
            water_velocity_at(deep, point)[:2].norm() / water_velocity_at(finite, point)[:2].norm()
        )
        want = math.exp(-k10 * z) / (math.cosh(k1 * (h - z)) / math.sinh(k1 * h))
        assert got.item() == pytest.approx(want, rel=1e-10)


def test_bad_water_depths_raise_naming_the_argument():
    state = reset_ocean("es", (2,), generator=_gen())
    position = torch.zeros(2, 3)
    for bad in (0.0, -5.0, math.nan, torch.tensor([45.0, 0.0]), True, "45"):
        with pytest.raises(ValueError, match="water_depth"):
            reset_ocean("es", (2,), generator=_gen(), water_depth=bad)
        with pytest.raises(ValueError, match="water_depth"):
            water_velocity_at(state, position, water_depth=bad)
        with pytest.raises(ValueError, match="water_depth"):
            current_at(state, position, water_depth=bad)
    with pytest.raises(ValueError, match="water_depth"):
        reset_ocean("es", (2,), generator=_gen(), water_depth=torch.full((3,), 45.0))
    with pytest.raises(ValueError, match="water_depth"):
        current_at(state, position, water_depth=torch.full((3,), 45.0))


# --------------------------------------------------------------------------- the vehicle


def test_vertical_water_velocity_is_a_relative_heave():
    """A REMUS-100 at rest, fins centred, propeller off, in water sinking at 0.2 m/s: the
    relative velocity is w_r = w - w_c = -0.2 m/s, so the hull sees the flow of a vehicle rising
    at 0.2 m/s. Forces by hand from the spec (Secs. 2, 4): angle of attack
    alpha = atan2(-0.2, 0) = -pi/2, hull lift and drag at U_r = 0.2, heave damping
    M_33 / T_heave; nothing else acts (no rates, no thrust, no restoring at zero attitude)."""
    zero6, zero3 = torch.zeros(6, dtype=F64), torch.zeros(3, dtype=F64)
    current = torch.tensor([0.0, 0.0, 0.2], dtype=F64)  # [V_c, beta_c, w_c], w_c down
    nu_dot, _, _ = remus100.dynamics(zero6, zero6, zero3, zero3, current)
    # spec Sec. 2.7 and 2.6: S, C_D0, C_L_alpha, pi e AR; heave damping base
    area, cd0, cl_alpha, pi_e_ar = (
        0.7 * 1.6 * 0.19,
        0.05595961914206819,
        0.2659967942359403,
        (0.37306412761378793),
    )
    d_heave = 3.0233510795768757
    alpha, u_r2 = -math.pi / 2, 0.2**2
    c_lift = cl_alpha * alpha
    c_drag = cd0 + c_lift**2 / pi_e_ar
    f_drag, f_lift = 0.5 * 1026 * u_r2 * area * c_drag, 0.5 * 1026 * u_r2 * area * c_lift
    x_force = -math.cos(alpha) * f_drag + math.sin(alpha) * f_lift
    z_force = -math.sin(alpha) * f_drag - math.cos(alpha) * f_lift - d_heave * (-0.2)
    # M^-1 entries from spec Sec. 2.4
    m11, m15, m33 = 3.1430023437722727e-02, -2.6123846790717434e-03, 1.6537940412463644e-02
    want = torch.tensor([m11 * x_force, 0, m33 * z_force, 0, m15 * x_force, 0], dtype=F64)
    torch.testing.assert_close(nu_dot, want, rtol=1e-12, atol=1e-15)
    assert nu_dot[2].item() > 0  # the sinking water drags the vehicle down (z positive down)
    # exactly what a vehicle rising at 0.2 m/s feels in still water (PVS, 2-wide current)
    rising = torch.tensor([0.0, 0.0, -0.2, 0.0, 0.0, 0.0], dtype=F64)
    still, _, _ = remus100.dynamics(zero6, rising, zero3, zero3, torch.zeros(2, dtype=F64))
    assert torch.equal(nu_dot, still)
    # one step: the vehicle starts to sink with the water
    eta, nu, _ = remus100.step(zero6, zero6, zero3, zero3, current, 0.05)
    assert nu[2].item() > 0 and eta[2].item() > 0
    # the horizontal columns keep their meaning: [V, beta, 0] is the 2-wide current
    horizontal = torch.tensor([0.5, 0.3], dtype=F64)
    padded = torch.tensor([0.5, 0.3, 0.0], dtype=F64)
    for a, b in zip(
        remus100.step(zero6, zero6, zero3, zero3, horizontal, 0.05),
        remus100.step(zero6, zero6, zero3, zero3, padded, 0.05),
        strict=True,
    ):
        assert torch.equal(a, b)
