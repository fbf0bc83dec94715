"""The executed policy's backup and the anchored selection: SelectionRule, the selector with
an ensemble, CandidateBackupSACLoss's and LyapunovActorCriticLoss's targets by hand."""

from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import NormalParamExtractor, TensorDictModule
from torch import nn
from torchrl.modules import MLP, ProbabilisticActor, TanhNormal, ValueOperator

from torchrl_auv.objectives import (
    CandidateBackupSACLoss,
    CandidateSelector,
    LyapunovActorCriticLoss,
    LyapunovSpec,
    QEnsembleCritic,
    SelectionRule,
    lyapunov_value,
)

OBS, ACT, K = 3, 2, 4


def _actor():
    net = nn.Sequential(
        MLP(in_features=OBS, out_features=2 * ACT, num_cells=[16]), NormalParamExtractor()
    )
    return ProbabilisticActor(
        TensorDictModule(net, ["observation"], ["loc", "scale"]),
        in_keys=["loc", "scale"],
        distribution_class=TanhNormal,
        return_log_prob=True,
    )


class _CatLinear(nn.Linear):
    """A linear critic of the concatenated observation and action."""

    def forward(self, *inputs):
        return super().forward(torch.cat(inputs, -1))


def _critic(out_keys=None):
    return ValueOperator(
        _CatLinear(OBS + ACT, 1), in_keys=["observation", "action"], out_keys=out_keys
    )


def _batch(n=8, seed=0, terminated_rows=(0,)):
    g = torch.Generator().manual_seed(seed)
    terminated = torch.zeros(n, 1, dtype=torch.bool)
    terminated[list(terminated_rows)] = True
    return TensorDict(
        {
            "observation": torch.randn(n, OBS, generator=g),
            "action": torch.rand(n, ACT, generator=g) * 2 - 1,
            "next": {
                "observation": torch.randn(n, OBS, generator=g),
                "reward": -torch.rand(n, 1, generator=g),
                "cost": torch.rand(n, 1, generator=g),
                "done": terminated.clone(),
                "terminated": terminated,
                ("proposer", "first_actions"): torch.rand(n, K, ACT, generator=g) * 2 - 1,
                ("proposer", "medoid"): torch.randint(0, K, (n,), generator=g),
            },
        },
        batch_size=[n],
    )


def _linear(params, observation, action):
    """A Linear critic's output by hand from its parameters (``module.weight/bias``)."""
    weight, bias = params["module", "weight"], params["module", "bias"]
    return torch.cat([observation, action], -1) @ weight.T + bias


# -- SelectionRule -----------------------------------------------------------------------------
def test_the_anchored_rule_deviates_only_where_the_best_dominates_the_anchor():
    lower = torch.tensor([[1.0, 3.0, 2.0], [1.0, 3.0, 2.0], [1.0, 3.0, 2.0]])
    upper = torch.tensor([[1.5, 3.5, 2.5], [1.5, 3.5, 3.2], [1.5, 3.5, 2.5]])
    anchor = torch.tensor([0, 2, 2])
    rule = SelectionRule(anchor="medoid")
    # row 0: 3.0 > 1.5 deviates; row 1: 3.0 < 3.2 keeps the anchor; row 2: 3.0 > 2.5 deviates
    assert rule.choose(lower, upper, anchor).tolist() == [1, 2, 1]
    assert SelectionRule(anchor="medoid", margin=0.6).choose(lower, upper, anchor).tolist() == [
        1,
        2,
        2,
    ]
    rule.deviate.fill_(False)  # the warm-up: always the anchor
    assert rule.choose(lower, upper, anchor).tolist() == [0, 2, 2]
    assert SelectionRule().choose(lower, upper).tolist() == [1, 1, 1]  # argmax of lower
    with pytest.raises(ValueError, match="anchor_index"):
        SelectionRule(anchor="medoid").choose(lower, upper)


