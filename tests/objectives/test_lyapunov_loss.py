"""LyapunovActorCriticLoss: TorchRL loss hygiene, dual dynamics, spec switching, bad input."""

from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import NormalParamExtractor, TensorDictModule
from torch import nn
from torchrl.modules import MLP, ProbabilisticActor, TanhNormal, ValueOperator
from torchrl.objectives import SoftUpdate

from torchrl_auv.objectives import LyapunovActorCriticLoss, LyapunovSpec

OBS, ACT = 3, 2


def _actor():
    net = nn.Sequential(
        MLP(in_features=OBS, out_features=2 * ACT, num_cells=[32]), NormalParamExtractor()
    )
    module = TensorDictModule(net, in_keys=["observation"], out_keys=["loc", "scale"])
    return ProbabilisticActor(
        module,
        in_keys=["loc", "scale"],
        distribution_class=TanhNormal,
        distribution_kwargs={"low": -1.0, "high": 1.0},
        return_log_prob=True,
    )


def _critic(out=16):
    return ValueOperator(
        MLP(in_features=OBS + ACT, out_features=out, num_cells=[32]),
        in_keys=["observation", "action"],
    )


def _batch(n=64, cost=0.5, seed=0):
    g = torch.Generator().manual_seed(seed)
    return TensorDict(
        {
            "observation": torch.randn(n, OBS, generator=g),
            "action": torch.rand(n, ACT, generator=g) * 2 - 1,
            "next": {
                "observation": torch.randn(n, OBS, generator=g),
                "reward": torch.full((n, 1), -cost),
                "cost": torch.full((n, 1), cost),
                "done": torch.zeros(n, 1, dtype=torch.bool),
                "terminated": torch.zeros(n, 1, dtype=torch.bool),
            },
        },
        batch_size=[n],
    )


def _loss(**kwargs):
    torch.manual_seed(0)
    return LyapunovActorCriticLoss(
        _actor(), _critic(), form=kwargs.pop("form", "squared"), **kwargs
    )


def test_output_keys_and_only_four_loss_terms():
    out = _loss()(_batch())
    assert sorted(k for k in out.keys() if k.startswith("loss")) == [
        "loss_actor",
        "loss_beta",
        "loss_lambda",
        "loss_lyapunov",
    ]
    for key in ("lambda", "beta", "delta_l", "violation_rate"):
        assert key in out.keys() and not out[key].requires_grad


def _grad_owners(loss, name):
    loss.zero_grad(set_to_none=True)
    torch.manual_seed(1)
    loss(_batch())[name].backward()
    owners = set()
    for param_name, p in loss.named_parameters():
        if p.grad is not None and p.grad.abs().sum() > 0:
            owners.add(param_name.split(".")[0])
    return owners


@pytest.mark.parametrize("mode", ["lac", "paper"])
def test_each_loss_term_sends_gradient_only_to_its_own_parameters(mode):
    loss = _loss(mode=mode)
    assert _grad_owners(loss, "loss_actor") == {"actor_network_params"}
    assert _grad_owners(loss, "loss_lyapunov") == {"lyapunov_network_params"}
    assert _grad_owners(loss, "loss_lambda") == {"log_lambda"}
    assert _grad_owners(loss, "loss_beta") == {"log_beta"}


def test_the_input_is_not_modified_and_set_keys_renames_work():
    loss = _loss()
    data = _batch()
    before = data.clone()
    torch.manual_seed(3)
    reference = loss(data)
    assert (data == before).all() and set(data.keys(True)) == set(before.keys(True))
    renamed = data.clone()
    renamed.rename_key_(("next", "cost"), ("next", "penalty"))
    loss.set_keys(cost="penalty")
    torch.manual_seed(3)
    again = loss(renamed)
    for key in ("loss_actor", "loss_lyapunov", "loss_lambda", "loss_beta"):
        torch.testing.assert_close(again[key], reference[key])


def test_without_a_cost_key_the_cost_is_minus_the_reward():
    loss = _loss()
    data = _batch(cost=0.3)
    no_cost = data.exclude(("next", "cost"))
    torch.manual_seed(4)
    a = loss(data)
    torch.manual_seed(4)
    b = loss(no_cost)
    torch.testing.assert_close(a["loss_lyapunov"], b["loss_lyapunov"])
    negative = _batch(cost=-0.3)
    assert loss(negative)["negative_cost_fraction"] == 1.0  # reported, not hidden


