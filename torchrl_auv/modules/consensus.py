r"""Which of the proposer's K candidates to execute when no critic chooses: the medoid.

The proposer acting alone (the paper's "Diffusion" framework) has no critic to filter its
candidates. Executing one i.i.d. sample (candidate 0) executes the sampler's spread too: a
diffusion model trained on a deterministic expert still spreads its samples where it is
unsure, and in a strong current one stray heading sample sends the vehicle off course.
The medoid of the K chunks, the candidate with the smallest summed distance to the others,
is a consensus of the samples (a robust estimate of the distribution's mode that is itself
one of the samples, so it is always feasible, unlike the mean of two modes):

.. math::

    k^\star = \arg\min_k \sum_{j} \lVert \hat a^{(k)} - \hat a^{(j)} \rVert_2,

with each chunk flattened (``H x A`` action units). Measured in the very extreme sea
(``recipes/README.md``): the same pretrained proposer costs 5.35 per AUV-decision and leaves
the area in one scene of four executing candidate 0, and 1.93 with no exit executing the
medoid of K = 5; more candidates make a better medoid (K = 10 did better than K = 5 on every
artefact tried).

Examples:
    >>> candidates = torch.tensor([[[[0.0]], [[0.1]], [[0.9]], [[0.2]]]])  # [B=1, K=4, H=1, A=1]
    >>> medoid_index(candidates)
    tensor([1])
    >>> pick_candidate(candidates, "first").flatten().tolist()
    [0.0]
"""

from __future__ import annotations

import torch
from tensordict import NestedKey, TensorDictBase
from tensordict.nn import TensorDictModuleBase

__all__ = ["CANDIDATE_PICKS", "ProposerAlone", "medoid_index", "pick_candidate"]

#: ``medoid``: the consensus candidate (:func:`medoid_index`); ``first``: candidate 0 (one
#: sample of the proposer).
CANDIDATE_PICKS = ("medoid", "first")
#: Where :class:`ProposerAlone` with ``replan_every > 1`` writes the chunk it executes and the
#: executed action's index in it.
PLAN_KEY, PLAN_STEP_KEY = ("proposer", "plan"), ("proposer", "plan_step")


def medoid_index(candidates: torch.Tensor) -> torch.Tensor:
    """The index ``[*B]`` of the medoid of candidates ``[*B, K, H, A]`` (ties: the lowest)."""
    if candidates.dim() < 3:
        raise ValueError(f"candidates must be shaped [*B, K, H, A], got {tuple(candidates.shape)}")
    flat = candidates.flatten(-2)  # [*B, K, H*A]
    distance = (flat.unsqueeze(-2) - flat.unsqueeze(-3)).norm(dim=-1)  # [*B, K, K]
    return distance.sum(-1).argmin(-1)


def pick_candidate(candidates: torch.Tensor, pick: str = "medoid") -> torch.Tensor:
    """The chunk ``[*B, H, A]`` of ``candidates`` ``[*B, K, H, A]`` chosen by ``pick`` (one
    of :data:`CANDIDATE_PICKS`)."""
    if pick not in CANDIDATE_PICKS:
        raise ValueError(f"pick must be one of {CANDIDATE_PICKS}, got {pick!r}")
    if pick == "first":
        return candidates[..., 0, :, :]
    index = medoid_index(candidates)
    gather = index[..., None, None, None].expand(*index.shape, 1, *candidates.shape[-2:])
    return torch.gather(candidates, -3, gather).squeeze(-3)


