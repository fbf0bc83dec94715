"""DataCollectionEnv: specs, layouts, determinism, bounds, metrics, expert, bad input;
termination (cost, flags), station keeping in service, the ASV, the observation's features."""

from __future__ import annotations

import math

import pytest
import torch
from torchrl.envs import TransformedEnv
from torchrl.envs.utils import check_env_specs

from torchrl_auv.envs import (
    SIM_KEY,
    AUVTrackingEnv,
    DataCollectionEnv,
    ScriptedExpert,
    StateActionHistory,
)
from torchrl_auv.envs.data_collection import AGENT_OBSERVATION_FEATURES

METRICS = (
    "sdr",
    "ssn",
    "ec",
    "shaft_power",
    "collisions",
    "violations",
    "overflow",
    "heading_error_mean",
    "heading_error_std",
    "depth_error_mean",
    "depth_error_std",
    "services_inside",
    "kf_position_error",
    "usbl_position_error",
)
FEATURE = {name: i for i, name in enumerate(AGENT_OBSERVATION_FEATURES)}


@pytest.mark.parametrize("batch_size", [[], [1], [8]])
@pytest.mark.parametrize("sea_state", ["ideal", "es", "ves"])
@pytest.mark.parametrize("controller", ["s_surface", "pid", "smc"])
def test_check_env_specs(batch_size, sea_state, controller):
    env = DataCollectionEnv(
        batch_size=batch_size, sea_state=sea_state, controller=controller, seed=0
    )
    check_env_specs(env, seed=0)


@pytest.mark.parametrize("batch_size", [[], [3]])
def test_flat_layout_specs_and_agreement_with_the_multi_agent_layout(batch_size):
    flat = DataCollectionEnv(batch_size=batch_size, seed=5, flatten_agents=True, num_auvs=3)
    check_env_specs(flat, seed=0)
    multi = DataCollectionEnv(batch_size=batch_size, seed=5, num_auvs=3)
    flat.set_seed(5)
    multi.set_seed(5)
    a = flat.rollout(4, ScriptedExpert(flat))
    b = multi.rollout(4, ScriptedExpert(multi))
    torch.testing.assert_close(a["observation"], b["agents", "observation"].flatten(-2))
    torch.testing.assert_close(a["action"], b["agents", "action"].flatten(-2))
    torch.testing.assert_close(a["next", "cost"], b["next", "agents", "cost"].sum(-2))
    torch.testing.assert_close(a["next", "reward"], b["next", "agents", "reward"].sum(-2))


def test_multi_agent_keys_and_shapes():
    env = DataCollectionEnv(batch_size=[2], seed=0, num_auvs=3, num_sensors=10)
    td = env.rollout(3)
    assert td["agents", "observation"].shape == (2, 3, 3, len(AGENT_OBSERVATION_FEATURES))
    assert td["agents", "action"].shape == (2, 3, 3, 3)
    for key in ("reward", "cost", "done", "terminated", "truncated"):
        assert td["next", "agents", key].shape == (2, 3, 3, 1)
    for key in ("done", "terminated", "truncated"):
        assert td["next", key].shape == (2, 3, 1)
    assert (td["next", "agents", "cost"] >= 0).all()
    assert set(METRICS) <= set(td["next", "metrics"].keys())
    assert td["next", "metrics", "sdr"].shape == (2, 3)


def test_the_simulator_state_is_one_key_and_the_rest_fits_in_1_kb_per_frame():
    """Everything a learner does not need lives under ``"sim"``: excluding it (and its
    ``next``) leaves the observation, action, reward, done, metrics and cost terms, at most
    1 KB per frame for the default two AUVs, and nothing else at the top level."""
    env = DataCollectionEnv(batch_size=[2], seed=0)
    td = env.rollout(4)
    sim_leaves = td["sim"].keys(True, True)
    assert {"truth", "kf", "task", "ocean", "sensors", "setpoint"} <= set(td["sim"].keys())
    assert ("truth", "eta") in sim_leaves
    kept = td.exclude(SIM_KEY, ("next", SIM_KEY))
    assert set(kept.keys()) == {
        "agents",
        "cost_terms",
        "done",
        "metrics",
        "next",
        "overridden",
        "step_count",
        "terminated",
        "truncated",
    }
    per_frame = kept.bytes() / td.numel()
    assert per_frame <= 1024, per_frame
    assert td.bytes() / td.numel() > 10 * per_frame  # the simulator state is the bulk


