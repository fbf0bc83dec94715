r"""``DenoisingLoss``: the epsilon-prediction loss of the diffusion proposer (paper eq. 9).

.. math::

    \mathcal L(\theta) = \mathbb E_{t, x_0, \epsilon}
        \big\|\epsilon - \epsilon_\theta(\sqrt{\bar\alpha_t} x_0 + \sqrt{1-\bar\alpha_t}\,\epsilon,
        t, s)\big\|^2,

with :math:`t` uniform in :math:`\{0, \dots, T-1\}`, :math:`x_0` the demonstrated action chunk
normalised to :math:`[-1, 1]` and :math:`s` the proposer's conditioning state (standardised by
the proposer). Chunk steps past the end of an episode (``action_chunk_mask`` false) are left
out of the mean. With per-sample weights :math:`w \ge 0` (``sample_weight``, e.g. advantage
weights over the proposer's own candidates when it is fine-tuned) the mean is weighted:
:math:`\sum_{i,h} w_i m_{ih} e_{ih} / \sum_{i,h} w_i m_{ih}`, which is the plain loss when every
:math:`w_i = 1`.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from tensordict import NestedKey, TensorDict, TensorDictBase
from torchrl.objectives.common import LossModule

from torchrl_auv.modules import DiffusionProposer

__all__ = ["DenoisingLoss"]


class DenoisingLoss(LossModule):
    """Epsilon-prediction MSE for a :class:`~torchrl_auv.modules.DiffusionProposer`.

    The proposer is held as a plain submodule: its parameters are the loss's parameters, so
    an optimiser over ``loss.parameters()`` trains the very module the user samples from.

    Keys (``set_keys``): ``action`` (the clean chunk ``[*B, H, A]``, default
    ``"action_chunk"``), ``action_mask`` (``[*B, H]``, default ``"action_chunk_mask"``, used
    when present), ``sample_weight`` (``[*B]``, >= 0, default ``"sample_weight"``, used when
    present: a weighted mean over the samples), ``state`` (default ``None``: the proposer
    builds its state from its own keys; set a key to read a flat state instead). Output:
    ``loss_denoising``.

    Args:
        proposer: the proposer to train.
        generator: optional source of the timesteps and noise (default: the global RNG).
        ema_decay: keep an exponential moving average of the noise model's weights
            (:meth:`update_ema` after each optimiser step).

    Examples:
        >>> proposer = DiffusionProposer(4, 2, horizon=8)
        >>> loss = DenoisingLoss(proposer)
        >>> td = TensorDict({"observation": torch.zeros(16, 4),
        ...                  "action_chunk": torch.zeros(16, 8, 2)}, batch_size=[16])
        >>> out = loss(td)
        >>> out["loss_denoising"].backward()
        >>> list(out.keys())
        ['loss_denoising']
    """

    @dataclass
    class _AcceptedKeys:
        """Keys read by the loss.

        Attributes:
            action: clean action chunk ``[*B, H, A]``.
            action_mask: validity of each chunk step ``[*B, H]`` (optional in the data).
            sample_weight: weight of each sample ``[*B]`` (optional in the data).
            state: flat conditioning state, or ``None`` to let the proposer build it.
        """

        action: NestedKey = "action_chunk"
        action_mask: NestedKey = "action_chunk_mask"
        sample_weight: NestedKey = "sample_weight"
        state: NestedKey | None = None

    default_keys = _AcceptedKeys

    def __init__(
        self,
        proposer: DiffusionProposer,
        *,
        generator: torch.Generator | None = None,
        ema_decay: float | None = None,
    ) -> None:
        if not isinstance(proposer, DiffusionProposer):
            raise ValueError(f"proposer must be a DiffusionProposer, got {type(proposer).__name__}")
        super().__init__()
        self.proposer = proposer
        self.generator = generator
        if ema_decay is not None:
            proposer.enable_ema(ema_decay)

    def update_ema(self) -> None:
        """Move the proposer's EMA weights (call after each optimiser step when ``ema_decay``
        was given); sampling uses them only once ``proposer.use_ema = True``."""
        self.proposer.update_ema()

    def _forward_value_estimator_keys(self, **kwargs) -> None:
        pass

    @property
    def in_keys(self) -> list[NestedKey]:
        state = [self.tensor_keys.state] if self.tensor_keys.state is not None else []
        return [*(state or self.proposer.in_keys), self.tensor_keys.action]

    @property
    def out_keys(self) -> list[str]:
        return ["loss_denoising"]

    def forward(self, tensordict: TensorDictBase) -> TensorDict:
        proposer = self.proposer
        if self.tensor_keys.state is None:
            state = proposer.build_state(tensordict)
        else:
            state = tensordict.get(self.tensor_keys.state)
        action = tensordict.get(self.tensor_keys.action, None)
        expected = (proposer.horizon, proposer.action_dim)
        if action is None or tuple(action.shape[-2:]) != expected:
            raise ValueError(
                f"action key {self.tensor_keys.action!r} must hold chunks shaped [*B, "
                f"{expected[0]}, {expected[1]}], got "
                f"{None if action is None else tuple(action.shape)}"
            )
        x0 = proposer.normalize(action).clamp(-1.0, 1.0)
        batch = x0.shape[:-2]
        kw = {"generator": self.generator, "device": x0.device}
        t = torch.randint(0, proposer.schedule.num_train_steps, batch, **kw)
        eps = torch.randn(x0.shape, dtype=x0.dtype, **kw)
        x_t = proposer.schedule.add_noise(x0, eps, t)
        error = (proposer.predict_noise(x_t, t, state) - eps).square().mean(-1)  # [*B, H]
        mask = tensordict.get(self.tensor_keys.action_mask, None)
        sample_weight = tensordict.get(self.tensor_keys.sample_weight, None)
        if mask is None and sample_weight is None:
            loss = error.mean()
        else:
            weight = torch.ones_like(error) if mask is None else mask.to(error.dtype)
            if sample_weight is not None:
                if tuple(sample_weight.shape) != tuple(batch):
                    raise ValueError(
                        f"sample_weight key {self.tensor_keys.sample_weight!r} must be shaped "
                        f"{list(batch)} (one weight per chunk), got {list(sample_weight.shape)}"
                    )
                weight = weight * sample_weight.to(error.dtype).unsqueeze(-1)
            floor = 1.0 if sample_weight is None else torch.finfo(error.dtype).tiny
            loss = (error * weight).sum() / weight.sum().clamp_min(floor)
        return TensorDict({"loss_denoising": loss}, batch_size=[])