class ProposerAlone(TensorDictModuleBase):
    """The proposer acting alone: runs ``proposer`` and writes the first action of the
    candidate chosen by ``pick`` (:func:`pick_candidate`) to ``action_key``; with
    ``replan_every = n > 1`` it then executes the chunk's next actions for ``n`` decisions
    in all before it plans again (receding-horizon execution of action chunks, as in
    Diffusion Policy, Chi et al. 2023).

    Re-planning every decision lets the pick switch between the modes of the proposer's
    distribution from one decision to the next (turn left, then right, then left: a heading
    that never commits); executing a few actions of one chunk commits to it. Each row
    (scene, AUV) keeps its own plan and plans anew when its episode restarts
    (``step_count_key`` is 0); the chunk's length ``H`` bounds ``n``.

    Args:
        proposer: a :class:`~torchrl_auv.modules.DiffusionProposer`.
        pick: ``"medoid"`` (the consensus candidate, default) or ``"first"`` (candidate 0,
            one i.i.d. sample).
        action_key: where the action goes (the env's action key).
        num_candidates: how many candidates to draw for the pick (``None``: the proposer's
            own ``num_candidates``). The medoid of more samples is a better estimate of the
            mode; the proposer's K for a critic's selection stays as it is.
        replan_every: decisions per plan (``1 <= n <= H``; 1: re-plan every decision). With
            ``n > 1`` the module is stateful (one plan per row of the batch it last saw) and
            writes the chunk it executes to ``("proposer", "plan")`` ``[*B, H, A]`` and the
            action's index in it to ``("proposer", "plan_step")`` ``[*B]`` instead of the
            candidates.
        step_count_key: the env's decision counter (``[*B', 1]``, broadcast over trailing
            agent dims; TorchRL's ``StepCounter`` writes one), read when ``n > 1``.

    Examples:
        >>> from tensordict import TensorDict
        >>> from torchrl_auv.modules import DiffusionProposer
        >>> proposer = DiffusionProposer(4, 3, num_candidates=3, num_inference_steps=2)
        >>> td = ProposerAlone(proposer, num_candidates=7)(
        ...     TensorDict({"observation": torch.zeros(2, 4)}, [2]))
        >>> td["action"].shape, td["proposer", "candidates"].shape
        (torch.Size([2, 3]), torch.Size([2, 7, 8, 3]))
        >>> chunked = ProposerAlone(proposer, replan_every=4)
        >>> steps = [chunked(TensorDict({"observation": torch.zeros(2, 4),
        ...                              "step_count": torch.full((2, 1), t)}, [2]))
        ...          for t in range(5)]
        >>> [td["proposer", "plan_step"].tolist() for td in steps]
        [[0, 0], [1, 1], [2, 2], [3, 3], [0, 0]]
    """

    def __init__(
        self,
        proposer,
        pick: str = "medoid",
        action_key: NestedKey = "action",
        *,
        num_candidates: int | None = None,
        replan_every: int = 1,
        step_count_key: NestedKey = "step_count",
    ) -> None:
        super().__init__()
        if pick not in CANDIDATE_PICKS:
            raise ValueError(f"pick must be one of {CANDIDATE_PICKS}, got {pick!r}")
        if num_candidates is not None and not (
            isinstance(num_candidates, int) and num_candidates >= 1
        ):
            raise ValueError(f"num_candidates must be an int >= 1, got {num_candidates!r}")
        horizon = proposer.horizon
        if not (isinstance(replan_every, int) and 1 <= replan_every <= horizon):
            raise ValueError(
                f"replan_every must be an int in [1, {horizon}] (the proposer's "
                f"horizon), got {replan_every!r}"
            )
        self.proposer, self.pick, self.action_key = proposer, pick, action_key
        self.num_candidates, self.replan_every = num_candidates, replan_every
        self.step_count_key = step_count_key
        self.in_keys = list(proposer.in_keys)
        if replan_every == 1:
            self.out_keys = [*proposer.out_keys, action_key]
        else:
            self.in_keys.append(step_count_key)
            self.out_keys = [PLAN_KEY, PLAN_STEP_KEY, action_key]
        self._plan: torch.Tensor | None = None  # [*B, H, A], the chunk each row executes
        self._step: torch.Tensor | None = None  # [*B], the index of its next action

    def _candidates(self, tensordict: TensorDictBase) -> torch.Tensor:
        proposer = self.proposer
        if self.num_candidates is None:
            return proposer(tensordict).get(proposer.candidates_key)
        candidates, _ = proposer.sample(
            proposer.build_state(tensordict),
            num_candidates=self.num_candidates,
            generator=proposer.generator,
        )
        tensordict.set(proposer.candidates_key, candidates)
        tensordict.set(proposer.first_actions_key, candidates[..., 0, :])
        return candidates

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        if self.replan_every > 1:
            return self._forward_chunked(tensordict)
        chunk = pick_candidate(self._candidates(tensordict), self.pick)
        return tensordict.set(self.action_key, chunk[..., 0, :])

    def _forward_chunked(self, tensordict: TensorDictBase) -> TensorDictBase:
        batch = tensordict.get(self.proposer.state_key).shape[:-1]
        count = tensordict.get(self.step_count_key, None)
        if count is None:
            raise KeyError(
                f"replan_every > 1 reads the decision counter {self.step_count_key!r} "
                "(step_count_key), absent from the input; add TorchRL's StepCounter "
                "to the env"
            )
        count = count.reshape(*count.shape[:-1], *(1,) * (len(batch) - count.dim() + 1))
        restarted = (count == 0).expand(batch)
        if self._plan is None or self._plan.shape[:-2] != batch:
            self._plan = None
            self._step = torch.zeros(batch, dtype=torch.long, device=count.device)
            due = torch.ones(batch, dtype=torch.bool, device=count.device)
        else:
            due = restarted | (self._step >= self.replan_every)
        if due.any():
            work = tensordict.select(*self.proposer.in_keys, strict=False)
            chunk = pick_candidate(self._candidates(work), self.pick)
            self._plan = (
                chunk
                if self._plan is None
                else torch.where(due[..., None, None], chunk, self._plan)
            )
            self._step = torch.where(due, torch.zeros_like(self._step), self._step)
        index = self._step[..., None, None].expand(*batch, 1, self._plan.shape[-1])
        tensordict.set(self.action_key, self._plan.gather(-2, index).squeeze(-2))
        tensordict.set(PLAN_KEY, self._plan.clone())
        tensordict.set(PLAN_STEP_KEY, self._step.clone())
        self._step = self._step + 1
        return tensordict