@pytest.mark.parametrize(
    ("kwargs", "named"),
    [
        ({"anchor": "mean"}, "anchor"),
        ({"margin": -1.0}, "margin"),
        ({"dominance": "x"}, "dominance"),
    ],
)
def test_a_bad_rule_names_the_argument(kwargs, named):
    with pytest.raises(ValueError, match=named):
        SelectionRule(**kwargs)


# -- the selector with a Q ensemble and an anchor ------------------------------------------------
class _Scaled(nn.Module):
    """Q(s, a) = w * a_0 + b: members differ in w and b only."""

    def __init__(self):
        super().__init__()
        self.w = nn.Parameter(torch.ones(()))
        self.b = nn.Parameter(torch.zeros(()))

    def forward(self, observation, action):
        return self.w * action[..., :1] + self.b + 0 * observation[..., :1]


def _ensemble(weights, offsets=None):
    net = TensorDictModule(_Scaled(), ["observation", "action"], ["state_action_value"])
    params = TensorDict.from_module(net).expand(len(weights)).clone()
    params["module", "w"] = torch.tensor(weights)
    params["module", "b"] = torch.tensor(offsets or [0.0] * len(weights))
    from tensordict import TensorDictParams

    return QEnsembleCritic(net, TensorDictParams(params))


def test_the_anchored_selector_keeps_the_medoid_unless_the_ensemble_agrees_on_a_better_one():
    # 5 chunks: four close together around 0 (the medoid among them), one far out at 0.9
    chunks = torch.zeros(1, 5, 2, 2)
    chunks[0, :, :, 0] = torch.tensor([0.0, 0.05, -0.05, 0.02, 0.9])[:, None]
    td = TensorDict({"observation": torch.zeros(1, 3), ("proposer", "candidates"): chunks}, [1])
    rule = SelectionRule(anchor="medoid")
    agree = CandidateSelector(_ensemble([1.0, 1.1]), mode="q", rule=rule)(td.clone())
    assert agree["selector", "anchor"].item() == 3  # the medoid of the five chunks
    assert agree["selector", "index"].item() == 4  # 0.9 * 1.0 > 0.02 * 1.1: dominates
    # members that disagree in sign: the far candidate's pessimistic value is below the anchor's
    disagree = CandidateSelector(_ensemble([1.0, -1.0]), mode="q", rule=rule)(td.clone())
    assert disagree["selector", "index"].item() == 3
    plain = CandidateSelector(_ensemble([1.0, -1.0]), mode="q")(td.clone())
    assert ("selector", "anchor") not in plain.keys(True)
    assert plain["selector", "index"].item() == plain["selector", "ranking"][0, 0].item()
    # members that agree on every advantage but disagree on the state's value by 2: the
    # intervals overlap (0.9 - 1 < 0.02 + 1), every member's advantage is 0.88
    shifted = _ensemble([1.0, 1.0], offsets=[-1.0, 1.0])
    assert CandidateSelector(shifted, mode="q", rule=rule)(td.clone())["selector", "index"] == 3
    paired = SelectionRule(anchor="medoid", dominance="paired")
    assert CandidateSelector(shifted, mode="q", rule=paired)(td.clone())["selector", "index"] == 4
    # ... and not where one member's advantage is negative, nor below the margin
    opposed = CandidateSelector(_ensemble([1.0, -1.0]), mode="q", rule=paired)(td.clone())
    assert opposed["selector", "index"] == 3
    wide = SelectionRule(anchor="medoid", dominance="paired", margin=0.9)
    assert CandidateSelector(shifted, mode="q", rule=wide)(td.clone())["selector", "index"] == 3


def test_the_paired_rule_needs_every_members_advantage():
    members = torch.tensor([[[0.0, 2.0, 1.0]], [[5.0, 3.0, 4.5]]])  # [n=2, B=1, K=3]
    lower, upper = members.min(0).values, members.max(0).values
    paired = SelectionRule(anchor="medoid", dominance="paired")
    # anchor 0: member 1 prefers it to both others
    assert paired.choose(lower, upper, torch.tensor([0]), members=members).tolist() == [0]
    members[1, 0, 1] = 5.0  # now member 1 prefers candidate 1 to 2 by 0.5, member 0 by 1.0
    assert paired.choose(lower, upper, torch.tensor([2]), members=members).tolist() == [1]
    paired.deviate.fill_(False)
    assert paired.choose(lower, upper, torch.tensor([2]), members=members).tolist() == [2]
    with pytest.raises(ValueError, match="members"):
        SelectionRule(anchor="medoid", dominance="paired").choose(lower, upper, torch.tensor([2]))