def test_same_seed_same_rollout_different_seed_differs():
    def rollout(seed):
        env = DataCollectionEnv(batch_size=[2], sea_state="ves", seed=seed)
        return env.rollout(4, ScriptedExpert(env))

    a, b, c = rollout(3), rollout(3), rollout(4)
    assert (a == b).all()
    assert not torch.equal(a["next", "sim", "truth", "eta"], c["next", "sim", "truth", "eta"])
    assert not torch.equal(
        a["sim", "task", "nodes", "position"], c["sim", "task", "nodes", "position"]
    )


def test_observation_is_the_estimate_not_the_truth():
    env = DataCollectionEnv(batch_size=[4], sea_state="es", seed=0)
    td = env.rollout(20)
    estimate, truth = (
        td["next", "sim", "kf", "mean"][..., :3],
        td["next", "sim", "truth", "eta"][..., :3],
    )
    error = (estimate - truth)[..., :2].norm(dim=-1)
    # the ASV's GNSS error (sigma 1.5 m per axis in es, 60 s correlation) biases the fixes:
    # the filter is metres off, not centimetres, and not wildly so
    assert 0.3 < error.mean() < 4.0 and error.max() < 10.0
    obs = td["next", "agents", "observation"]
    depth = obs[..., FEATURE["depth"]] * env.config.seabed_depth_range_m[1]
    torch.testing.assert_close(depth, estimate[..., 2], rtol=1e-5, atol=1e-4)
    # the distances to the edges come from the estimate too
    x_low = obs[..., FEATURE["edge_x_low"]] * env.config.area_m[0]
    y_high = obs[..., FEATURE["edge_y_high"]] * env.config.area_m[1]
    torch.testing.assert_close(x_low, estimate[..., 0], rtol=1e-5, atol=1e-3)
    torch.testing.assert_close(
        y_high, env.config.area_m[1] - estimate[..., 1], rtol=1e-5, atol=1e-3
    )


def test_the_current_and_altitude_features_are_the_vehicles_own_measurements():
    """The current estimate is the scene's current (north, east) within the ADCP's noise
    (0.05 m/s per axis); the altitude is the altimeter's reading (0.1 m noise, 30 m range)."""
    env = DataCollectionEnv(batch_size=[8], sea_state="ves", seed=1)
    td = env.rollout(30, ScriptedExpert(env), break_when_any_done=False)
    obs, nxt = td["next", "agents", "observation"], td["next"]
    speed, direction = (
        nxt["sim", "ocean", "current_speed"],
        nxt["sim", "ocean", "current_direction"],
    )
    flow = torch.stack((speed * torch.cos(direction), speed * torch.sin(direction)), -1)
    seen = torch.stack((obs[..., FEATURE["current_north"]], obs[..., FEATURE["current_east"]]), -1)
    noise = seen - flow[..., None, :]
    assert noise.mean().abs() < 0.01 and abs(noise.std().item() - 0.05) < 0.01
    h_max = env.config.seabed_depth_range_m[1]
    from torchrl_auv import iout

    eta = nxt["sim", "truth", "eta"]
    terrain = nxt["sim", "task", "terrain"]
    seabed = torch.stack(
        [
            iout.seabed_depth(terrain[:, t], eta[:, t, :, 0], eta[:, t, :, 1], env.config)
            for t in range(30)
        ],
        1,
    )
    true_altitude = seabed - eta[..., 2]
    seen = obs[..., FEATURE["altitude"]] * h_max
    near = true_altitude < 29.0
    assert near.any() and (~near).any()
    assert ((seen - true_altitude)[near].abs() < 0.5).all()  # 5 sigma of 0.1 m
    assert torch.allclose(seen[true_altitude > 31.0], torch.tensor(30.0))  # out of range


def test_an_auv_in_service_gets_the_station_keepers_setpoints():
    """While in service the env replaces the action by
    :func:`~torchrl_auv.iout.station_keeping_setpoints` of what the AUV knows (filter,
    compass, node, current estimate, altimeter), recomputed here from those public pieces;
    the other AUVs get the card's action mapping."""
    from torchrl_auv import iout

    env = DataCollectionEnv(batch_size=[4], sea_state="es", seed=3, num_auvs=2)
    td = env.reset()
    td["sim", "task", "auvs", "in_service"][:, 0] = True
    td["sim", "task", "auvs", "service_remaining"][:, 0] = 50.0
    td["agents", "action"] = torch.full((4, 2, 3), 0.7)
    before = td.clone()
    out = env.step(td)["next"]
    eta_hat, _ = env.vehicles.estimate(before["sim"])
    node = iout.gather_nodes(
        before["sim", "task", "nodes", "position"], before["sim", "task", "auvs", "target"]
    )
    sensors = before["sim", "sensors"]
    altitude = torch.where(sensors["altitude_valid"], sensors["altitude"], torch.nan)
    depth, heading, rpm = iout.station_keeping_setpoints(
        eta_hat[:, 0, :3],
        eta_hat[:, 0, 5],
        node[:, 0],
        sensors["current"][:, 0],
        altitude[:, 0],
        env.station_keeping,
    )
    torch.testing.assert_close(out["sim", "setpoint"][:, 0], torch.stack((depth, heading, rpm), -1))
    assert out["overridden"][:, 0].all() and not out["overridden"][:, 1].any()
    # not in service: 0.7 -> depth + 0.56 m (above the seabed the altimeter sees, if any),
    # heading + 0.105 rad, 380 * 3.7 rpm
    sp = before["sim", "setpoint"][:, 1]
    torch.testing.assert_close(out["sim", "setpoint"][:, 1, 1], sp[:, 1] + 0.105)
    torch.testing.assert_close(out["sim", "setpoint"][:, 1, 2], torch.full((4,), 380.0 * 3.7))
    assert (out["sim", "setpoint"][:, 1, 0] <= sp[:, 0] + 0.56 + 1e-5).all()


