r"""The Lyapunov function forms: maps from a critic's raw output to :math:`L \ge 0`.

A Lyapunov critic outputs raw features :math:`z(s, a)` (``[*B, m]``); a form turns them into the
Lyapunov value :math:`L(s, a) \ge 0` (``[*B, 1]``). An optional state-shaping prior adds a
quadratic term :math:`w \lVert o_{I} \rVert^2` on named observation entries, so that an advisor
can move the function from a position-based to a velocity-oriented shape (paper §III-C).

=============  =====================================  ==============================================
name           :math:`L` from :math:`z`               behaviour (paper §IV, Fig. 11)
=============  =====================================  ==============================================
``softplus``   :math:`\log(1 + e^{z_1})` (eq. 21)      mild stabilisation, wider uncertainty
``squared``    :math:`\sum_i z_i^2` (LAC)              strong corrections, fast, tight contraction
``log``        :math:`\log(1 + \sum_i z_i^2)`          gentle far from the goal (grows slowly),
                                                       relaxes near it (quadratic at 0)
=============  =====================================  ==============================================
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import torch

__all__ = ["FORMS", "PRIORS", "LyapunovSpec", "lyapunov_value"]

#: form name -> one-line description (also used in the advisor's prompt)
FORMS: dict[str, str] = {
    "softplus": "softplus of the first raw output (paper eq. 21): mild stabilisation, wider "
    "uncertainty",
    "squared": "sum of squares of the raw outputs (LAC): strong corrections, fast and tight "
    "contraction",
    "log": "log(1 + sum of squares): gentle far from the goal, relaxes near convergence",
}
#: prior name -> description
PRIORS: dict[str, str] = {
    "position": "adds w * |position-like observation entries|^2 (errors to the reference)",
    "velocity": "adds w * |velocity-like observation entries|^2 (rates, speed errors)",
}
#: alpha must lie in this closed range (the advisor's range)
ALPHA_RANGE = (0.05, 0.5)


@dataclass(frozen=True)
class LyapunovSpec:
    """Which Lyapunov function to use: form, optional prior and stability weight.

    Attributes:
        form: a name of :data:`FORMS`.
        prior: ``None`` or a name of :data:`PRIORS`.
        alpha: the stability weight :math:`\\alpha > 0` of the decrease condition.
        prior_weight: :math:`w \\ge 0` of the prior's quadratic term.
        prior_indices: observation entries per prior name (default: the tracking env's
            layout: position-like = depth and heading errors, velocity-like = speed error,
            body velocities and rates).

    Examples:
        >>> LyapunovSpec(form="log", alpha=0.2).form
        'log'
        >>> LyapunovSpec(form="cubic")
        Traceback (most recent call last):
            ...
        ValueError: form must be one of ['log', 'softplus', 'squared'], got 'cubic'
    """

    form: str = "softplus"
    prior: str | None = None
    alpha: float = 0.1
    prior_weight: float = 1.0
    prior_indices: Mapping[str, Sequence[int]] = field(
        default_factory=lambda: {"position": (0, 1), "velocity": (3, 4, 5, 6, 7, 8, 9)}
    )

    def __post_init__(self) -> None:
        if self.form not in FORMS:
            raise ValueError(f"form must be one of {sorted(FORMS)}, got {self.form!r}")
        if self.prior is not None and self.prior not in PRIORS:
            raise ValueError(f"prior must be None or one of {sorted(PRIORS)}, got {self.prior!r}")
        if not (isinstance(self.alpha, int | float) and math.isfinite(self.alpha)) or not (
            self.alpha > 0
        ):
            raise ValueError(f"alpha must be a finite number > 0, got {self.alpha!r}")
        if not self.prior_weight >= 0:
            raise ValueError(f"prior_weight must be >= 0, got {self.prior_weight}")
        if self.prior is not None and self.prior not in self.prior_indices:
            raise ValueError(f"prior_indices must name the entries of prior {self.prior!r}")


def lyapunov_value(
    raw: torch.Tensor, spec: LyapunovSpec, observation: torch.Tensor | None = None
) -> torch.Tensor:
    """:math:`L \\ge 0`, ``[*B, 1]``, from raw critic outputs ``[*B, m]`` (module docstring).

    Args:
        raw: the critic's raw output.
        spec: form and prior.
        observation: ``[*B, d]``, needed when ``spec.prior`` is set.

    Examples:
        >>> raw = torch.tensor([[0.0, 0.0], [3.0, 4.0]])
        >>> lyapunov_value(raw, LyapunovSpec(form="squared")).squeeze(-1).tolist()
        [0.0, 25.0]
        >>> round(lyapunov_value(raw, LyapunovSpec(form="log"))[1].item(), 4)  # log(26)
        3.2581
    """
    if spec.form == "softplus":
        value = torch.nn.functional.softplus(raw[..., :1])
    elif spec.form == "squared":
        value = raw.square().sum(-1, keepdim=True)
    else:
        value = torch.log1p(raw.square().sum(-1, keepdim=True))
    if spec.prior is not None:
        if observation is None:
            raise ValueError(f"observation is required for the {spec.prior!r} prior")
        index = torch.as_tensor(list(spec.prior_indices[spec.prior]), device=observation.device)
        entries = observation.index_select(-1, index)
        value = value + spec.prior_weight * entries.square().sum(-1, keepdim=True).to(value.dtype)
    return value
