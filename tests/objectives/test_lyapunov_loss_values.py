"""LyapunovActorCriticLoss values against a hand calculation.

The actor is a Dirac policy at a linear function of the observation (``a = A o + a0``) with a
known log-density, and the critic is one linear layer with weights set here, so every loss term
of the module docstring (paper eqs. 20-28, LAC) can be written out in plain torch in the test:
the critic target with the discount, the terminated mask and the *target* network, the decrease
:math:`\\Delta L` in both modes, the actor's :math:`\\lambda \\Delta L + \\beta \\log\\pi`, and the
two dual losses, for every form and prior; with a task Q critic (``qvalue_network``) its TD
loss and the actor's ``Q(s, pi(s))``; and the module docstring's derivation: with a critic
equal to the true discounted cost-to-go, the decrease term is ``(1 - gamma) L(s') - (1 - alpha)
c``, positive for a cost that does not vanish, non-positive along a trajectory whose cost falls
to zero at the goal.
"""

from __future__ import annotations

from typing import ClassVar

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torch import nn
from torchrl.data import Bounded
from torchrl.modules import ProbabilisticActor, ValueOperator

from torchrl_auv.objectives import LyapunovActorCriticLoss, LyapunovSpec

OBS, ACT, RAW, N = 3, 2, 2, 6
LOG_PROB_SHIFT = -1.25


class _Dirac(torch.distributions.Distribution):
    """All mass at ``loc``; ``log_prob(x) = -0.5 |x|^2 + LOG_PROB_SHIFT`` (a known function of
    the action, so that the entropy terms have a value the test can compute)."""

    has_rsample = True
    arg_constraints: ClassVar[dict] = {}

    def __init__(self, loc: torch.Tensor) -> None:
        self.loc = loc
        super().__init__(
            batch_shape=loc.shape[:-1], event_shape=loc.shape[-1:], validate_args=False
        )

    def rsample(self, sample_shape=()) -> torch.Tensor:
        return self.loc.expand(*sample_shape, *self.loc.shape)

    def log_prob(self, value: torch.Tensor) -> torch.Tensor:
        return -0.5 * value.square().sum(-1) + LOG_PROB_SHIFT

    @property
    def deterministic_sample(self) -> torch.Tensor:
        return self.loc


class _Affine(nn.Module):
    """``W [o, a] + b`` on the concatenated inputs."""

    def __init__(self, weight: torch.Tensor, bias: torch.Tensor) -> None:
        super().__init__()
        self.weight = nn.Parameter(weight.clone())
        self.bias = nn.Parameter(bias.clone())

    def forward(self, *inputs: torch.Tensor) -> torch.Tensor:
        return torch.cat(inputs, -1) @ self.weight.T + self.bias


# the numbers of the hand calculation (chosen, not read off the code)
A = torch.tensor([[0.5, -0.3, 0.2], [0.1, 0.4, -0.6]])
A0 = torch.tensor([0.05, -0.1])
W = torch.tensor([[0.3, -0.2, 0.1, 0.6, -0.4], [-0.5, 0.25, 0.35, -0.15, 0.45]])
B = torch.tensor([0.2, -0.1])
W_TARGET = W + 0.3  # the target network differs from the online one
B_TARGET = B - 0.2
PRIOR_INDICES = {"position": (0,), "velocity": (1, 2)}


def _modules():
    actor = ProbabilisticActor(
        TensorDictModule(_Affine(A, A0), in_keys=["observation"], out_keys=["loc"]),
        in_keys=["loc"],
        distribution_class=_Dirac,
        return_log_prob=True,
    )
    critic = ValueOperator(_Affine(W, B), in_keys=["observation", "action"])
    return actor, critic


def _data():
    g = torch.Generator().manual_seed(0)
    cost = torch.rand(N, 1, generator=g) * 2
    terminated = torch.zeros(N, 1, dtype=torch.bool)
    terminated[[1, 4]] = True
    return TensorDict(
        {
            "observation": torch.randn(N, OBS, generator=g),
            "action": torch.rand(N, ACT, generator=g) * 2 - 1,
            "next": {
                "observation": torch.randn(N, OBS, generator=g),
                "cost": cost,
                "reward": torch.zeros(N, 1),  # not -cost: the cost key must be the one read
                "done": terminated.clone(),
                "terminated": terminated,
            },
        },
        batch_size=[N],
    )