def test_the_depth_setpoint_stays_above_the_seabed_the_altimeter_sees():
    """z_sp <= z_hat + altitude - clearance (1 m) when the altimeter has a reading."""
    env = DataCollectionEnv(batch_size=[2], seed=0, num_auvs=1, num_sensors=5)
    td = env.reset()
    td["sim", "sensors", "altitude"][:] = 3.0
    td["sim", "sensors", "altitude_valid"][:] = True
    td["sim", "setpoint"][..., 0] = td["sim", "kf", "mean"][..., 2] + 1.5
    td["agents", "action"] = torch.ones(2, 1, 3)  # deeper by 0.8 m
    out = env.step(td.clone())["next"]
    floor = td["sim", "kf", "mean"][..., 2] + 3.0 - 1.0
    torch.testing.assert_close(out["sim", "setpoint"][..., 0], floor)
    td["sim", "sensors", "altitude_valid"][:] = False  # no echo: no clamp from the altimeter
    out = env.step(td.clone())["next"]
    torch.testing.assert_close(out["sim", "setpoint"][..., 0], td["sim", "setpoint"][..., 0] + 0.8)


def test_services_end_on_station_in_ideal_water():
    """The expert with the station keeper in still water, 4 scenes x 300 decisions of the
    paper's rate model: services complete and end within the service radius (a regression
    check of the keeper; the full numbers per preset are in torchrl_auv.cli.collection)."""
    env = DataCollectionEnv(batch_size=[4], seed=2, rate_model="paper")
    td = env.rollout(300, ScriptedExpert(env), break_when_any_done=False)
    final = td["next", "metrics"][:, -1]
    assert final["ssn"].sum() >= 20
    assert final["services_inside"].sum() >= 0.9 * final["ssn"].sum()


def test_truncation_and_metrics_at_the_time_limit():
    env = DataCollectionEnv(batch_size=[2], seed=0, max_steps=4)
    td = env.rollout(10, break_when_any_done=False)
    truncated = td["next", "truncated"].squeeze(-1)
    assert truncated[:, 3].all() and not truncated[:, :3].any()
    assert td["next", "agents", "truncated"][:, 3].all()
    metrics = td["next", "metrics"][:, 3]
    for name in METRICS:
        value = metrics[name].float()
        assert torch.isfinite(value).all() and (value >= 0).all(), name


def test_leaving_the_area_terminates_with_the_termination_cost():
    env = DataCollectionEnv(batch_size=[1], seed=0, num_auvs=1, exit_margin_m=0.0)
    td = env.reset()
    td["sim", "truth", "eta"][..., 0] = -0.5  # already outside: the first step ends the episode
    td["agents", "action"] = torch.zeros(1, 1, 3)
    out = env.step(td)["next"]
    assert out["terminated"].all() and not out["truncated"].any()
    assert out["agents", "cost"].item() >= env.termination_cost
    stability_end = env.cost_weights.stability_termination_cost()
    w = env.cost_weights  # distance, regress, collision and violation at their weights
    assert stability_end == pytest.approx(
        (w.distance + w.regress + w.collision + w.violation) / (1 - 0.99)
    )
    assert out["agents", "stability_cost"].item() >= stability_end


