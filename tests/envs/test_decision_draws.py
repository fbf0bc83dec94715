"""A decision's random numbers drawn ahead (what lets its code after the draws compile as
pure tensor code) are the numbers the generator would have drawn during it: every function
that takes them gives, from draws made as documented, what it gives from the generator."""

import pytest
import torch
from tensordict import TensorDict

from torchrl_auv.control import make_controller
from torchrl_auv.envs import DataCollectionEnv
from torchrl_auv.envs.vehicles import VehicleStack
from torchrl_auv.estimation import asv_draws, asv_fixes, usbl_fix
from torchrl_auv.iout.nodes import data_arrivals
from torchrl_auv.physics import ocean


def _same(a, b):
    for x, y in zip(a, b, strict=True):
        if isinstance(x, torch.Tensor):
            assert torch.equal(x, y)
        else:
            assert set(x.keys(True, True)) == set(y.keys(True, True))
            for key in x.keys(True, True):
                assert torch.equal(x[key], y[key]), key


def test_usbl_fix_from_given_draws_equals_the_generators():
    position = torch.tensor([[30.0, 40.0, 20.0], [-5.0, 80.0, 60.0]])
    asv = torch.zeros(2, 3)
    args = (position, asv, 0.01, 0.02)
    own = usbl_fix(*args, torch.Generator().manual_seed(4), dropout=0.3)
    g = torch.Generator().manual_seed(4)
    normal, uniform = torch.randn((3, 2), generator=g), torch.rand(2, generator=g)
    given = usbl_fix(*args, None, dropout=0.3, standard_normal=normal, uniform=uniform)
    _same(own, given)
    with pytest.raises(ValueError, match="together"):
        usbl_fix(*args, None, standard_normal=normal)
    with pytest.raises(ValueError, match=r"standard_normal must be shaped \(3, 2\)"):
        usbl_fix(*args, None, standard_normal=normal[:, :1], uniform=uniform)


def test_asv_fixes_from_asv_draws_equal_the_generators():
    sea = ocean.get_sea_state("ves")
    auvs = torch.tensor([[[30.0, 40.0, 20.0], [60.0, 10.0, 35.0]]])
    gnss, start = torch.tensor([[0.5, -1.0]]), torch.zeros(1, 3)
    own = asv_fixes(start, gnss, auvs, sea, 1.0, torch.Generator().manual_seed(9))
    draws = asv_draws(gnss, auvs, torch.Generator().manual_seed(9))
    assert draws["usbl"].shape == (3, 1, 2) and draws["dropout"].shape == (1, 2)
    _same(own, asv_fixes(start, gnss, auvs, sea, 1.0, None, draws=draws))
    with pytest.raises(ValueError, match=r"generator must be a torch\.Generator"):
        asv_fixes(start, gnss, auvs, sea, 1.0, None)


def test_data_arrivals_from_given_arrivals_equal_the_generators():
    buffer, rate = torch.tensor([[0.0, 4990.0, 100.0]]), torch.tensor([[3.0, 50.0, 0.0]])
    own = data_arrivals(buffer, rate, 5000, generator=torch.Generator().manual_seed(2))
    drawn = torch.poisson(rate.expand_as(buffer), generator=torch.Generator().manual_seed(2))
    _same(own, data_arrivals(buffer, rate, 5000, generator=None, arrivals=drawn))
    with pytest.raises(ValueError, match="arrivals must be shaped like buffer"):
        data_arrivals(buffer, rate, 5000, generator=None, arrivals=drawn[..., :2])


def test_decide_from_draw_noise_equals_the_generators():
    sea = ocean.get_sea_state("es")
    stack = VehicleStack(sea, make_controller("s_surface"), decision_steps=4, unroll=2)
    eta = torch.tensor([[0.0, 0.0, 10.0, 0.0, 0.0, 0.3], [5.0, 5.0, 20.0, 0.0, 0.0, -1.0]])
    nu = torch.zeros(2, 6)
    nu[:, 0] = 1.5
    vehicles = stack.init(eta, nu, torch.zeros(2, 3))
    sea_td = ocean.reset_ocean(sea, (2,), generator=torch.Generator().manual_seed(0))
    setpoint = torch.tensor([[12.0, 0.5, 1200.0], [18.0, -0.5, 1000.0]])
    own = stack.decide(vehicles, setpoint, sea_td, 50.0, generator=torch.Generator().manual_seed(1))
    noise = stack.draw_noise((2,), (2,), torch.Generator().manual_seed(1))
    _same(own, stack.decide(vehicles, setpoint, sea_td, 50.0, generator=None, noise=noise))
    with pytest.raises(ValueError, match="draw_noise"):
        stack.decide(vehicles, setpoint, sea_td, 50.0, generator=None, noise=(noise[0], noise[0]))


@pytest.mark.parametrize("flatten", [False, True])
def test_a_decision_after_its_draws_is_pure_and_repeatable(flatten):
    """The env's decision draws every random number first (:meth:`_decision_draws`, nothing
    more), and the code after the draws gives the step's own result from them."""
    env = DataCollectionEnv(batch_size=[2], sea_state="ves", seed=3, flatten_agents=flatten)
    td = env.rand_action(env.reset())
    state = td.select(*env._state_keys)
    sim = state["sim"]
    start = env.rng.get_state()
    draws = env._decision_draws(sim)
    after_draws = env.rng.get_state()
    env.rng.set_state(start)
    first = env._simulate_step(td.clone())
    assert torch.equal(env.rng.get_state(), after_draws)  # the step drew its draws, no more
    # the drawn arrivals reach the buffers (no service ends in a scene's first decision)
    assert not sim["task", "auvs", "in_service"].any()
    filled = sim["task", "nodes", "buffer"] + draws["arrivals"]
    want = filled.clamp(max=env.config.buffer_capacity)
    assert draws["arrivals"].sum() > 0 and torch.equal(
        first["sim", "task", "nodes", "buffer"], want
    )
    setpoint, seabed = env._before_physics(sim, env._agent_action(td))
    fleet = TensorDict({k: sim[k] for k in ("truth", "kf", "controller")}, batch_size=(2, 2))
    vehicles, sea_td, decision = env.vehicles.decide(
        fleet, setpoint, sim["ocean"], seabed, generator=None, noise=draws["vehicles"]
    )
    again = env._after_physics(state, setpoint, vehicles, sea_td, decision, draws)
    assert set(first.keys(True, True)) == set(again.keys(True, True))
    for key in first.keys(True, True):
        assert torch.equal(first[key], again[key]), key