def _hand_l(obs, action, spec, weight=W, bias=B):
    """The Lyapunov value by hand: the form of the affine critic plus the prior."""
    raw = torch.cat([obs, action], -1) @ weight.T + bias
    if spec.form == "softplus":
        value = torch.log(1 + torch.exp(raw[:, :1]))
    elif spec.form == "squared":
        value = (raw**2).sum(-1, keepdim=True)
    else:
        value = torch.log(1 + (raw**2).sum(-1, keepdim=True))
    if spec.prior is not None:
        index = list(PRIOR_INDICES[spec.prior])
        value = value + spec.prior_weight * (obs[:, index] ** 2).sum(-1, keepdim=True)
    return value


def _expected(data, spec, *, mode, gamma, lam, beta, target_entropy, legs=False, constraint="mean"):
    """Every term by hand. ``legs``: the data's ``approach`` and ``service_start`` flags
    select the transitions (masked means) and make ``L(s') = 0`` at the equilibrium."""
    obs, action, nobs = data["observation"], data["action"], data["next", "observation"]
    cost, term = data["next", "cost"], data["next", "terminated"].float()
    ones = torch.ones_like(cost)
    on = data["next", "approach"].float() if legs else ones
    eq = data["next", "service_start"].float() if legs else 0 * ones
    policy = lambda o: o @ A.T + A0  # noqa: E731  (the Dirac actor)
    log_pi = -0.5 * (policy(obs) ** 2).sum(-1) + LOG_PROB_SHIFT
    value = _hand_l(obs, action, spec)
    next_target = _hand_l(nobs, policy(nobs), spec, W_TARGET, B_TARGET)
    target = cost + gamma * (1 - term) * (1 - eq) * next_target
    if mode == "lac":  # L is 0 after an episode's end and at the equilibrium
        after = (1 - term) * (1 - eq) * _hand_l(nobs, policy(nobs), spec)
    else:
        after = _hand_l(obs, policy(obs), spec)
    delta = after - value + spec.alpha * cost

    def masked(x):
        return (x * on).sum() / on.sum()

    owed = masked(delta) if constraint == "mean" else masked(delta.clamp_min(0))
    return {
        "loss_lyapunov": masked(0.5 * (value - target) ** 2),
        "delta_l": masked(delta),
        "violation_rate": masked((delta > 0).float()),
        "lyapunov_value": masked(value),
        "loss_actor": lam * owed + beta * log_pi.mean(),
        "loss_lambda": -torch.log(torch.tensor(lam)) * masked(delta),
        "loss_beta": -torch.log(torch.tensor(beta)) * (log_pi + target_entropy).mean(),
    }


def _loss(spec, mode, **kwargs):
    actor, critic = _modules()
    loss = LyapunovActorCriticLoss(
        actor,
        critic,
        spec=spec,
        mode=mode,
        lambda_init=0.7,
        lambda_max=1.0,
        beta_init=0.3,
        **kwargs,
    )
    with torch.no_grad():
        loss.target_lyapunov_network_params["module", "weight"].copy_(W_TARGET)
        loss.target_lyapunov_network_params["module", "bias"].copy_(B_TARGET)
    return loss


def _check(out, expected):
    for key, value in expected.items():
        torch.testing.assert_close(
            out[key],
            value.to(out[key].dtype),
            rtol=1e-5,
            atol=1e-6,
            msg=lambda m, key=key: f"{key}: {m}",
        )


@pytest.mark.parametrize("mode", ["lac", "paper"])
@pytest.mark.parametrize("form", ["softplus", "squared", "log"])
@pytest.mark.parametrize("prior", [None, "position", "velocity"])
def test_every_term_equals_the_hand_calculation(mode, form, prior):
    spec = LyapunovSpec(
        form=form, prior=prior, alpha=0.3, prior_weight=0.7, prior_indices=PRIOR_INDICES
    )
    loss = _loss(spec, mode, target_entropy=-1.5)
    loss.make_value_estimator(gamma=0.9)
    data = _data()
    expected = _expected(data, spec, mode=mode, gamma=0.9, lam=0.7, beta=0.3, target_entropy=-1.5)
    _check(loss(data), expected)