# -- CandidateBackupSACLoss ------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("anchor", "dominance"), [(None, "interval"), ("medoid", "interval"), ("medoid", "paired")]
)
def test_the_sac_target_bootstraps_on_the_executed_candidate(anchor, dominance):
    torch.manual_seed(0)
    rule = SelectionRule(anchor=anchor, dominance=dominance)
    loss = CandidateBackupSACLoss(
        _actor(), _critic(), backup="candidates", rule=rule, target_entropy=-float(ACT)
    )
    loss.make_value_estimator(gamma=0.9)
    with torch.no_grad():  # distinct target members
        loss.target_qvalue_network_params["module", "weight"].normal_()
    td = _batch(n=64)
    nxt = td["next"]
    cands = nxt["proposer", "first_actions"]
    obs = nxt["observation"].unsqueeze(-2).expand(-1, K, -1)
    members = torch.stack(
        [_linear(loss.target_qvalue_network_params[i], obs, cands)[..., 0] for i in range(2)]
    )
    lower, upper = members.min(0).values, members.max(0).values
    index = rule.choose(lower, upper, nxt["proposer", "medoid"], members=members)
    if dominance == "paired":  # this batch tells the two rules apart
        interval = SelectionRule(anchor="medoid").choose(lower, upper, nxt["proposer", "medoid"])
        assert not torch.equal(index, interval)
    bootstrap = lower.gather(-1, index[:, None])
    expected = nxt["reward"] + 0.9 * (~nxt["terminated"]) * bootstrap
    torch.testing.assert_close(loss._compute_target_v2(td), expected.squeeze(-1))
    assert loss(td)["loss_qvalue"].isfinite()


def test_the_actor_backup_is_torchrls_sac_target():
    from torchrl.objectives import SACLoss

    torch.manual_seed(0)
    ours = CandidateBackupSACLoss(_actor(), _critic(), target_entropy=-float(ACT))
    torch.manual_seed(0)
    theirs = SACLoss(_actor(), _critic(), target_entropy=-float(ACT))
    td = _batch()
    torch.manual_seed(1)
    a = ours._compute_target_v2(td)
    torch.manual_seed(1)
    torch.testing.assert_close(a, theirs._compute_target_v2(td))


def test_a_candidate_backup_without_stored_candidates_says_what_to_store():
    loss = CandidateBackupSACLoss(
        _actor(), _critic(), backup="candidates", target_entropy=-float(ACT)
    )
    td = _batch()
    del td["next", "proposer"]
    with pytest.raises(ValueError, match="with_next_candidates"):
        loss(td)
    with pytest.raises(ValueError, match="backup"):
        CandidateBackupSACLoss(_actor(), _critic(), backup="policy")