def test_the_stability_cost_is_zero_in_service_and_a_separate_signal_from_the_cost():
    """The expert serves nodes: in service (inside the area, clear of the other AUV) the
    stability cost is 0 while the task cost still pays energy; outside service it is the
    distance, regress, collision and violation terms (at most their weights)."""
    env = DataCollectionEnv(batch_size=[2], seed=2, rate_model="paper")
    td = env.rollout(120, ScriptedExpert(env), break_when_any_done=False)
    nxt = td["next"]
    stability, cost = nxt["agents", "stability_cost"][..., 0], nxt["agents", "cost"][..., 0]
    terms = nxt["cost_terms"]
    serving = (
        nxt["sim", "task", "auvs", "in_service"]
        & (terms["violation"] == 0)
        & (terms["collision"] == 0)
    )
    assert serving.any() and (stability[serving] == 0).all() and (cost[serving] > 0).all()
    assert (stability[~serving] > 0).any()
    assert (stability <= env.cost_weights.max_stability_cost() + 1e-5).all()
    # the safety terms are shared: stability >= collision + violation everywhere
    assert (stability >= terms["collision"] + terms["violation"] - 1e-6).all()
    flat = DataCollectionEnv(batch_size=[2], seed=2, flatten_agents=True)
    assert flat.rollout(3)["next", "stability_cost"].shape == (2, 3, 1)


def test_approach_legs_follow_the_service_flags_and_the_targets():
    """``("agents", "approach" | "service_start")``: False at reset; a decision starts
    service exactly when the AUV is in service after it and was not before; an approach
    decision starts out of service with a target that it keeps or reaches."""
    env = DataCollectionEnv(batch_size=[2], seed=2, rate_model="paper")
    td = env.rollout(150, ScriptedExpert(env), break_when_any_done=False)
    first = env.reset()
    assert not first["agents", "approach"].any() and not first["agents", "service_start"].any()
    before = td["sim", "task", "auvs"]
    after = td["next", "sim", "task", "auvs"]
    approach = td["next", "agents", "approach"][..., 0]
    start = td["next", "agents", "service_start"][..., 0]
    assert start.any() and approach.any() and (~approach).any()
    assert torch.equal(start, ~before["in_service"] & after["in_service"])
    kept = after["target"] == before["target"]
    expected = ~before["in_service"] & (before["target"] >= 0) & kept
    assert torch.equal(approach, expected)
    assert (start & ~approach).sum() == 0  # a leg ends on its own last transition
    assert not (approach & td["next", "overridden"]).any()  # the policy's own decisions


def test_history_transform_on_the_multi_agent_env():
    env = TransformedEnv(
        DataCollectionEnv(batch_size=[2], seed=0),
        StateActionHistory(
            10, observation_key=("agents", "observation"), action_key=("agents", "action")
        ),
    )
    check_env_specs(env, seed=0)
    td = env.rollout(3)
    size = env.base_env.observation_dim
    assert td["agents", "history", "observation"].shape == (2, 3, 2, 10, size)
    assert td["agents", "history", "action"].shape == (2, 3, 2, 10, 3)


def test_expert_collects_data_and_beats_random_actions():
    env = DataCollectionEnv(batch_size=[4], seed=1, rate_model="paper", max_steps=200)
    expert = env.rollout(200, ScriptedExpert(env), break_when_any_done=False)
    env.set_seed(1)
    random = env.rollout(200, break_when_any_done=False)
    assert expert["next", "agents", "cost"].mean() < random["next", "agents", "cost"].mean()
    assert (
        expert["next", "metrics", "ssn"].amax(-1).sum()
        > random["next", "metrics", "ssn"].amax(-1).sum()
    )


def _assert_finite_and_in_bounds(env, td):
    for key in td.keys(True, True):
        value = td.get(key)
        if value.is_floating_point():
            assert torch.isfinite(value).all(), key
    assert env.full_action_spec["agents", "action"].is_in(td["agents", "action"][:, 0])
    eta, nu = td["next", "sim", "truth", "eta"], td["next", "sim", "truth", "nu"]
    seabed = env.config.seabed_depth_range_m[1]
    assert (eta[..., 2] >= 0).all() and (eta[..., 2] <= seabed).all()
    assert (eta[..., 4].abs() < 1.4).all()
    assert (nu[..., :3].norm(dim=-1) < 5.0).all()
    margin = env.exit_margin_m + 5.0  # one decision past the margin at most
    assert (eta[..., :2] > -margin).all() and (eta[..., :2] < 200.0 + margin).all()
    assert (td["next", "agents", "cost"] >= 0).all()
    obs = td["next", "agents", "observation"]
    assert env.observation_spec["agents", "observation"].is_in(obs[:, 0])