def _leg_data():
    """:func:`_data` with approach legs: transitions 2 and 5 belong to none (in service, a
    target switch), 3 reaches the equilibrium (service starts), 4 ends the episode."""
    data = _data()
    data["next", "approach"] = torch.tensor([1, 1, 0, 1, 1, 0], dtype=torch.bool)[:, None]
    data["next", "service_start"] = torch.tensor([0, 0, 0, 1, 0, 0], dtype=torch.bool)[:, None]
    return data


@pytest.mark.parametrize("constraint", ["mean", "hinge"])
@pytest.mark.parametrize("mode", ["lac", "paper"])
def test_legs_mask_the_critic_and_the_condition_and_the_equilibrium_absorbs(constraint, mode):
    """With ``approach`` and ``service_start`` in the data: the critic's TD loss and the
    decrease condition are means over the approach transitions only, the target and
    ``L(s')`` are 0 at the equilibrium; ``hinge`` charges the actor only for violations."""
    spec = LyapunovSpec(form="softplus", alpha=0.3)
    loss = _loss(spec, mode, target_entropy=-1.5, constraint=constraint)
    loss.make_value_estimator(gamma=0.9)
    data = _leg_data()
    expected = _expected(
        data,
        spec,
        mode=mode,
        gamma=0.9,
        lam=0.7,
        beta=0.3,
        target_entropy=-1.5,
        legs=True,
        constraint=constraint,
    )
    out = loss(data)
    _check(out, expected)
    assert out["leg_fraction"] == pytest.approx(4 / 6)
    # keys set with set_keys that the data lack are refused, not read as "no legs"
    named = _loss(spec, mode, constraint=constraint)
    named.set_keys(approach=("agents", "approach"))
    with pytest.raises(ValueError, match=r"the approach key \('agents', 'approach'\)"):
        named(data)
    # the masks matter: without the flags the numbers differ
    plain = loss(_data())
    assert not torch.allclose(plain["loss_lyapunov"], out["loss_lyapunov"])
    if constraint == "hinge" and mode == "lac":  # (lac's numbers decrease on some legs)
        mean = _expected(
            data, spec, mode=mode, gamma=0.9, lam=0.7, beta=0.3, target_entropy=-1.5, legs=True
        )
        assert not torch.allclose(mean["loss_actor"], out["loss_actor"])


def test_the_lyapunov_critic_has_its_own_discount_and_the_task_critic_keeps_gamma():
    """``make_value_estimator(lyapunov_gamma=...)``: the Lyapunov TD target discounts with
    it; without it, with ``gamma``; a value outside (0, 1] is refused by name."""
    spec = LyapunovSpec(form="softplus", alpha=0.3)
    data = _leg_data()
    loss = _loss(spec, "lac", target_entropy=-1.5)
    loss.make_value_estimator(gamma=0.9, lyapunov_gamma=0.5)
    assert (loss.gamma, loss.lyapunov_gamma) == (0.9, 0.5)
    expected = _expected(
        data, spec, mode="lac", gamma=0.5, lam=0.7, beta=0.3, target_entropy=-1.5, legs=True
    )
    _check(loss(data), {"loss_lyapunov": expected["loss_lyapunov"]})
    loss.make_value_estimator(gamma=0.8)  # keeps the Lyapunov discount it was given
    assert loss.lyapunov_gamma == 0.5
    loss.make_value_estimator(lyapunov_gamma=None)  # back to gamma
    assert loss.lyapunov_gamma == 0.8
    with pytest.raises(ValueError, match="lyapunov_gamma must be in"):
        loss.make_value_estimator(lyapunov_gamma=1.2)


