"""DataCollectionEnv: specs, layouts, determinism, bounds, metrics, expert, bad input;
divergence and termination cost, loitering in service, the ASV."""

from __future__ import annotations

import math

import pytest
import torch
from torchrl.envs import TransformedEnv
from torchrl.envs.utils import check_env_specs

from torchrl_auv.envs import DataCollectionEnv, ScriptedExpert, StateActionHistory
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
)


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


def test_same_seed_same_rollout_different_seed_differs():
    def rollout(seed):
        env = DataCollectionEnv(batch_size=[2], sea_state="ves", seed=seed)
        return env.rollout(4, ScriptedExpert(env))

    a, b, c = rollout(3), rollout(3), rollout(4)
    assert (a == b).all()
    assert not torch.equal(a["next", "truth", "eta"], c["next", "truth", "eta"])
    assert not torch.equal(a["task", "nodes", "position"], c["task", "nodes", "position"])


def test_observation_is_the_estimate_not_the_truth():
    env = DataCollectionEnv(batch_size=[2], sea_state="es", seed=0)
    td = env.rollout(5)
    estimate, truth = td["next", "kf", "mean"][..., :3], td["next", "truth", "eta"][..., :3]
    assert not torch.equal(estimate, truth)
    assert (estimate - truth).abs().max() < 2.0
    # the depth feature (index 10) is the estimate's depth over the deepest seabed
    depth = td["next", "agents", "observation"][..., 10] * env.config.seabed_depth_range_m[1]
    torch.testing.assert_close(depth, estimate[..., 2], rtol=1e-5, atol=1e-4)


def test_hovering_auvs_loiter_at_the_slowest_propeller_speed():
    env = DataCollectionEnv(batch_size=[4], seed=2, rate_model="paper")
    td = env.rollout(150, ScriptedExpert(env), break_when_any_done=False)
    hovering = td["task", "auvs", "in_service"]  # in service during this decision
    assert hovering.any(), "the expert should start some services in 150 s"
    rpm_sp = td["next", "setpoint"][..., 2]
    assert (rpm_sp[hovering] == 760.0).all()
    completed = td["next", "metrics", "ssn"][:, -1]
    assert (completed >= 1).any()


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
    td["truth", "eta"][..., 0] = -0.5  # already outside: the first step ends the episode
    td["agents", "action"] = torch.zeros(1, 1, 3)
    out = env.step(td)["next"]
    assert out["terminated"].all() and not out["truncated"].any()
    assert out["agents", "cost"].item() >= env.termination_cost


def test_history_transform_on_the_multi_agent_env():
    env = TransformedEnv(
        DataCollectionEnv(batch_size=[2], seed=0),
        StateActionHistory(
            10, observation_key=("agents", "observation"), action_key=("agents", "action")
        ),
    )
    check_env_specs(env, seed=0)
    td = env.rollout(3)
    assert td["agents", "history", "observation"].shape == (2, 3, 2, 10, 31)
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
    eta, nu = td["next", "truth", "eta"], td["next", "truth", "nu"]
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
        ({"areas": (1.0, 1.0)}, "areas"),
    ],
)
def test_bad_input_names_the_argument(kwargs, argument):
    with pytest.raises(ValueError, match=argument):
        DataCollectionEnv(batch_size=[1], **kwargs)


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
    assert (final["collisions"] <= 10).all()


# -- divergence, loitering, the ASV ------------------------------------------------------------
@pytest.mark.parametrize(
    ("key", "index", "value"),
    [(("truth", "eta"), 0, float("nan")), (("truth", "eta"), 1, float("nan")),
     (("truth", "nu"), 0, float("inf")), (("truth", "actuators"), 2, float("nan"))],
)  # fmt: skip
def test_a_non_finite_auv_terminates_its_scene_and_pays_the_termination_cost(key, index, value):
    env = DataCollectionEnv(batch_size=[2], seed=0, num_sensors=10, termination_cost=37.0)
    td = env.reset()
    td[key][0, 1, index] = value  # scene 0, AUV 1
    td["agents", "action"] = torch.zeros(2, 2, 3)
    out = env.step(td)["next"]
    assert out["terminated"].squeeze(-1).tolist() == [True, False]
    assert out["done"].squeeze(-1).tolist() == [True, False]
    assert not out["truncated"].any()
    # the scene's flag for every AUV
    assert out["agents", "terminated"].squeeze(-1).tolist() == [[True, True], [False, False]]
    cost, reward = out["agents", "cost"].squeeze(-1), out["agents", "reward"].squeeze(-1)
    # the AUV that ends the episode: its own terms are undefined (NaN pose), c_term alone
    assert cost[0, 1].item() == 37.0 and reward[0, 1].item() == -37.0
    # the others do not pay it and stay finite
    healthy = torch.tensor([[True, False], [True, True]])
    assert torch.isfinite(cost[healthy]).all() and (cost[healthy] < 37.0).all()
    assert (cost[healthy] >= 0).all()
    assert torch.isfinite(out["agents", "observation"]).all()