# -- LyapunovActorCriticLoss -------------------------------------------------------------------
def test_both_lac_critics_bootstrap_on_the_candidate_argmin_l_executes():
    torch.manual_seed(0)
    rule = SelectionRule(anchor="medoid")
    q = _critic(out_keys=["task_q"])
    loss = LyapunovActorCriticLoss(
        _actor(), _critic(), qvalue_network=q, form="softplus", backup="candidates", rule=rule
    )
    loss.set_keys(qvalue="task_q", task_cost="cost")
    loss.make_value_estimator(gamma=0.9)
    td = _batch()
    nxt = td["next"]
    cands = nxt["proposer", "first_actions"]
    obs = nxt["observation"].unsqueeze(-2).expand(-1, K, -1)
    spec = LyapunovSpec(form="softplus")
    values = lyapunov_value(_linear(loss.target_lyapunov_network_params, obs, cands), spec)
    index = rule.choose(-values[..., 0], -values[..., 0], nxt["proposer", "medoid"])
    chosen = cands[torch.arange(len(index)), index]
    continues = (~nxt["terminated"]).float()
    l_target = nxt["cost"] + 0.9 * continues * values[torch.arange(len(index)), index]
    q_target = nxt["cost"] + 0.9 * continues * _linear(
        loss.target_qvalue_network_params, nxt["observation"], chosen
    )
    l_now = lyapunov_value(
        _linear(loss.lyapunov_network_params, td["observation"], td["action"]), spec
    )
    q_now = _linear(loss.qvalue_network_params, td["observation"], td["action"])
    out = loss(td)
    torch.testing.assert_close(out["loss_lyapunov"], 0.5 * (l_now - l_target).square().mean())
    torch.testing.assert_close(out["loss_qvalue"], 0.5 * (q_now - q_target).square().mean())
    assert ("next", "proposer", "medoid") in loss.in_keys


# -- the Lyapunov filter on the executed candidate ----------------------------------------------
def _filter_td(n=6, seed=3):
    """A state with K candidates, the previous pair in the history and the leg flags."""
    g = torch.Generator().manual_seed(seed)
    return TensorDict(
        {
            "observation": torch.randn(n, OBS, generator=g),
            ("proposer", "candidates"): torch.rand(n, K, 2, ACT, generator=g) * 2 - 1,
            ("history", "observation"): torch.randn(n, 3, OBS, generator=g),
            ("history", "action"): torch.rand(n, 3, ACT, generator=g) * 2 - 1,
            ("history", "mask"): torch.ones(n, 3, dtype=torch.bool),
            "cost": torch.rand(n, 1, generator=g),
            "approach": torch.ones(n, 1, dtype=torch.bool),
            "service_start": torch.zeros(n, 1, dtype=torch.bool),
        },
        batch_size=[n],
    )


@pytest.mark.parametrize(("anchored", "mode"), [(False, "rank"), (True, "rank"), (True, "veto")])
def test_the_filtered_selector_executes_the_task_critics_choice_among_the_feasible(anchored, mode):
    """LyapunovFilter + mode "cost": where the previous decision is on a leg that goes on,
    the executed candidate is the least task cost among those with L(s, a_k) <= L(s_prev,
    a_prev) - alpha c_prev (the anchored rule among them: an infeasible medoid is left), the
    least L where none is; off a leg (or without the previous pair) the plain choice. "veto":
    the medoid wherever it is feasible."""
    from torchrl_auv.modules import LyapunovFilter

    torch.manual_seed(0)
    lyap, task = _critic(), _critic(out_keys=["task_q"])
    spec = LyapunovSpec(form="softplus", alpha=0.4)
    rule = SelectionRule(anchor="medoid") if anchored else None
    selector = CandidateSelector(
        task,
        mode="cost",
        critic_out_key="task_q",
        constraint=LyapunovFilter(lyap, spec=spec, mode=mode),
        rule=rule,
    )
    td = _filter_td(n=32)
    td["service_start"][29] = True  # decision 29 reached the node: the leg is over
    td["approach"][30] = False  # decision 30: off a leg; decision 31: a reset, no history
    td["history", "mask"][31, -1] = False
    out = selector(td.clone())

    first = td["proposer", "candidates"][..., 0, :]
    obs = td["observation"].unsqueeze(-2).expand(-1, K, -1)
    l_params, q_params = TensorDict.from_module(lyap), TensorDict.from_module(task)
    with torch.no_grad():
        l_now = lyapunov_value(_linear(l_params, obs, first), spec)[..., 0]
        previous = (td["history", "observation"][:, -1], td["history", "action"][:, -1])
        before = lyapunov_value(_linear(l_params, *previous), spec)[:, 0]
        q = _linear(q_params, obs, first)[..., 0]
    torch.testing.assert_close(out["selector", "lyapunov"], l_now)
    feasible = l_now <= (before - 0.4 * td["cost"][:, 0])[:, None]
    feasible[29:] = True
    assert torch.equal(out["selector", "feasible"], feasible)
    none = ~feasible.any(-1)
    some = feasible.any(-1) & ~feasible.all(-1)
    assert none.any() and some.any()  # the numbers cover both cases
    cost = q.masked_fill(~feasible, float("inf"))
    expected = cost.argmin(-1)
    if anchored:  # one critic: deviate where the best feasible costs less than the medoid
        anchor = out["selector", "anchor"]
        medoid_cost = cost.gather(-1, anchor[:, None])[:, 0]
        expected = torch.where(cost.min(-1).values < medoid_cost, expected, anchor)
        if mode == "veto":
            kept = feasible[torch.arange(32), anchor]
            assert kept.any() and (~kept & ~none).any()
            expected = torch.where(kept, anchor, cost.argmin(-1))
    expected = torch.where(none, l_now.argmin(-1), expected)
    assert torch.equal(out["selector", "index"], expected)
    if anchored:  # a warm-up: the anchor acts, feasible or not, whatever the untrained L says
        selector.rule.deviate.fill_(False)
        warm = selector(td.clone())
        assert torch.equal(warm["selector", "index"], warm["selector", "anchor"])


