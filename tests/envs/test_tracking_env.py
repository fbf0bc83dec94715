"""AUVTrackingEnv: specs, determinism, bounds; the card's cost and reference segments, the USBL
fix, divergence, bad input."""

from __future__ import annotations

import math

import pytest
import torch
from torchrl.envs import TransformedEnv
from torchrl.envs.utils import check_env_specs

from torchrl_auv.envs import AUVTrackingEnv, ScriptedExpert, StateActionHistory
from torchrl_auv.estimation import kf_update, usbl_fix


@pytest.mark.parametrize("batch_size", [[], [1], [8]])
@pytest.mark.parametrize("sea_state", ["ideal", "es", "ves"])
@pytest.mark.parametrize("controller", ["s_surface", "pid", "smc"])
def test_check_env_specs(batch_size, sea_state, controller):
    env = AUVTrackingEnv(batch_size=batch_size, sea_state=sea_state, controller=controller, seed=0)
    check_env_specs(env, seed=0)


def test_same_seed_same_rollout_different_seed_differs():
    def rollout(seed):
        env = AUVTrackingEnv(batch_size=[2], sea_state="ves", seed=seed)
        return env.rollout(5, ScriptedExpert(env))

    a, b, c = rollout(3), rollout(3), rollout(4)
    assert (a == b).all()
    assert not torch.equal(a["next", "truth", "eta"], c["next", "truth", "eta"])


def test_observation_is_the_estimate_not_the_truth():
    env = AUVTrackingEnv(batch_size=[4], sea_state="es", seed=0)
    td = env.rollout(5)
    estimate, truth = td["next", "kf", "mean"][..., :3], td["next", "truth", "eta"][..., :3]
    assert not torch.equal(estimate, truth)
    # but a good one: horizontally within a few sigma of the ASV's GNSS error (1 m per axis,
    # the fixes' bias), in depth within centimetres (the depth sensor's 0.05 m, 20 Hz)
    assert (estimate - truth)[..., :2].norm(dim=-1).max() < 5.0
    assert (estimate - truth)[..., 2].abs().max() < 0.3


def test_expert_tracks_better_than_random_actions():
    env = AUVTrackingEnv(batch_size=[4], sea_state="es", seed=1)
    expert = env.rollout(60, ScriptedExpert(env))
    env.set_seed(1)
    random = env.rollout(60)
    assert expert["next", "cost"].mean() < 0.6 * random["next", "cost"].mean()
    assert (expert["next", "cost"] >= 0).all()
    torch.testing.assert_close(expert["next", "reward"], -expert["next", "cost"])


def test_truncation_and_metrics_at_the_time_limit():
    env = AUVTrackingEnv(batch_size=[2], seed=0, max_steps=4)
    td = env.rollout(10, break_when_any_done=False)
    truncated = td["next", "truncated"].squeeze(-1)
    assert truncated[:, 3].all() and not truncated[:, :3].any()
    assert not td["next", "terminated"].any()
    metrics = td["next", "metrics"][:, 3]
    for name in ("heading_error_mean", "heading_error_std", "depth_error_mean", "depth_error_std"):
        assert torch.isfinite(metrics[name]).all() and (metrics[name] >= 0).all()


@pytest.mark.parametrize("seed", [0, 1])
def test_random_actions_in_ves_stay_finite_and_in_bounds(seed):
    env = AUVTrackingEnv(batch_size=[4], sea_state="ves", seed=seed)
    td = env.rollout(150, break_when_any_done=False)
    for key in td.keys(True, True):
        value = td.get(key)
        if value.is_floating_point():
            assert torch.isfinite(value).all(), key
    assert env.action_spec.is_in(td["action"][:, 0])
    eta, nu = td["next", "truth", "eta"], td["next", "truth", "nu"]
    assert (eta[..., 2] >= 0).all() and (eta[..., 4].abs() < 1.4).all()
    assert (nu[..., :3].norm(dim=-1) < 5.0).all()


def test_history_transform_on_the_env():
    env = TransformedEnv(AUVTrackingEnv(batch_size=[2], seed=0), StateActionHistory(10))
    check_env_specs(env, seed=0)
    td = env.rollout(3)
    assert td["history", "observation"].shape == (2, 3, 10, 16)
    assert td["history", "action"].shape == (2, 3, 10, 3)


def test_bad_input():
    with pytest.raises(ValueError, match="sea_state"):
        AUVTrackingEnv(sea_state="storm")
    with pytest.raises(ValueError, match="controller"):
        AUVTrackingEnv(controller="lqr")
    with pytest.raises(ValueError, match="max_steps"):
        AUVTrackingEnv(max_steps=0)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(3))