def test_the_pid_multiplier_follows_the_constraint_error_and_integrates_it():
    """multiplier="pid": lambda = clip(kp e + ki I + kd max(0, e - e_prev), 0, lambda_max)
    with I = max(0, I + e), e the batch's mean Delta L; updated in training mode only; the
    dual loss is a constant (no gradient to log_lambda)."""
    spec = LyapunovSpec(form="softplus", alpha=0.3)
    kp, ki, kd = 0.5, 0.25, 2.0
    loss = _loss(spec, "lac", multiplier="pid", pid_gains=(kp, ki, kd))
    loss.lambda_max = 50.0  # far above 1: the PID sets the scale
    data = _leg_data()
    data["next", "cost"] = 5 * data["next", "cost"]  # costly enough to violate on average
    e = _expected(
        data, spec, mode="lac", gamma=0.99, lam=0.7, beta=0.3, target_entropy=-2.0, legs=True
    )
    error = float(e["delta_l"])
    assert error > 0
    out = loss(data)
    first = kp * error + ki * error + kd * error
    assert out["lambda"].item() == pytest.approx(first, rel=1e-5)
    assert not out["loss_lambda"].requires_grad
    out = loss(data)  # the same error again: the integral doubles, no rise
    assert out["lambda"].item() == pytest.approx(kp * error + ki * 2 * error, rel=1e-5)
    loss.eval()
    assert loss(data)["lambda"].item() == pytest.approx(kp * error + ki * 2 * error, rel=1e-5)
    state = loss.state_dict()
    assert state["pid_integral"].item() == pytest.approx(2 * error, rel=1e-5)
    with pytest.raises(ValueError, match="pid_gains"):
        _loss(spec, "lac", multiplier="pid", pid_gains=(1.0, -1.0, 0.0))


def test_with_a_violation_budget_the_pid_follows_the_violation_rate_over_it():
    """violation_budget b: the PID's error is the batch's violation rate over the approach
    transitions minus b (a chance constraint), not the mean Delta L; b needs the PID."""
    spec = LyapunovSpec(form="softplus", alpha=0.3)
    kp, ki = 2.0, 0.5
    data = _leg_data()
    data["next", "cost"] = 3 * data["next", "cost"]  # some transitions violate, some not
    e = _expected(
        data, spec, mode="lac", gamma=0.99, lam=0.7, beta=0.3, target_entropy=-2.0, legs=True
    )
    rate = float(e["violation_rate"])
    assert 0 < rate < 1 and float(e["delta_l"]) != pytest.approx(rate - 0.05)
    loss = _loss(spec, "lac", multiplier="pid", pid_gains=(kp, ki, 0.0), violation_budget=0.05)
    loss.lambda_max = 50.0
    out = loss(data)
    assert out["violation_rate"].item() == pytest.approx(rate)
    assert out["lambda"].item() == pytest.approx((kp + ki) * (rate - 0.05), rel=1e-5)
    # a budget above the rate: a negative error lowers the integral to 0 and lambda to 0
    loose = _loss(spec, "lac", multiplier="pid", pid_gains=(kp, ki, 0.0), violation_budget=0.99)
    assert loose(data)["lambda"].item() == 0.0
    with pytest.raises(ValueError, match="violation_budget"):
        _loss(spec, "lac", multiplier="dual", violation_budget=0.05)
    with pytest.raises(ValueError, match="violation_budget"):
        _loss(spec, "lac", multiplier="pid", violation_budget=1.0)


def test_a_fixed_zero_multiplier_switches_the_constraint_off():
    spec = LyapunovSpec(form="softplus", alpha=0.3)
    actor, critic = _modules()
    loss = LyapunovActorCriticLoss(
        actor,
        critic,
        spec=spec,
        multiplier="fixed",
        lambda_init=0.0,
        beta_init=0.3,
        target_entropy=-1.5,
    )
    out = loss(_data())
    e = _expected(_data(), spec, mode="lac", gamma=0.99, lam=1.0, beta=0.3, target_entropy=-1.5)
    torch.testing.assert_close(out["loss_actor"], e["loss_actor"] - e["delta_l"])
    assert out["lambda"].item() == 0.0
    with pytest.raises(ValueError, match="lambda_init must be > 0"):
        LyapunovActorCriticLoss(actor, critic, lambda_init=0.0)
    with pytest.raises(ValueError, match="multiplier must be one of"):
        LyapunovActorCriticLoss(actor, critic, multiplier="adam")
    with pytest.raises(ValueError, match="constraint must be one of"):
        LyapunovActorCriticLoss(actor, critic, constraint="quantile")


