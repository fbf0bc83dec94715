"""The medoid pick of the proposer acting alone: brute force agrees, an outlier is never
picked, the pick is one of the candidates, and ProposerAlone executes its first action."""

from __future__ import annotations

import itertools

import pytest
import torch
from tensordict import TensorDict

from torchrl_auv.modules import DiffusionProposer, ProposerAlone, medoid_index, pick_candidate


def _brute_force_medoid(chunks: torch.Tensor) -> int:
    """The candidate with the smallest summed distance, by explicit loops."""
    k = chunks.shape[0]
    totals = [
        sum(float((chunks[i] - chunks[j]).pow(2).sum().sqrt()) for j in range(k)) for i in range(k)
    ]
    return min(range(k), key=lambda i: (totals[i], i))


def test_medoid_matches_brute_force_on_batched_candidates():
    g = torch.Generator().manual_seed(0)
    candidates = torch.rand(3, 2, 7, 4, 3, generator=g) * 2 - 1  # [B=3, N=2, K=7, H=4, A=3]
    index = medoid_index(candidates)
    assert index.shape == (3, 2)
    for b, n in itertools.product(range(3), range(2)):
        assert index[b, n].item() == _brute_force_medoid(candidates[b, n])


def test_an_outlier_is_never_the_pick_and_the_pick_is_a_candidate():
    g = torch.Generator().manual_seed(1)
    cluster = 0.05 * torch.randn(5, 8, 3, generator=g)
    outlier = torch.ones(1, 8, 3)
    for position in range(6):  # wherever the outlier sits, even at candidate 0
        candidates = torch.cat([cluster[:position], outlier, cluster[position:]])[None]
        chosen = pick_candidate(candidates, "medoid")[0]
        assert not torch.equal(chosen, outlier[0])
        assert any(torch.equal(chosen, c) for c in candidates[0])
    assert torch.equal(pick_candidate(candidates, "first"), candidates[:, 0])


def test_bad_pick_and_shapes_are_refused():
    with pytest.raises(ValueError, match="pick must be one of"):
        pick_candidate(torch.zeros(1, 2, 3, 1), "mean")
    with pytest.raises(ValueError, match="candidates must be shaped"):
        medoid_index(torch.zeros(2, 3))
    with pytest.raises(ValueError, match="pick must be one of"):
        ProposerAlone(DiffusionProposer(4, 2), pick="best")


def test_proposer_alone_executes_the_first_action_of_the_medoid():
    proposer = DiffusionProposer(4, 3, num_candidates=6, horizon=4, num_inference_steps=3)
    td = TensorDict({"observation": torch.randn(5, 4)}, [5])
    torch.manual_seed(0)
    out = ProposerAlone(proposer, action_key=("agents", "action"))(td)
    candidates = out["proposer", "candidates"]
    expected = pick_candidate(candidates, "medoid")[..., 0, :]
    torch.testing.assert_close(out["agents", "action"], expected)
    assert not torch.equal(expected, candidates[:, 0, 0])  # not simply candidate 0 here


def _decide(module, obs, counts):
    td = TensorDict(
        {"observation": obs, "step_count": torch.tensor(counts)[:, None]}, [len(counts)]
    )
    return module(td)


def test_replan_every_executes_one_chunk_then_plans_again():
    torch.manual_seed(0)
    proposer = DiffusionProposer(4, 3, num_candidates=5, horizon=4, num_inference_steps=3)
    alone = ProposerAlone(proposer, replan_every=3)
    obs = torch.randn(2, 4)
    outs = [_decide(alone, obs, [t, t]) for t in range(4)]
    plan = outs[0]["proposer", "plan"]
    for t in range(3):  # one plan, its actions in order
        assert outs[t]["proposer", "plan_step"].tolist() == [t, t]
        torch.testing.assert_close(outs[t]["proposer", "plan"], plan)
        torch.testing.assert_close(outs[t]["action"], plan[:, t])
    assert outs[3]["proposer", "plan_step"].tolist() == [0, 0]  # the fourth decision re-plans
    assert not torch.equal(outs[3]["proposer", "plan"], plan)
    torch.testing.assert_close(outs[3]["action"], outs[3]["proposer", "plan"][:, 0])


def test_a_restarted_row_plans_anew_and_the_others_keep_their_plan():
    torch.manual_seed(1)
    proposer = DiffusionProposer(4, 3, num_candidates=5, horizon=8, num_inference_steps=3)
    alone = ProposerAlone(proposer, replan_every=8, action_key=("agents", "action"))
    obs = torch.randn(2, 3, 4)  # [B=2 scenes, N=3 AUVs, obs]; step_count per scene [B, 1]
    first = _decide(alone, obs, [0, 0])
    second = _decide(alone, obs, [1, 0])  # scene 1's episode restarted
    assert second["proposer", "plan_step"].tolist() == [[1, 1, 1], [0, 0, 0]]
    torch.testing.assert_close(second["proposer", "plan"][0], first["proposer", "plan"][0])
    assert not torch.equal(second["proposer", "plan"][1], first["proposer", "plan"][1])
    torch.testing.assert_close(second["agents", "action"][0], first["proposer", "plan"][0, :, 1])


def test_replan_every_is_checked():
    proposer = DiffusionProposer(4, 2, horizon=4)
    with pytest.raises(ValueError, match=r"replan_every must be an int in \[1, 4\]"):
        ProposerAlone(proposer, replan_every=5)
    with pytest.raises(KeyError, match="step_count"):
        ProposerAlone(proposer, replan_every=2)(TensorDict({"observation": torch.zeros(1, 4)}, [1]))