def test_thousand_decision_episodes_in_ves_stay_finite_and_bounded(seed):
    env = AUVTrackingEnv(batch_size=[4], sea_state="ves", seed=seed, max_steps=1000)
    td = env.rollout(1000, break_when_any_done=False)
    for key in td.keys(True, True):
        value = td.get(key)
        if value.is_floating_point():
            assert torch.isfinite(value).all(), key
    eta, nu = td["next", "truth", "eta"], td["next", "truth", "nu"]
    assert (eta[..., 2] >= 0).all() and (eta[..., 4].abs() < 1.4).all()
    assert (nu[..., :3].norm(dim=-1) < 5.0).all()
    assert td["next", "truncated"][:, -1].all()


def test_constructor_seed_equals_set_seed():
    a = AUVTrackingEnv(batch_size=[2], seed=5).reset()
    env = AUVTrackingEnv(batch_size=[2], seed=0)
    env.set_seed(5)
    assert (a == env.reset()).all()


# -- the env card's cost, reference segments, USBL fix, divergence ------------------------------
def _card_cost(reference, eta, nu):
    """The env card: |wrap(psi_ref - psi)|/pi + |z_ref - z|/10 + |u_ref - u|/2 (true state)."""
    d_psi = reference[..., 1] - eta[..., 5]
    heading = torch.atan2(torch.sin(d_psi), torch.cos(d_psi)).abs() / math.pi
    depth = (reference[..., 0] - eta[..., 2]).abs() / 10
    return heading + depth + (reference[..., 2] - nu[..., 0]).abs() / 2


def _constant_action(action):
    def policy(td):
        td["action"] = action.expand((*td.batch_size, 3)).clone()
        return td

    return policy