def test_the_huber_critic_loss_is_half_the_square_near_zero_and_linear_beyond():
    """loss_function="smooth_l1": mean of e^2 / 2 where |e| < 1, |e| - 1/2 elsewhere, with
    e = L(s, a) - (c + gamma (1 - d) L_target(s', a')) by hand; the other terms unchanged."""
    spec = LyapunovSpec(form="squared", alpha=0.3)
    loss = _loss(spec, "lac", target_entropy=-1.5, loss_function="smooth_l1")
    loss.make_value_estimator(gamma=0.9)
    data = _data()
    data["next", "cost"][0] = 40.0  # one large target (as a termination's cost)
    expected = _expected(data, spec, mode="lac", gamma=0.9, lam=0.7, beta=0.3, target_entropy=-1.5)
    obs, action, nobs = data["observation"], data["action"], data["next", "observation"]
    policy = lambda o: o @ A.T + A0  # noqa: E731
    target = data["next", "cost"] + 0.9 * (1 - data["next", "terminated"].float()) * _hand_l(
        nobs, policy(nobs), spec, W_TARGET, B_TARGET
    )
    e = (_hand_l(obs, action, spec) - target).abs()
    assert (e >= 1).any() and (e < 1).any()
    expected["loss_lyapunov"] = torch.where(e < 1, 0.5 * e**2, e - 0.5).mean()
    _check(loss(data), expected)
    with pytest.raises(ValueError, match="loss_function must be one of"):
        _loss(spec, "lac", loss_function="l1")


@pytest.mark.parametrize(
    ("kwargs", "target_entropy"),
    [
        ({}, -float(ACT)),  # "auto": minus the action dimension
        ({"action_spec": Bounded(-1.0, 1.0, shape=(ACT + 2,))}, -float(ACT + 2)),
        ({"target_entropy": 0.75}, 0.75),
    ],
)
def test_the_target_entropy_in_the_temperature_loss(kwargs, target_entropy):
    spec = LyapunovSpec(form="squared", alpha=0.1)
    out = _loss(spec, "lac", **kwargs)(_data())
    expected = _expected(
        _data(), spec, mode="lac", gamma=0.99, lam=0.7, beta=0.3, target_entropy=target_entropy
    )
    _check(out, {"loss_beta": expected["loss_beta"]})


def test_the_default_discount_is_0_99_and_lambda_is_clamped_to_lambda_max():
    spec = LyapunovSpec(form="log", alpha=0.2)
    loss = _loss(spec, "lac")
    with torch.no_grad():
        loss.log_lambda.fill_(torch.tensor(5.0).log())  # exp = 5 > lambda_max = 1
    out = loss(_data())
    expected = _expected(
        _data(), spec, mode="lac", gamma=0.99, lam=1.0, beta=0.3, target_entropy=-float(ACT)
    )
    # log_lambda itself is put back at log(lambda_max) = 0 before the dual term (no windup)
    expected["loss_lambda"] = -torch.tensor(1.0).log() * expected["delta_l"]
    _check(out, expected)
    assert out["lambda"] == 1.0 and loss.log_lambda.item() == 0.0


def test_the_critic_gradient_is_the_hand_derivative():
    """d loss_lyapunov / d b for the squared form: mean((L - y) * 2 raw) (target fixed)."""
    spec = LyapunovSpec(form="squared", alpha=0.1)
    loss = _loss(spec, "lac")
    data = _data()
    loss(data)["loss_lyapunov"].backward()
    obs, action = data["observation"], data["action"]
    raw = torch.cat([obs, action], -1) @ W.T + B
    value = (raw**2).sum(-1, keepdim=True)
    nobs = data["next", "observation"]
    next_target = _hand_l(nobs, nobs @ A.T + A0, spec, W_TARGET, B_TARGET)
    target = data["next", "cost"] + 0.99 * (1 - data["next", "terminated"].float()) * next_target
    grad_b = ((value - target) * 2 * raw).mean(0)
    torch.testing.assert_close(loss.lyapunov_network_params["module", "bias"].grad, grad_b)


# the task critic's numbers (one output; chosen, not read off the code)
WQ = torch.tensor([[0.7, 0.1, -0.4, 0.3, 0.9]])
BQ = torch.tensor([1.5])
WQ_TARGET, BQ_TARGET = WQ - 0.25, BQ + 0.5


def _two_critic_loss(spec):
    actor, critic = _modules()
    q = ValueOperator(_Affine(WQ, BQ), in_keys=["observation", "action"], out_keys=["task_q"])
    loss = LyapunovActorCriticLoss(
        actor,
        critic,
        spec=spec,
        lambda_init=0.7,
        lambda_max=1.0,
        beta_init=0.3,
        target_entropy=-1.5,
        qvalue_network=q,
    )
    loss.set_keys(cost="stability_cost", task_cost="cost", qvalue="task_q")
    with torch.no_grad():
        loss.target_lyapunov_network_params["module", "weight"].copy_(W_TARGET)
        loss.target_lyapunov_network_params["module", "bias"].copy_(B_TARGET)
        loss.target_qvalue_network_params["module", "weight"].copy_(WQ_TARGET)
        loss.target_qvalue_network_params["module", "bias"].copy_(BQ_TARGET)
    loss.make_value_estimator(gamma=0.9)
    return loss