@pytest.mark.parametrize(
    ("key", "index", "value"),
    [(("truth", "nu"), 4, 6.0),  # finite but absurd: a 6 rad/s pitch rate loops the AUV
     (("truth", "eta"), 0, -60.0)],  # 60 m outside the area (exit margin 50 m)
)  # fmt: skip
def test_the_auv_that_ends_the_episode_pays_its_cost_plus_the_termination_cost(key, index, value):
    costs, rewards = [], []
    for termination_cost in (0.0, 37.0):
        env = DataCollectionEnv(batch_size=[2], seed=0, num_sensors=10,
                                termination_cost=termination_cost)  # fmt: skip
        td = env.reset()
        td[key][0, 1, index] = value  # scene 0, AUV 1
        td["agents", "action"] = torch.zeros(2, 2, 3)
        out = env.step(td)["next"]
        assert out["terminated"].squeeze(-1).tolist() == [True, False]
        costs.append(out["agents", "cost"].squeeze(-1))
        rewards.append(out["agents", "reward"].squeeze(-1))
    # c_j + c_term for that AUV only; the same state otherwise (same seed)
    extra = torch.tensor([[0.0, 37.0], [0.0, 0.0]])
    torch.testing.assert_close(costs[1] - costs[0], extra)
    torch.testing.assert_close(rewards[1] - rewards[0], -extra)
    assert torch.isfinite(costs[0]).all() and (costs[0] >= 0).all()


def _in_service(env, positions, headings):
    """A reset state with every AUV (num_auvs=1) in service at ``positions`` (x, y), heading
    ``headings`` (rad); the compass reads 0.02 rad more, the last heading setpoint is 0.3 rad
    more."""
    td = env.reset()
    batch = len(headings)
    xy, psi = torch.tensor(positions), torch.tensor(headings)
    td["truth", "eta"][..., 0, :2] = xy
    td["truth", "eta"][..., 0, 5] = psi
    td["kf", "mean"][..., 0, :2] = xy
    td["kf", "heading"][..., 0] = psi + 0.02
    td["setpoint"][..., 0, 1] = psi + 0.3
    td["task", "auvs", "in_service"][:] = True
    td["task", "auvs", "service_remaining"][:] = 100.0
    td["agents", "action"] = torch.full((batch, 1, 3), 0.7)  # overridden while in service
    return td


def test_a_serving_auv_loiters_toward_the_area_centre_with_the_heading_lead():
    """Card: at 760 rpm, heading setpoint = compass heading + 0.5 rad toward the side of the
    area's centre (+1 starboard: heading increasing in NED), depth setpoint held."""
    env = DataCollectionEnv(batch_size=[4], seed=0, num_auvs=1, num_sensors=10)
    # the 200 m x 200 m area's centre is (100, 100); starboard of heading psi is
    # (-sin psi, cos psi): north-bound at y=20 the centre is to starboard, at y=180 to port
    positions = [[100.0, 20.0], [100.0, 180.0], [100.0, 20.0], [180.0, 100.0]]
    headings = [0.0, 0.0, math.pi, math.pi / 2]
    expected = torch.tensor([1.0, -1.0, -1.0, 1.0])
    td = _in_service(env, positions, headings)
    depth_sp = td["setpoint"][..., 0, 0].clone()
    out = env.step(td)["next"]
    assert out["loiter_turn"][:, 0].tolist() == expected.tolist()
    sp = out["setpoint"][:, 0]
    torch.testing.assert_close(sp[:, 1], torch.tensor(headings) + 0.02 + 0.5 * expected)
    assert (sp[:, 2] == 760.0).all()
    torch.testing.assert_close(sp[:, 0], depth_sp)
    # the vehicle does turn that way: the heading moves with the sign of the turn
    turned = out["truth", "eta"][:, 0, 5] - torch.tensor(headings)
    assert (torch.atan2(torch.sin(turned), torch.cos(turned)) * expected > 0.02).all()


def test_the_loiter_turn_is_kept_during_a_service_and_zero_outside():
    env = DataCollectionEnv(batch_size=[2], seed=0, num_auvs=1, num_sensors=10)
    td = _in_service(env, [[100.0, 20.0], [100.0, 20.0]], [0.0, 0.0])  # geometry says +1
    td["loiter_turn"][:, 0] = torch.tensor([-1.0, 1.0])  # chosen when the service started
    td["task", "auvs", "in_service"][1] = False
    out = env.step(td)["next"]
    assert out["loiter_turn"][:, 0].tolist() == [-1.0, 0.0]
    torch.testing.assert_close(out["setpoint"][0, 0, 1], torch.tensor(0.02 - 0.5))
    # not in service: the card's action mapping, 0.7 -> z + 0.56 m, psi + 0.105 rad, 1406 rpm
    want = td["setpoint"][1, 0] + torch.tensor([0.8 * 0.7, 0.15 * 0.7, 0.0])
    want[2] = 380.0 * 3.7
    torch.testing.assert_close(out["setpoint"][1, 0], want)


def test_the_asv_follows_the_fleet_centroid_at_2_m_per_s():
    env = DataCollectionEnv(batch_size=[2], seed=0, num_auvs=3, num_sensors=10)
    td = env.reset()
    centroid = td["truth", "eta"][..., :2].mean(-2)
    td["asv"][0, :2] = centroid[0] + torch.tensor([60.0, -80.0])  # 100 m away
    td["asv"][1, :2] = centroid[1]  # on station
    td["agents", "action"] = torch.zeros(2, 3, 3)
    out = env.step(td)["next"]
    new_centroid = out["truth", "eta"][..., :2].mean(-2)
    # far: 2 m (one 1 s decision at 2 m/s) straight toward the fleet's new centroid
    gap = new_centroid[0] - td["asv"][0, :2]
    torch.testing.assert_close(out["asv"][0, :2], td["asv"][0, :2] + 2.0 * gap / gap.norm())
    # near (the fleet moved less than 2 m): on the centroid
    assert (new_centroid[1] - centroid[1]).norm() < 2.0
    torch.testing.assert_close(out["asv"][1, :2], new_centroid[1])
    assert (out["asv"][:, 2] == 0).all()  # at the surface