@pytest.mark.parametrize(
    ("anchored", "filter_mode"), [(False, "rank"), (True, "rank"), (True, "veto")]
)
def test_with_the_filter_both_lac_critics_bootstrap_on_the_filtered_choice(anchored, filter_mode):
    """filter_candidates=True: at s' the target task critic's choice among the candidates
    with L'(s', a'_k) <= L'(s, a) - alpha c (on a leg that goes on), else the least L'; both
    TD targets bootstrap on it. Refused without a task critic or the candidate backup."""
    torch.manual_seed(1)
    q = _critic(out_keys=["task_q"])
    rule = SelectionRule(anchor="medoid") if anchored else SelectionRule()
    spec = LyapunovSpec(form="softplus", alpha=0.3)
    loss = LyapunovActorCriticLoss(
        _actor(),
        _critic(),
        qvalue_network=q,
        spec=spec,
        backup="candidates",
        rule=rule,
        filter_candidates=filter_mode,
    )
    loss.set_keys(qvalue="task_q", task_cost="cost")
    loss.make_value_estimator(gamma=0.9)
    n = 16
    td = _batch(n=n, seed=4, terminated_rows=(0,))
    td["next", "approach"] = torch.ones(n, 1, dtype=torch.bool)
    td["next", "approach"][1] = False  # off a leg
    td["next", "service_start"] = torch.zeros(n, 1, dtype=torch.bool)
    td["next", "service_start"][2] = True  # the leg ends: L(s') = 0, no filter
    nxt, rows = td["next"], torch.arange(n)
    cands, anchor = nxt["proposer", "first_actions"], nxt["proposer", "medoid"]
    obs = nxt["observation"].unsqueeze(-2).expand(-1, K, -1)
    target_l, target_q = loss.target_lyapunov_network_params, loss.target_qvalue_network_params
    with torch.no_grad():
        values = lyapunov_value(_linear(target_l, obs, cands), spec)[..., 0]
        own = lyapunov_value(_linear(target_l, td["observation"], td["action"]), spec)[:, 0]
        q_next = _linear(target_q, obs, cands)[..., 0]
    cost = nxt["cost"][:, 0]
    goes_on = nxt["approach"][:, 0] & ~nxt["service_start"][:, 0] & ~nxt["terminated"][:, 0]
    bound = torch.where(goes_on, own - 0.3 * cost, torch.inf)
    feasible = values <= bound[:, None]
    allowed = feasible
    if filter_mode == "veto":  # only the anchor where it is feasible
        keep = feasible[rows, anchor]
        allowed = torch.where(keep[:, None], torch.arange(K) == anchor[:, None], feasible)
    scores = (-q_next).masked_fill(~allowed, -1e9)
    index = rule.choose(scores, scores, anchor)
    index = torch.where(feasible.any(-1), index, values.argmin(-1))
    none, some = ~feasible.any(-1), feasible.any(-1) & ~feasible.all(-1)
    assert none.any() and some.any()  # the numbers cover both cases
    assert not torch.equal(index, values.argmin(-1))  # and the filter changes the choice
    chosen = cands[rows, index]
    absorbing = (~nxt["terminated"][:, 0] & ~nxt["service_start"][:, 0]).float()
    l_target = cost + 0.9 * absorbing * values[rows, index]
    q_target = (
        cost
        + 0.9
        * (~nxt["terminated"][:, 0]).float()
        * _linear(target_q, nxt["observation"], chosen)[:, 0]
    )
    l_now = lyapunov_value(
        _linear(loss.lyapunov_network_params, td["observation"], td["action"]), spec
    )[:, 0]
    q_now = _linear(loss.qvalue_network_params, td["observation"], td["action"])[:, 0]
    on = nxt["approach"][:, 0].float()
    if anchored:  # during a warm-up the backup bootstraps on the anchor, as the selector acts
        rule.deviate.fill_(False)
        warm = loss(td.clone())
        rule.deviate.fill_(True)
        at_anchor = cost + 0.9 * absorbing * values[rows, anchor]
        torch.testing.assert_close(
            warm["loss_lyapunov"], (0.5 * (l_now - at_anchor).square() * on).sum() / on.sum()
        )
    out = loss(td)
    torch.testing.assert_close(
        out["loss_lyapunov"], (0.5 * (l_now - l_target).square() * on).sum() / on.sum()
    )
    torch.testing.assert_close(out["loss_qvalue"], 0.5 * (q_now - q_target).square().mean())
    with pytest.raises(ValueError, match="filter_candidates='rank'"):
        LyapunovActorCriticLoss(_actor(), _critic(), backup="candidates", filter_candidates="rank")
    with pytest.raises(ValueError, match="filter_candidates='rank'"):
        LyapunovActorCriticLoss(_actor(), _critic(), qvalue_network=q, filter_candidates="rank")
    with pytest.raises(ValueError, match="needs an anchored rule"):
        LyapunovActorCriticLoss(
            _actor(), _critic(), qvalue_network=q, backup="candidates", filter_candidates="veto"
        )