def test_cost_and_observed_reference_follow_the_card_across_segment_boundaries():
    """segment_seconds=2: the reference (a new row of ``"reference"`` every 2 s of decisions
    of 1 s) at the end of decision k (t = k + 1 s) is row floor((k + 1) / 2)."""
    env = AUVTrackingEnv(batch_size=[3], sea_state="es", seed=4, segment_seconds=2.0)
    td = env.rollout(5, _constant_action(torch.tensor([0.5, -0.3, 0.2])))
    reference = td["reference"][:, 0]  # [B, segments, 3], fixed for the episode
    assert not torch.allclose(reference[:, 0], reference[:, 1])  # the rows differ
    rows = torch.tensor([(k + 1) // 2 for k in range(5)])  # 0, 1, 1, 2, 2
    ref_now = reference[:, rows]  # [B, T, 3]
    eta, nu = td["next", "truth", "eta"], td["next", "truth", "nu"]
    want = _card_cost(ref_now, eta, nu).unsqueeze(-1)
    torch.testing.assert_close(td["next", "cost"], want, rtol=1e-5, atol=1e-5)
    torch.testing.assert_close(td["next", "reward"], -want, rtol=1e-5, atol=1e-5)
    # the policy sees the same reference: observation[0] = (z_ref - z^)/10 with z^ the filter's
    seen = td["next", "observation"][..., 0] * 10 + td["next", "kf", "mean"][..., 2]
    torch.testing.assert_close(seen, ref_now[..., 0], rtol=1e-4, atol=1e-4)
    first = td["observation"][:, 0, 0] * 10 + td["kf", "mean"][:, 0, 2]  # at reset: row 0
    torch.testing.assert_close(first, reference[:, 0, 0], rtol=1e-4, atol=1e-4)


def test_the_usbl_fix_comes_from_the_asv_with_its_gnss_error_and_pulls_the_estimate():
    """The env card's fix, by hand: after the decision the ASV's GNSS error steps 1 s
    (Gauss-Markov, a = e^(-1/60), sigma 1.5 m in es), then one USBL fix of "es" (range 0.5 %,
    bearing hypot(0.1, 0.5) deg, 5 % dropout) from the ASV 30 m north of the AUV, converted from the
    ASV's believed position (so biased by the GNSS error, whose variance R includes)."""
    env = AUVTrackingEnv(batch_size=[2], sea_state="es", seed=2)
    td = env.reset()
    td["kf", "mean"][:, :2] += 3.0  # a filter 4.2 m off (1 m sigma): the fix must pull it back
    td["action"] = torch.zeros(2, 3)
    g = torch.Generator()
    g.set_state(env.rng.get_state())
    out = env.step(td.clone())["next"]
    # the same decision without the fix, from the public VehicleStack with the same draws;
    # setpoints by the card with a = 0: depth and heading held, 380 * 3 rpm; a 1000 m seabed
    # (the env's is 200 m): no bottom lock in either
    sp = td["setpoint"]
    setpoint = torch.stack((sp[:, 0], sp[:, 1], torch.full((2,), 1140.0)), -1)
    vehicles, _, _ = env.vehicles.decide(
        td.select("truth", "kf", "controller"), setpoint, td["ocean"], 1000.0, generator=g
    )
    torch.testing.assert_close(out["truth", "eta"], vehicles["truth", "eta"])  # same decision
    a = math.exp(-1.0 / 60.0)
    gnss = a * td["asv_gnss_error"] + 1.5 * math.sqrt(1 - a * a) * torch.randn(2, 2, generator=g)
    torch.testing.assert_close(out["asv_gnss_error"], gnss)
    truth = out["truth", "eta"][:, :3]
    asv = torch.stack((truth[:, 0] + 30.0, truth[:, 1], torch.zeros(2)), -1)
    bearing = math.hypot(math.radians(0.1), math.radians(0.5))
    fix, fix_cov, valid = usbl_fix(
        truth, asv, 0.005, bearing, g, dropout=0.05, asv_error=gnss, asv_error_sigma=1.5
    )
    assert valid.all()  # this seed loses no fix
    h = torch.cat([torch.eye(3), torch.zeros(3, 3)], 1)
    want_mean, want_cov = kf_update(vehicles["kf", "mean"], vehicles["kf", "cov"], fix, h, fix_cov)
    torch.testing.assert_close(out["kf", "mean"], want_mean)
    torch.testing.assert_close(out["kf", "cov"], want_cov)
    # the fix sits on truth + GNSS error, give or take the acoustic noise: ~32 m slant range x
    # 0.51 deg = 0.28 m per lateral axis (4 sigma: 1.2 m)
    assert ((fix[:, :2] - truth[:, :2] - gnss).norm(dim=-1) < 1.2).all()
    prior = vehicles["kf", "cov"][..., :3, :3].diagonal(dim1=-2, dim2=-1)
    posterior = out["kf", "cov"][..., :3, :3].diagonal(dim1=-2, dim2=-1)
    # prior ~1.25 m^2 against R ~2.25 m^2 (GNSS 1.5 m) + cm^2: posterior = prior R / (prior +
    # R), about 0.64 of the prior
    assert (prior[:, :2] > 0.5).all()
    assert (posterior[:, :2] < 0.7 * prior[:, :2]).all()
    assert (posterior <= prior + 1e-7).all()  # a fix never adds uncertainty
    before = (vehicles["kf", "mean"][:, :2] - fix[:, :2]).norm(dim=-1)
    after = (out["kf", "mean"][:, :2] - fix[:, :2]).norm(dim=-1)
    # pulled towards the fix by the gain prior / (prior + R), about 0.36
    assert (before > 2.0).all() and (after < 0.75 * before).all()


@pytest.mark.parametrize(
    ("key", "index", "value"),
    [
        (("truth", "eta"), 0, float("nan")),
        (("truth", "nu"), 0, float("inf")),
        (("truth", "actuators"), 2, float("nan")),
        (("truth", "nu"), 4, 6.0),
    ],  # finite but absurd: a 6 rad/s pitch rate loops the vehicle
)
def test_a_diverged_state_terminates_that_vehicle_only(key, index, value):
    env = AUVTrackingEnv(batch_size=[2], seed=0)
    td = env.reset()
    td[key][0, index] = value
    td["action"] = torch.zeros(2, 3)
    out = env.step(td)["next"]
    assert out["terminated"].squeeze(-1).tolist() == [True, False]
    assert out["done"].squeeze(-1).tolist() == [True, False]
    assert not out["truncated"].any()
    # the card's divergence cost, 10, and reward = -cost
    assert torch.isfinite(out["cost"]).all() and out["cost"][0].item() == 10.0
    torch.testing.assert_close(out["reward"], -out["cost"])
    assert torch.isfinite(out["observation"]).all()
    # the healthy vehicle is costed by the card's formula, unaffected
    want = _card_cost(out["reference"][1, 0], out["truth", "eta"][1], out["truth", "nu"][1])
    torch.testing.assert_close(out["cost"][1, 0], want, rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("max_steps", [0, -3, float("nan"), 2.5])
def test_bad_max_steps_names_the_argument(max_steps):
    with pytest.raises(ValueError, match="max_steps"):
        AUVTrackingEnv(max_steps=max_steps)


@pytest.mark.parametrize("segment_seconds", [0.0, -5.0, float("nan"), float("inf")])
def test_bad_segment_seconds_names_the_argument(segment_seconds):
    with pytest.raises(ValueError, match="segment_seconds"):
        AUVTrackingEnv(segment_seconds=segment_seconds)