def test_the_task_critic_learns_the_task_cost_and_the_actor_minimises_it():
    spec = LyapunovSpec(form="softplus", alpha=0.3)
    loss = _two_critic_loss(spec)
    data = _data()
    g = torch.Generator().manual_seed(1)
    data["next", "stability_cost"] = torch.rand(data.shape[0], 1, generator=g)
    obs, action, nobs = data["observation"], data["action"], data["next", "observation"]
    task_cost, cost = data["next", "cost"], data["next", "stability_cost"]
    term = data["next", "terminated"].float()
    policy = lambda o: o @ A.T + A0  # noqa: E731  (the Dirac actor)
    q = lambda o, a, w=WQ, b=BQ: torch.cat([o, a], -1) @ w.T + b  # noqa: E731

    value = _hand_l(obs, action, spec)
    l_target = cost + 0.9 * (1 - term) * _hand_l(nobs, policy(nobs), spec, W_TARGET, B_TARGET)
    q_target = task_cost + 0.9 * (1 - term) * q(nobs, policy(nobs), WQ_TARGET, BQ_TARGET)
    delta = (1 - term) * _hand_l(nobs, policy(nobs), spec) - value + 0.3 * cost
    log_pi = -0.5 * (policy(obs) ** 2).sum(-1) + LOG_PROB_SHIFT
    expected = {
        "loss_lyapunov": 0.5 * ((value - l_target) ** 2).mean(),
        "loss_qvalue": 0.5 * ((q(obs, action) - q_target) ** 2).mean(),
        "qvalue": q(obs, action).mean(),
        "delta_l": delta.mean(),
        "loss_actor": q(obs, policy(obs)).mean() + 0.7 * delta.mean() + 0.3 * log_pi.mean(),
        "loss_lambda": -torch.log(torch.tensor(0.7)) * delta.mean(),
    }
    out = loss(data)
    for key, val in expected.items():
        torch.testing.assert_close(
            out[key], val, rtol=1e-5, atol=1e-6, msg=lambda m, key=key: f"{key}: {m}"
        )
    assert set(expected) <= set(loss.out_keys)

    # gradients: the Q loss reaches only the Q critic, the actor loss only the actor
    loss.zero_grad()
    out["loss_qvalue"].backward(retain_graph=True)
    assert loss.qvalue_network_params["module", "weight"].grad.abs().sum() > 0
    assert all(
        p.grad is None or p.grad.abs().sum() == 0
        for p in loss.actor_network_params.values(True, True)
    )
    loss.zero_grad()
    out["loss_actor"].backward()
    assert loss.actor_network_params["module", "0", "module", "weight"].grad.abs().sum() > 0
    for params in (loss.qvalue_network_params, loss.lyapunov_network_params):
        assert all(p.grad is None or p.grad.abs().sum() == 0 for p in params.values(True, True))


def test_without_a_task_critic_the_loss_is_lac_as_published():
    actor, critic = _modules()
    loss = LyapunovActorCriticLoss(actor, critic)
    assert loss.qvalue_network is None
    assert "loss_qvalue" not in loss.out_keys
    assert "loss_qvalue" not in loss(_data()).keys()