def test_soft_update_finds_and_moves_the_target_parameters():
    loss = _loss()
    updater = SoftUpdate(loss, tau=0.5)
    target = loss.target_lyapunov_network_params.clone()
    with torch.no_grad():
        for p in loss.lyapunov_network_params.values(True, True):
            p.add_(1.0)
    updater.step()
    moved = loss.target_lyapunov_network_params
    for key in target.keys(True, True):
        torch.testing.assert_close(moved[key], target[key] + 0.5)


def test_the_users_actor_is_trained_in_place():
    actor = _actor()
    loss = LyapunovActorCriticLoss(actor, _critic())
    probe = TensorDict({"observation": torch.randn(8, OBS)}, batch_size=[8])
    before = actor(probe.clone())["loc"].detach()
    optim = torch.optim.Adam(loss.parameters(), lr=1e-2)
    for _ in range(5):
        out = loss(_batch())
        total = sum(v for k, v in out.items() if k.startswith("loss"))
        optim.zero_grad()
        total.backward()
        optim.step()
    assert not torch.allclose(actor(probe.clone())["loc"], before)


def _optimise_lambda(loss, data, steps=200):
    optim = torch.optim.Adam([loss.log_lambda], lr=0.05)
    for _ in range(steps):
        optim.zero_grad()
        loss(data)["loss_lambda"].backward()
        optim.step()
    return loss.lambda_.item()


def test_dual_ascent_raises_lambda_when_the_condition_is_violated_and_lowers_it_otherwise():
    violated = _loss(lambda_init=0.2, lambda_max=1.0, stability_weight=0.5)
    data = _batch(cost=50.0)  # alpha * c dominates: DeltaL > 0
    assert violated(data)["delta_l"] > 0
    assert _optimise_lambda(violated, data) == pytest.approx(1.0)  # up to its clamp
    satisfied = _loss(lambda_init=0.5, stability_weight=0.05)
    with torch.no_grad():  # L depends on the action only: large at the stored a = 0.99,
        first = satisfied.lyapunov_network_params["module", "0", "weight"]  # small at pi(s')
        first[:, :OBS] = 0.0
        first[:, OBS:] = 3.0
    data = _batch(cost=0.0)
    data["action"] = torch.full_like(data["action"], 0.99)
    assert satisfied(data)["delta_l"] < 0
    start = satisfied.lambda_.item()
    assert _optimise_lambda(satisfied, data, steps=50) < 0.5 * start


def test_the_multiplier_does_not_wind_up_above_its_cap():
    """Dual ascent while the condition is violated must not push log_lambda past
    log(lambda_max): once the condition holds, lambda comes off its cap within a few steps
    (as TorchRL's SACLoss clamps log_alpha in place)."""
    loss = _loss(lambda_init=0.2, lambda_max=1.0, stability_weight=0.5)
    assert _optimise_lambda(loss, _batch(cost=50.0), steps=300) == pytest.approx(1.0)
    loss(_batch(cost=50.0))  # a forward after the last step: the stored value is back at its cap
    assert loss.log_lambda.item() <= 1e-6
    with torch.no_grad():  # now the condition holds (the critic of the test above)
        first = loss.lyapunov_network_params["module", "0", "weight"]
        first[:, :OBS] = 0.0
        first[:, OBS:] = 3.0
    data = _batch(cost=0.0)
    data["action"] = torch.full_like(data["action"], 0.99)
    assert loss(data)["delta_l"] < 0
    assert _optimise_lambda(loss, data, steps=3) < 1.0


def test_switching_the_spec_keeps_the_duals_and_the_optimiser():
    loss = _loss(lambda_init=0.7, beta_init=0.3)
    optim = torch.optim.Adam(loss.parameters(), lr=1e-3)
    out = loss(_batch())
    sum(v for k, v in out.items() if k.startswith("loss")).backward()
    optim.step()
    lam, beta, state = loss.lambda_.item(), loss.beta.item(), optim.state_dict()
    loss.set_lyapunov_spec(LyapunovSpec(form="log", alpha=0.3, prior="position"))
    assert loss.lambda_.item() == lam and loss.beta.item() == beta
    assert loss.spec.form == "log" and loss.spec.alpha == 0.3
    assert optim.state_dict()["state"].keys() == state["state"].keys()
    out = loss(_batch())  # the new form is used at once
    assert torch.isfinite(out["loss_lyapunov"])