@pytest.mark.parametrize("seed", [0, 1])
def test_random_actions_in_ves_stay_finite_and_in_bounds(seed):
    env = DataCollectionEnv(batch_size=[4], sea_state="ves", seed=seed)
    td = env.rollout(100, break_when_any_done=False)
    _assert_finite_and_in_bounds(env, td)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_1000_decision_ves_episodes_with_random_actions(seed):
    env = DataCollectionEnv(batch_size=[4], sea_state="ves", seed=seed)
    td = env.rollout(1000, break_when_any_done=False)
    _assert_finite_and_in_bounds(env, td)


@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"sea_state": "stormy"}, "sea_state"),
        ({"controller": "lqr"}, "controller"),
        ({"num_auvs": 0}, "num_auvs"),
        ({"num_sensors": 0}, "num_sensors"),
        ({"area_m": (-200.0, 200.0)}, "area_m"),
        ({"rate_model": "magic"}, "rate_model"),
        ({"max_steps": 0}, "max_steps"),
        ({"termination_cost": -1.0}, "termination_cost"),
        ({"exit_margin_m": -1.0}, "exit_margin_m"),
    ],
)
def test_bad_input_names_the_argument(kwargs, argument):
    with pytest.raises(ValueError, match=argument):
        DataCollectionEnv(batch_size=[1], **kwargs)


def test_unknown_argument_is_pythons_type_error_naming_it():
    with pytest.raises(TypeError, match="unexpected keyword argument 'areas'"):
        DataCollectionEnv(batch_size=[1], areas=(1.0, 1.0))


@pytest.mark.slow
def test_expert_reaches_the_papers_magnitudes_with_the_paper_rate_model():
    """Paper (and the group's heuristic): SDR ~100 (99-110), SSN ~50 (49-56), EC ~350 W
    (404-418 W). "Of order" is checked as within a factor of 3 of the paper's value."""
    env = DataCollectionEnv(batch_size=[4], seed=100, rate_model="paper")
    td = env.rollout(1000, ScriptedExpert(env), break_when_any_done=False)
    assert not td["next", "terminated"].any()
    final = td["next", "metrics"][:, -1]
    for name, paper in (("sdr", 100.0), ("ssn", 50.0), ("ec", 350.0)):
        mean = final[name].float().mean().item()
        assert paper / 3 <= mean <= 3 * paper, (name, mean)
    # regression bound, not the paper's: measured 6, 2, 0, 11 decisions with a pair closer
    # than 5 m (two AUVs holding station over neighbouring nodes do not repel each other)
    assert (final["collisions"] <= 20).all()


# -- termination, the ASV ---------------------------------------------------------------------
def test_the_default_termination_cost_outweighs_any_continuation():
    """c_term = N c_max / (1 - gamma_max): the largest discounted cost the whole scene could
    still accumulate (gamma_max 0.99, the recipes' largest discount)."""
    from torchrl_auv.iout import CostWeights

    env = DataCollectionEnv(batch_size=[1], seed=0)
    w = CostWeights()
    c_max = w.mission + w.energy + w.collision + w.violation
    assert env.termination_cost == pytest.approx(2 * c_max / (1 - 0.99))


@pytest.mark.parametrize(
    ("key", "index", "value"),
    [
        (("sim", "truth", "eta"), 0, float("nan")),
        (("sim", "truth", "eta"), 1, float("nan")),
        (("sim", "truth", "nu"), 0, float("inf")),
        (("sim", "truth", "actuators"), 2, float("nan")),
    ],
)
def test_a_non_finite_auv_terminates_and_its_peers_are_truncated(key, index, value):
    env = DataCollectionEnv(batch_size=[2], seed=0, num_sensors=10, termination_cost=37.0)
    td = env.reset()
    td[key][0, 1, index] = value  # scene 0, AUV 1
    td["agents", "action"] = torch.zeros(2, 2, 3)
    out = env.step(td)["next"]
    assert out["terminated"].squeeze(-1).tolist() == [True, False]
    assert out["done"].squeeze(-1).tolist() == [True, False]
    assert not out["truncated"].any()
    # the AUV that ends the episode is terminated; its peer is truncated (it bootstraps)
    assert out["agents", "terminated"].squeeze(-1).tolist() == [[False, True], [False, False]]
    assert out["agents", "truncated"].squeeze(-1).tolist() == [[True, False], [False, False]]
    assert out["agents", "done"].squeeze(-1).tolist() == [[True, True], [False, False]]
    cost, reward = out["agents", "cost"].squeeze(-1), out["agents", "reward"].squeeze(-1)
    # the AUV that ends the episode: its own terms are undefined (NaN pose), c_term alone
    assert cost[0, 1].item() == 37.0 and torch.equal(reward, -cost)
    # the others do not pay it and stay finite
    healthy = torch.tensor([[True, False], [True, True]])
    assert torch.isfinite(cost[healthy]).all() and (cost[healthy] < 37.0).all()
    assert (cost[healthy] >= 0).all()
    assert torch.isfinite(out["agents", "observation"]).all()


