r"""n-step returns for the Q critics: TorchRL's ``MultiStepTransform`` on the agents layout.

With ``optim.n_steps = n > 1`` (SAC and Diffusion+RL) each stored frame's reward is the
discounted sum of the next ``n`` rewards of its scene and its next state the state ``n``
decisions later (fewer where the episode ended first), so the TD target becomes

.. math::

    y_t = \sum_{i=0}^{m-1} \gamma^i r_{t+i} + \gamma^{m} (1 - d_{t+m-1})\, V'(s_{t+m}),
    \qquad m = \min(n, \text{decisions to the episode's end}),

and the critic leans on its own bootstrap only after ``m`` decisions of what was executed.
In the diffusion frameworks the executed policy is the selection, which stays near the prior
(the anchor), so these returns follow the policy that acts; in SAC they are off-policy by as
much as the buffer is old (no correction, as in RLPD/Rainbow-style n-step learners).

TorchRL's transform keeps the last ``n`` frames of every scene between batches, so the
windows run across batch boundaries (the collector's ``MultiStep`` post-processor would cut
them at each batch's end: 25 decisions per scene at the fast preset). Two choices of ours on
top of it:

- ``terminated`` and ``done`` are gathered from the window's last frame like the next state
  (the transform's own default keeps frame ``t``'s flags, which would bootstrap on the terminal
  state of an episode that ends within the window);
- the discount's exponent ``m`` is written per AUV (:data:`N_STEPS_KEY`, ``[*B, n_agents, 1]``)
  because TorchRL's TD(0) estimator raises ``gamma`` to it shaped as the reward;
  :func:`~torchrl_auv.training.make_sac_loss` points the estimator at it, so a loss fed
  one-step frames (no such key) keeps ``gamma``.

A resumed run starts the transform empty: the last ``n`` decisions of each scene before the
checkpoint are not stored.

Examples:
    >>> from torchrl_auv.training import make_env, select_for_replay
    >>> env = make_env("ideal", seed=0, num_envs=2)
    >>> returns = NStepReturns(3, gamma=0.99)
    >>> frames = select_for_replay(env.rollout(5), n_step=returns)  # [2 scenes x (5 - 3)]
    >>> frames.batch_size, frames[N_STEPS_KEY].flatten().tolist()[:2]
    (torch.Size([4]), [3, 3])
"""

from __future__ import annotations

from collections.abc import Mapping

from tensordict import TensorDictBase
from torchrl.envs.transforms import MultiStepTransform

from torchrl_auv.envs.keys import AGENT_COST, AGENT_REWARD, AGENT_STABILITY_COST
from torchrl_auv.training.keys import AGENTS

__all__ = ["N_STEPS_KEY", "N_STEP_KEYS", "NStepReturns", "n_step_from_config"]

#: the number of decisions a stored frame's return sums (the discount's exponent), per AUV
N_STEPS_KEY = (AGENTS, "steps_to_next_obs")
#: what the replay buffer stores beside :data:`~torchrl_auv.training.REPLAY_KEYS`
N_STEP_KEYS = (N_STEPS_KEY,)
#: the per-step signals summed over the window (the loss reads one of them)
SUMMED_KEYS = (AGENT_REWARD, AGENT_COST, AGENT_STABILITY_COST)
#: the scene's done flag ``[*B, T, 1]`` that delimits episodes
EPISODE_DONE = "done"


class NStepReturns:
    """Batches ``[*B, T]`` (time last, the same scenes every batch) to n-step frames
    ``[*B, T']``: a stateful ``MultiStepTransform`` (module docstring) plus :data:`N_STEPS_KEY`.

    Args:
        n_steps: decisions per return (>= 2; one-step frames need no transform).
        gamma: the critics' discount, in (0, 1].

    Calling it returns ``None`` while fewer than ``n_steps + 1`` decisions per scene have been
    seen; afterwards each call returns as many frames as it was given, ``n_steps`` decisions
    behind.
    """

    def __init__(self, n_steps: int, gamma: float) -> None:
        if isinstance(n_steps, bool) or not isinstance(n_steps, int) or n_steps < 2:
            raise ValueError(f"n_steps must be an integer >= 2, got {n_steps!r}")
        if not 0 < gamma <= 1:
            raise ValueError(f"gamma must be in (0, 1], got {gamma!r}")
        self.n_steps = n_steps
        self.transform = MultiStepTransform(
            n_steps,
            gamma,
            reward_keys=list(SUMMED_KEYS),
            done_key=EPISODE_DONE,
            done_keys=[EPISODE_DONE],  # the rest, terminated included, from the window's end
        )

    def __call__(self, data: TensorDictBase) -> TensorDictBase | None:
        if data.get(("next", EPISODE_DONE), None) is None:
            raise ValueError(
                f"n-step returns read the scene's done flag ('next', {EPISODE_DONE!r}), "
                "which the data lack"
            )
        out = self.transform.inv(data)
        if out is None:
            return None
        steps = out.get("steps_to_next_obs")  # [*B, T']
        per_agent = out.get(("next", *AGENT_REWARD)).shape  # [*B, T', n_agents, 1]
        out.set(N_STEPS_KEY, steps[..., None, None].expand(per_agent).clone())
        return out


def n_step_from_config(cfg: Mapping) -> NStepReturns | None:
    """:class:`NStepReturns` of ``cfg.optim.n_steps`` and ``cfg.optim.gamma``, or ``None`` for
    one-step returns (``n_steps`` 1, or no ``optim`` or ``n_steps`` in ``cfg``)."""
    optim = cfg.get("optim") or {}
    n_steps = optim.get("n_steps", 1)
    if n_steps == 1 and not isinstance(n_steps, bool):
        return None
    try:
        return NStepReturns(n_steps, float(optim["gamma"]))
    except ValueError as err:
        raise ValueError(f"optim.n_steps: {err}") from None