@pytest.mark.parametrize("backup", ["actor", "candidates"])
def test_a_critic_of_another_cost_learns_its_negative_as_the_reward(backup):
    """reward_from="stability_cost": every output is the loss's on the same data whose reward
    is -stability_cost (the caller's data untouched); a missing key is named."""
    torch.manual_seed(2)
    kwargs = {"backup": backup, "target_entropy": -1.0}
    own = CandidateBackupSACLoss(_actor(), _critic(), reward_from="stability_cost", **kwargs)
    plain = CandidateBackupSACLoss(_actor(), _critic(), **kwargs)
    plain.load_state_dict(own.state_dict())
    td = _batch()
    td["next", "stability_cost"] = torch.rand(td.shape[0], 1) * 3
    relabelled = td.clone()
    relabelled["next", "reward"] = -td["next", "stability_cost"]
    reward = td["next", "reward"].clone()
    torch.manual_seed(5)
    out = own(td)
    torch.manual_seed(5)
    expected = plain(relabelled)
    for key in ("loss_qvalue", "loss_actor"):
        torch.testing.assert_close(out[key], expected[key])
    assert torch.equal(td["next", "reward"], reward)
    td_without = _batch()
    with pytest.raises(ValueError, match="reward_from 'stability_cost'"):
        own(td_without)


def test_a_veto_filter_needs_an_anchored_rule():
    from torchrl_auv.modules import LyapunovFilter

    with pytest.raises(ValueError, match="needs an anchored rule"):
        CandidateSelector(_critic(), mode="cost", constraint=LyapunovFilter(_critic(), mode="veto"))
    with pytest.raises(ValueError, match="mode must be one of"):
        LyapunovFilter(_critic(), mode="strict")