@pytest.mark.parametrize(
    ("key", "index", "value"),
    [
        (("sim", "truth", "nu"), 4, 6.0),  # finite but absurd: a 6 rad/s pitch rate loops the AUV
        (("sim", "truth", "eta"), 0, -110.0),
    ],  # 110 m outside the area (exit margin 100 m)
)
def test_the_auv_that_ends_the_episode_pays_its_cost_plus_the_termination_cost(key, index, value):
    costs = []
    for termination_cost in (0.0, 37.0):
        env = DataCollectionEnv(
            batch_size=[2], seed=0, num_sensors=10, termination_cost=termination_cost
        )
        td = env.reset()
        td[key][0, 1, index] = value  # scene 0, AUV 1
        td["agents", "action"] = torch.zeros(2, 2, 3)
        out = env.step(td)["next"]
        assert out["terminated"].squeeze(-1).tolist() == [True, False]
        costs.append(out["agents", "cost"].squeeze(-1))
        assert torch.equal(out["agents", "reward"], -out["agents", "cost"])
    # c_j + c_term for that AUV only; the same state otherwise (same seed)
    extra = torch.tensor([[0.0, 37.0], [0.0, 0.0]])
    torch.testing.assert_close(costs[1] - costs[0], extra)
    assert torch.isfinite(costs[0]).all() and (costs[0] >= 0).all()


def test_leaving_the_area_is_a_violation_and_only_100_m_beyond_it_ends_the_episode():
    env = DataCollectionEnv(batch_size=[2], seed=0, num_auvs=1, num_sensors=10)
    td = env.reset()
    td["sim", "truth", "eta"][:, 0, 0] = torch.tensor([-30.0, -98.0])  # outside, within the margin
    td["sim", "truth", "eta"][:, 0, 5] = math.pi  # heading further out (south)
    td["agents", "action"] = torch.zeros(2, 1, 3)
    out = env.step(td)["next"]
    assert not out["terminated"].any()
    assert (out["cost_terms", "violation"][:, 0] == env.cost_weights.violation).all()
    td = out.clone()
    td["agents", "action"] = torch.zeros(2, 1, 3)
    for _ in range(3):  # at 1.5-2 m/s the second one crosses x = -100 m within 3 s
        out = env.step(td)["next"]
        td = out.clone()
        td["agents", "action"] = torch.zeros(2, 1, 3)
        if out["terminated"].any():
            break
    assert out["terminated"].squeeze(-1).tolist() == [False, True]
    assert out["sim", "truth", "eta"][1, 0, 0] < -100.0 < out["sim", "truth", "eta"][0, 0, 0]


def test_reward_is_minus_the_cost_and_the_cost_is_bounded():
    env = DataCollectionEnv(batch_size=[4], sea_state="ves", seed=3)
    td = env.rollout(50, break_when_any_done=False)
    cost, reward = td["next", "agents", "cost"], td["next", "agents", "reward"]
    assert torch.equal(reward, -cost)
    ends = td["next", "agents", "terminated"]
    c_max = env.cost_weights.max_cost()
    assert (cost >= 0).all() and (cost[~ends] <= c_max + 1e-5).all()
    terms = sum(td["next", "cost_terms", k] for k in td["next", "cost_terms"].keys())
    torch.testing.assert_close(terms[~ends[..., 0]], cost[..., 0][~ends[..., 0]])


def test_tracking_errors_leave_out_the_station_keeping_decisions():
    """The heading/depth error metrics average over the physics steps of the decisions whose
    setpoints the policy set: decisions overridden by the station keeper do not count."""
    env = DataCollectionEnv(batch_size=[2], seed=2, rate_model="paper")
    td = env.rollout(120, ScriptedExpert(env), break_when_any_done=False)
    overridden = td["next", "overridden"]
    assert overridden.any() and (~overridden).any()
    steps = td["next", "sim", "tracking", "steps"][:, -1]  # per AUV
    own = (~overridden).sum(1) * 20  # 20 physics steps per decision
    torch.testing.assert_close(steps, own.to(steps.dtype))


def test_time_fraction_counts_against_max_steps():
    env = DataCollectionEnv(batch_size=[1], seed=0, max_steps=50)
    td = env.rollout(5)
    fraction = td["next", "agents", "observation"][..., FEATURE["time_fraction"]]
    torch.testing.assert_close(fraction[0, :, 0], torch.arange(1, 6) / 50.0)