class _CostToGo(nn.Module):
    """``sqrt(L*)`` is observation entry 0: with the "squared" form the critic is the true
    cost-to-go ``L*``, whatever the action."""

    def __init__(self) -> None:
        super().__init__()
        self.unused = nn.Parameter(torch.zeros(1))

    def forward(self, observation: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        return observation[..., :1] + 0 * self.unused


def _chain(costs: torch.Tensor, gamma: float, tail: float) -> TensorDict:
    """Transitions of a deterministic chain with these per-step costs; ``tail`` is the
    cost-to-go after the last one. The critic reads the exact discounted cost-to-go."""
    to_go = [tail]
    for c in reversed(costs.tolist()):
        to_go.insert(0, c + gamma * to_go[0])
    root = torch.tensor(to_go).sqrt()[:, None]
    n = costs.numel()
    return TensorDict(
        {
            "observation": root[:-1],
            "action": torch.zeros(n, 1),
            "next": {
                "observation": root[1:],
                "cost": costs[:, None],
                "terminated": torch.zeros(n, 1, dtype=torch.bool),
            },
        },
        batch_size=[n],
    )


def _cost_to_go_loss(alpha: float, gamma: float) -> LyapunovActorCriticLoss:
    """The loss with :class:`_CostToGo` as its critic (the squared form: the true L)."""
    actor = ProbabilisticActor(
        TensorDictModule(nn.Linear(1, 1), in_keys=["observation"], out_keys=["loc"]),
        in_keys=["loc"],
        distribution_class=_Dirac,
    )
    critic = ValueOperator(_CostToGo(), in_keys=["observation", "action"])
    loss = LyapunovActorCriticLoss(actor, critic, spec=LyapunovSpec(form="squared", alpha=alpha))
    loss.make_value_estimator(gamma=gamma)
    return loss


@pytest.mark.parametrize("alpha", [0.1, 0.3])
def test_the_decrease_condition_fails_for_a_stationary_cost_and_holds_for_a_vanishing_one(alpha):
    gamma = 0.97
    loss = _cost_to_go_loss(alpha, gamma)

    def delta(data):
        out = loss(data)
        after, cost = data["next", "observation"][:, 0] ** 2, data["next", "cost"][:, 0]
        closed_form = (1 - gamma) * after - (1 - alpha) * cost  # the docstring's identity
        torch.testing.assert_close(out["delta_l"], closed_form.mean(), rtol=1e-4, atol=1e-4)
        return out

    # a cost that never vanishes (as the waiting data): 1 per step for ever
    stationary = _chain(torch.ones(50), gamma, tail=1.0 / (1 - gamma))
    out = delta(stationary)
    assert out["violation_rate"] == 1.0
    torch.testing.assert_close(out["delta_l"], torch.tensor(alpha), rtol=1e-3, atol=1e-3)
    # a cost that falls to zero at the goal (closing on a target 100 m away at 1.5 m/step)
    approach = torch.clamp(torch.arange(100.0, 0.0, -1.5) / 283.0, min=0.0)
    vanishing = _chain(torch.cat([approach, torch.zeros(20)]), gamma, tail=0.0)
    out = delta(vanishing)
    assert out["violation_rate"] == 0.0 and out["delta_l"] < 0


@pytest.mark.parametrize("gamma", [0.99, 1.0])
def test_on_a_leg_that_ends_at_an_absorbing_equilibrium_the_true_cost_to_go_decreases(gamma):
    """The docstring's leg derivation: with the TD target ending at service start (``L = 0``
    there), the leg's cost-to-go satisfies the decrease condition on every transition of an
    approach at constant speed (costs proportional to the distance left), the last one
    included, for gamma up to 1; a policy that stalls half-way for ever (the same cost
    again and again, gamma < 1) violates it."""
    alpha = 0.3
    loss = _cost_to_go_loss(alpha, gamma)
    costs = torch.arange(150.0, 0.0, -1.5) / 283.0  # 150 m from the node at 1.5 m a decision
    leg = _chain(costs, gamma, tail=0.0)
    n = costs.numel()
    leg["next", "approach"] = torch.ones(n, 1, dtype=torch.bool)
    leg["next", "service_start"] = torch.arange(n)[:, None] == n - 1
    # the state after service start reads a cost-to-go of the next leg, not 0: the flag, not
    # the observation, makes the equilibrium absorbing
    leg["next", "observation"][-1] = 3.0
    out = loss(leg)
    assert out["violation_rate"] == 0.0 and out["delta_l"] < 0
    if gamma == 1.0:  # a stalled policy's undiscounted cost-to-go is infinite
        return
    stall = costs[n // 2].item()  # for ever: the stationary cost-to-go stall / (1 - gamma)
    stalled = _chain(torch.full((40,), stall), gamma, tail=stall / (1 - gamma))
    stalled["next", "approach"] = torch.ones(40, 1, dtype=torch.bool)
    stalled["next", "service_start"] = torch.zeros(40, 1, dtype=torch.bool)
    assert loss(stalled)["violation_rate"] == 1.0