@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"form": "cubic"}, "form"),
        ({"mode": "hybrid"}, "mode"),
        ({"stability_weight": 0.0}, "stability_weight"),
        ({"lambda_max": 0.0}, "lambda_max"),
        ({"beta_init": -1.0}, "beta_init"),
    ],
)
def test_bad_input_names_the_argument(kwargs, argument):
    with pytest.raises(ValueError, match=argument):
        _loss(**kwargs)


def test_missing_keys_are_named():
    loss = _loss()
    with pytest.raises(ValueError, match="terminated"):
        loss(_batch().exclude(("next", "terminated")))
    with pytest.raises(ValueError, match="cost"):
        loss(_batch().exclude(("next", "cost"), ("next", "reward")))


def test_a_cost_key_set_with_set_keys_must_be_in_the_data():
    """A typo in ``set_keys(cost=...)`` used to fall back to ``-reward`` without a word."""
    loss = _loss()
    loss.set_keys(cost="costt")
    with pytest.raises(ValueError, match=r"cost key 'costt' \(set with set_keys\).*'next'"):
        loss(_batch())
    default = _loss()  # the default key absent: -reward, as documented (e.g. Pendulum)
    without_cost = default(_batch().exclude(("next", "cost")))
    torch.testing.assert_close(without_cost["loss_lyapunov"], _loss()(_batch())["loss_lyapunov"])


def test_a_critic_that_does_not_write_the_value_key_names_both_keys():
    critic = ValueOperator(
        MLP(in_features=OBS + ACT, out_features=16, num_cells=[32]),
        in_keys=["observation", "action"],
        out_keys=["lyapunov"],
    )
    loss = LyapunovActorCriticLoss(_actor(), critic, form="squared")
    with pytest.raises(ValueError, match=r"'value' key 'state_action_value'.*\['lyapunov'\]"):
        loss(_batch())
    loss.set_keys(value="lyapunov")
    assert torch.isfinite(loss(_batch())["loss_lyapunov"])


def test_multi_agent_keys_via_set_keys():
    n_agents = 2
    net = nn.Sequential(
        MLP(in_features=OBS, out_features=2 * ACT, num_cells=[32]), NormalParamExtractor()
    )
    actor = ProbabilisticActor(
        TensorDictModule(
            net,
            in_keys=[("agents", "observation")],
            out_keys=[("agents", "loc"), ("agents", "scale")],
        ),
        in_keys={"loc": ("agents", "loc"), "scale": ("agents", "scale")},
        out_keys=[("agents", "action")],
        distribution_class=TanhNormal,
        distribution_kwargs={"low": -1.0, "high": 1.0},
    )
    critic = ValueOperator(
        MLP(in_features=OBS + ACT, out_features=16, num_cells=[32]),
        in_keys=[("agents", "observation"), ("agents", "action")],
        out_keys=[("agents", "state_action_value")],
    )
    loss = LyapunovActorCriticLoss(actor, critic, form="squared")
    loss.set_keys(
        action=("agents", "action"),
        reward=("agents", "reward"),
        cost=("agents", "cost"),
        terminated=("agents", "terminated"),
        done=("agents", "done"),
        value=("agents", "state_action_value"),
        observation=("agents", "observation"),
    )
    b = 8
    agents = lambda **kw: TensorDict(kw, batch_size=[b, n_agents])  # noqa: E731
    data = TensorDict(
        {
            "agents": agents(
                observation=torch.randn(b, n_agents, OBS),
                action=torch.rand(b, n_agents, ACT) * 2 - 1,
            ),
            "next": {
                "agents": agents(
                    observation=torch.randn(b, n_agents, OBS),
                    reward=-torch.rand(b, n_agents, 1),
                    cost=torch.rand(b, n_agents, 1),
                    terminated=torch.zeros(b, n_agents, 1, dtype=torch.bool),
                    done=torch.zeros(b, n_agents, 1, dtype=torch.bool),
                )
            },
        },
        batch_size=[b],
    )
    out = loss(data)
    for key in ("loss_actor", "loss_lyapunov", "loss_lambda", "loss_beta"):
        assert out[key].shape == () and torch.isfinite(out[key]), key
    sum(v for k, v in out.items() if k.startswith("loss")).backward()
    assert all(p.grad is not None for p in loss.actor_network_params.values(True, True))