def test_the_asv_follows_the_fleet_centroid_at_2_m_per_s():
    env = DataCollectionEnv(batch_size=[2], seed=0, num_auvs=3, num_sensors=10)
    td = env.reset()
    centroid = td["sim", "truth", "eta"][..., :2].mean(-2)
    td["sim", "asv"][0, :2] = centroid[0] + torch.tensor([60.0, -80.0])  # 100 m away
    td["sim", "asv"][1, :2] = centroid[1]  # on station
    td["agents", "action"] = torch.zeros(2, 3, 3)
    out = env.step(td)["next"]
    new_centroid = out["sim", "truth", "eta"][..., :2].mean(-2)
    # far: 2 m (one 1 s decision at 2 m/s) straight toward the fleet's new centroid
    gap = new_centroid[0] - td["sim", "asv"][0, :2]
    torch.testing.assert_close(
        out["sim", "asv"][0, :2], td["sim", "asv"][0, :2] + 2.0 * gap / gap.norm()
    )
    # near (the fleet moved less than 2 m): on the centroid
    assert (new_centroid[1] - centroid[1]).norm() < 2.0
    torch.testing.assert_close(out["sim", "asv"][1, :2], new_centroid[1])
    assert (out["sim", "asv"][:, 2] == 0).all()  # at the surface


def test_the_ocean_is_as_deep_as_the_scene_mean_seabed():
    """Finite-depth waves (spec v2): each scene's ocean is reset with its terrain's mean depth,
    and its wavenumbers solve omega^2 = g k tanh(k h) there (g = 9.81 m/s^2)."""
    td = DataCollectionEnv(batch_size=[3], sea_state="ves", seed=0).reset()
    depth = td["sim", "task", "terrain", "depth"].mean((-2, -1))
    assert ((depth > 39.0) & (depth < 58.0)).all()
    torch.testing.assert_close(td["sim", "ocean", "water_depth"], depth)
    k, omega = (
        td["sim", "ocean", "wave_number"].double(),
        td["sim", "ocean", "wave_frequency"].double(),
    )
    residual = 9.81 * k * torch.tanh(k * depth.double()[:, None]) - omega**2
    assert residual.abs().max().item() < 1e-5  # float32 state


@pytest.mark.parametrize("batch_size", [[-1], [0], 4, "4", [2.0]])
def test_a_bad_batch_size_is_an_error_naming_it(batch_size):
    with pytest.raises(ValueError, match=r"batch_size must be a list of ints >= 1"):
        DataCollectionEnv(batch_size=batch_size, num_sensors=5)
    with pytest.raises(ValueError, match=r"batch_size must be a list of ints >= 1"):
        AUVTrackingEnv(batch_size=batch_size)


@pytest.mark.parametrize("flatten_agents", [False, True])
@pytest.mark.parametrize(
    ("shape", "expected"),
    [((2, 2, 4), r"\[2, 2, 3\]"), ((2, 2, 2), r"\[2, 2, 3\]"), ((2, 7), r"\[2, 6\]")],
)
def test_an_action_of_the_wrong_shape_is_an_error_naming_the_expected_shape(
    flatten_agents, shape, expected
):
    env = DataCollectionEnv(batch_size=[2], seed=0, num_sensors=5, flatten_agents=flatten_agents)
    if flatten_agents != (len(shape) == 2):
        pytest.skip("a shape of the other layout")
    td = env.reset()
    td[env.agent_action_key] = torch.zeros(shape)
    with pytest.raises(ValueError, match=rf"action.* must have shape {expected}"):
        env.step(td)


@pytest.mark.parametrize("bad", [float("nan"), float("inf")])
def test_a_non_finite_action_is_an_error_not_a_diverged_episode(bad):
    env = DataCollectionEnv(batch_size=[2], seed=0, num_sensors=5)
    td = env.reset()
    action = torch.zeros(2, 2, 3)
    action[1, 0, 2] = bad
    td["agents", "action"] = action
    with pytest.raises(ValueError, match="1 non-finite entries"):
        env.step(td)
    tracking = AUVTrackingEnv(batch_size=[2], seed=0)
    td = tracking.reset()
    td["action"] = torch.full((2, 3), bad)
    with pytest.raises(ValueError, match="6 non-finite entries"):
        tracking.step(td)


def test_an_action_outside_its_bounds_is_clipped_as_the_card_says():
    env = DataCollectionEnv(batch_size=[1], seed=0, num_sensors=5, num_auvs=1)
    td = env.reset()
    outs = []
    for value in (1.0, 7.0):
        td["agents", "action"] = torch.full((1, 1, 3), value)
        outs.append(env.step(td.clone())["next", "sim", "setpoint"])
    torch.testing.assert_close(outs[0], outs[1])


