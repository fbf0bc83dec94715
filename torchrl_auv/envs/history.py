"""A transform that keeps the last ``L`` observations **and** actions (the paper's eq. 5).

TorchRL's :class:`~torchrl.envs.transforms.CatFrames` stacks observations only; the diffusion
proposer is conditioned on past observations *and* past actions,

.. math::

    s_t = [o_t,\\ \\mathrm{Flatten}(H_{t-L:t-1}),\\ \\mathrm{Flatten}(A_{t-L:t-1})],

so this transform carries both, plus a validity mask for the first ``L`` decisions of an
episode.
"""

from __future__ import annotations

import torch
from tensordict import NestedKey, TensorDictBase, unravel_key
from torchrl.data import Binary, Composite, Unbounded
from torchrl.envs.transforms import Transform

__all__ = ["StateActionHistory", "history_key_for"]


def history_key_for(observation_key: NestedKey) -> tuple[str, ...]:
    """The default history key: a ``"history"`` sibling of the observation key.

    >>> history_key_for("observation")
    ('history',)
    >>> history_key_for(("agents", "observation"))
    ('agents', 'history')
    """
    key = unravel_key(observation_key)
    key = (key,) if isinstance(key, str) else tuple(key)
    return (*key[:-1], "history")


class StateActionHistory(Transform):
    """Keep the last ``length`` (observation, action) pairs under ``history_key``.

    Key contract: reads ``observation_key`` and ``action_key`` at time ``t`` and writes, into the
    data at ``t + 1``, ``history_key + ("observation",)`` shaped ``[*B, length, obs]``,
    ``history_key + ("action",)`` shaped ``[*B, length, act]`` and ``history_key + ("mask",)``
    shaped ``[*B, length]`` (``True`` where the entry holds real data). Entries are oldest first:
    index ``-1`` is the most recent pair ``(o_{t}, a_{t})``. After a reset every entry is zero
    and masked out; partial resets of batched envs clear only the reset elements (TorchRL
    merges the reset data with the mask).

    Works for single-agent (``obs [*B, d]``) and multi-agent layouts
    (``("agents", "observation")`` shaped ``[*B, n_agents, d]``): the history gets a time
    dimension just before the feature dimension.

    Args:
        length: number of past pairs ``L`` (the paper uses 10).
        observation_key: the observation entry to record.
        action_key: the action entry to record.
        history_key: where to write; defaults to a ``"history"`` sibling of ``observation_key``.

    Examples:
        >>> from torchrl.envs import GymEnv, TransformedEnv
        >>> env = TransformedEnv(GymEnv("Pendulum-v1"), StateActionHistory(3))
        >>> td = env.rollout(5)
        >>> td["history", "observation"].shape, td["history", "action"].shape
        (torch.Size([5, 3, 3]), torch.Size([5, 3, 1]))
        >>> td["history", "mask"][:, -1].tolist()  # nothing recorded before the first step
        [False, True, True, True, True]
    """

    def __init__(
        self,
        length: int = 10,
        *,
        observation_key: NestedKey = "observation",
        action_key: NestedKey = "action",
        history_key: NestedKey | None = None,
    ) -> None:
        if not isinstance(length, int) or length < 1:
            raise ValueError(f"length must be a positive int, got {length!r}")
        self.length = length
        self.observation_key = unravel_key(observation_key)
        self.action_key = unravel_key(action_key)
        base = history_key_for(observation_key) if history_key is None else history_key
        base = unravel_key(base)
        base = (base,) if isinstance(base, str) else tuple(base)
        self.history_key = base
        self.history_obs_key = (*base, "observation")
        self.history_action_key = (*base, "action")
        self.history_mask_key = (*base, "mask")
        super().__init__(
            in_keys=[self.observation_key, self.action_key],
            out_keys=[self.history_obs_key, self.history_action_key, self.history_mask_key],
        )

    # -- specs ---------------------------------------------------------------------------
    def transform_observation_spec(self, observation_spec: Composite) -> Composite:
        obs_spec = observation_spec[self.observation_key]
        action_spec = self.parent.full_action_spec[self.action_key]
        if len(obs_spec.shape) == 0 or len(action_spec.shape) == 0:
            raise ValueError(
                f"observation_key {self.observation_key} and action_key {self.action_key} need a "
                "feature dimension; concatenate scalar entries first (e.g. with CatTensors)"
            )
        lead = obs_spec.shape[:-1]
        obs_dim, act_dim = obs_spec.shape[-1], action_spec.shape[-1]
        if action_spec.shape[:-1] != lead:
            raise ValueError(
                f"action_key {self.action_key} has leading shape {tuple(action_spec.shape[:-1])}, "
                f"expected the observation's {tuple(lead)}"
            )
        device = obs_spec.device
        observation_spec[self.history_obs_key] = Unbounded(
            shape=(*lead, self.length, obs_dim), dtype=obs_spec.dtype, device=device
        )
        observation_spec[self.history_action_key] = Unbounded(
            shape=(*lead, self.length, act_dim), dtype=action_spec.dtype, device=device
        )
        observation_spec[self.history_mask_key] = Binary(
            n=self.length, shape=(*lead, self.length), dtype=torch.bool, device=device
        )
        return observation_spec

    # -- data ----------------------------------------------------------------------------
    def _empty_history(self, observation: torch.Tensor, action_shape: torch.Size, action_dtype):
        lead = observation.shape[:-1]
        return (
            observation.new_zeros((*lead, self.length, observation.shape[-1])),
            torch.zeros(
                (*lead, self.length, action_shape[-1]),
                dtype=action_dtype,
                device=observation.device,
            ),
            torch.zeros((*lead, self.length), dtype=torch.bool, device=observation.device),
        )

    def _reset(
        self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase
    ) -> TensorDictBase:
        observation = tensordict_reset.get(self.observation_key)
        action_spec = self.parent.full_action_spec[self.action_key]
        obs_h, act_h, mask = self._empty_history(observation, action_spec.shape, action_spec.dtype)
        tensordict_reset.set(self.history_obs_key, obs_h)
        tensordict_reset.set(self.history_action_key, act_h)
        tensordict_reset.set(self.history_mask_key, mask)
        return tensordict_reset

    def _step(self, tensordict: TensorDictBase, next_tensordict: TensorDictBase) -> TensorDictBase:
        observation = tensordict.get(self.observation_key)
        action = tensordict.get(self.action_key)
        obs_h = tensordict.get(self.history_obs_key, None)
        if obs_h is None:  # a step from a tensordict that never went through reset
            obs_h, act_h, mask = self._empty_history(observation, action.shape, action.dtype)
        else:
            act_h = tensordict.get(self.history_action_key)
            mask = tensordict.get(self.history_mask_key)
        next_tensordict.set(
            self.history_obs_key, torch.cat([obs_h[..., 1:, :], observation.unsqueeze(-2)], -2)
        )
        next_tensordict.set(
            self.history_action_key,
            torch.cat([act_h[..., 1:, :], action.to(act_h.dtype).unsqueeze(-2)], -2),
        )
        next_tensordict.set(
            self.history_mask_key,
            torch.cat([mask[..., 1:], torch.ones_like(mask[..., :1])], -1),
        )
        return next_tensordict

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        raise RuntimeError(
            "StateActionHistory works inside an environment (TransformedEnv); to rebuild "
            "histories offline, use the recorded history entries of a rollout"
        )