@pytest.mark.parametrize("flatten_agents", [False, True])
def test_reward_key_is_the_reward_and_scaling_it_with_the_cost_keys_keeps_them_one(
    flatten_agents,
):
    from torchrl.envs import RewardScaling, TransformedEnv

    def make():
        return DataCollectionEnv(
            batch_size=[2], seed=0, num_sensors=5, flatten_agents=flatten_agents
        )

    env = make()
    assert env.reward_key == ("reward" if flatten_agents else ("agents", "reward"))
    assert env.reward_keys == [env.reward_key]
    scaled_keys = [env.reward_key, *env.cost_keys]
    scaled = TransformedEnv(make(), RewardScaling(0.0, 0.1, in_keys=scaled_keys))
    torch.manual_seed(0)  # the same random actions in both
    plain = env.rollout(3)
    torch.manual_seed(0)
    small = scaled.rollout(3)
    for key in scaled_keys:
        torch.testing.assert_close(small["next", key], 0.1 * plain["next", key])
    cost = "cost" if flatten_agents else ("agents", "cost")
    torch.testing.assert_close(small["next", env.reward_key], -small["next", cost])


def _wrapped(make):
    """The env behind each TorchRL wrapper a user reaches for."""
    from functools import partial

    from torchrl.envs import ParallelEnv, RewardSum, SerialEnv

    return {
        "plain": make([2]),
        "TransformedEnv": TransformedEnv(make([2]), RewardSum()),
        "SerialEnv": SerialEnv(2, partial(make, [])),
        "ParallelEnv": ParallelEnv(2, partial(make, []), mp_start_method="fork"),
    }


@pytest.mark.parametrize(
    ("name", "reward", "costs"),
    [
        ("agents", ("agents", "reward"), [("agents", "cost"), ("agents", "stability_cost")]),
        ("flat", "reward", ["cost", "stability_cost"]),
        ("tracking", "reward", ["cost"]),
    ],
)
def test_reward_key_through_every_wrapper_and_reward_sum_with_its_defaults(name, reward, costs):
    """Issue [26/26]: ``env.reward_key`` raised on wrapped envs (three reward-like keys); the
    cost keys are observation keys now, 0 at reset."""

    def make(batch):
        if name == "tracking":
            return AUVTrackingEnv(batch_size=batch, seed=0, max_steps=4)
        flat = name == "flat"
        return DataCollectionEnv(
            batch_size=batch, seed=0, num_sensors=5, max_steps=4, flatten_agents=flat
        )

    envs = _wrapped(make)
    try:
        for label, env in envs.items():
            assert env.reward_key == reward, label
            assert env.reward_keys == [reward], label
        data = envs["TransformedEnv"].rollout(3)
        episode = ("agents", "episode_reward") if name == "agents" else "episode_reward"
        torch.testing.assert_close(
            data["next", episode][:, -1], data["next", reward].sum(1)
        )  # RewardSum with its default keys sums the one reward
        for key in costs:
            assert (data[key][:, 0] == 0).all() and (data["next", key] >= 0).all()
            torch.testing.assert_close(data[key][:, 1:], data["next", key][:, :-1])
    finally:
        if not envs["ParallelEnv"].is_closed:
            envs["ParallelEnv"].close()


def test_multi_agent_attributes_as_torchrl_multi_agent_envs_have_them():
    env = DataCollectionEnv(batch_size=[2], seed=0, num_sensors=5, num_auvs=3)
    assert env.n_agents == 3 and env.group_map == {"agents": ["auv_0", "auv_1", "auv_2"]}
    assert TransformedEnv(env).n_agents == 3  # through the wrapper too
    flat = DataCollectionEnv(batch_size=[2], seed=0, num_sensors=5, flatten_agents=True)
    assert flat.group_map == {"agent": ["agent"]}


def test_scene_level_done_flags_only_as_vmas_has_them():
    """``per_agent_done=False``: the layout TorchRL's multi-agent scripts expect (their
    DoneTransform expands scene-level flags over the agents)."""
    env = DataCollectionEnv(batch_size=[2], seed=0, num_sensors=5, per_agent_done=False)
    check_env_specs(env)
    assert sorted(env.done_keys) == ["done", "terminated", "truncated"]
    env.set_seed(0)
    torch.manual_seed(0)  # the same random actions in both
    data = env.rollout(3)
    assert ("agents", "terminated") not in data["next"].keys(True)
    torch.manual_seed(0)
    with_flags = DataCollectionEnv(batch_size=[2], seed=0, num_sensors=5).rollout(3)
    torch.testing.assert_close(data["next", "agents", "cost"], with_flags["next", "agents", "cost"])
