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

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import torch

__all__ = ["FORMS", "PRIORS", "LyapunovSpec", "LyapunovSpecState", "lyapunov_value"]

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


_FORM_NAMES, _PRIOR_NAMES = sorted(FORMS), sorted(PRIORS)


def _encode(spec: LyapunovSpec, device: torch.device | str | None = None) -> torch.Tensor:
    """``[form index, prior index (-1: none), alpha, prior weight]`` (float64, on ``device``)."""
    prior = -1 if spec.prior is None else _PRIOR_NAMES.index(spec.prior)
    return torch.tensor(
        [_FORM_NAMES.index(spec.form), prior, spec.alpha, spec.prior_weight],
        dtype=torch.float64,
        device=device,
    )


def _decode(code: torch.Tensor, like: LyapunovSpec) -> LyapunovSpec:
    """The spec of ``code`` (:func:`_encode`), the other fields (prior indices) from ``like``."""
    form, prior, alpha, weight = code.tolist()
    return dataclasses.replace(
        like,
        form=_FORM_NAMES[int(form)],
        alpha=alpha,
        prior=None if prior < 0 else _PRIOR_NAMES[int(prior)],
        prior_weight=weight,
    )


class LyapunovSpecState(torch.nn.Module):
    """The Lyapunov spec in force, as one module that the loss owning it and every selector
    ranking with it hold (the same object: setting it once sets it for all).

    Its form, prior, alpha and prior weight are the float64 buffer ``code``, so the spec is
    part of the state dict of every module holding it: it is saved and restored with the
    loss's weights (a checkpoint), and travels with the policy's weights to collector worker
    processes and Ray actors, whose copies follow the buffer when it is overwritten in place.
    The prior's observation indices are not in the buffer: they stay the constructor's.

    Examples:
        >>> state = LyapunovSpecState(LyapunovSpec(form="log", alpha=0.2))
        >>> state.spec = LyapunovSpec(form="squared", alpha=0.25)
        >>> copy = LyapunovSpecState()
        >>> _ = copy.load_state_dict(state.state_dict())
        >>> copy.spec.form, copy.spec.alpha
        ('squared', 0.25)
        >>> other = LyapunovSpecState(LyapunovSpec(form="log", alpha=0.3))
        >>> _ = copy.code.copy_(other.code)  # overwritten in place, as a collector does
        >>> copy.spec.form, copy.spec.alpha
        ('log', 0.3)
    """

    def __init__(self, spec: LyapunovSpec | None = None) -> None:
        super().__init__()
        spec = LyapunovSpec() if spec is None else spec
        self._check(spec)
        self._spec = spec
        self.register_buffer("code", _encode(spec))

    @staticmethod
    def _check(spec) -> None:
        if not isinstance(spec, LyapunovSpec):
            raise ValueError(f"spec must be a LyapunovSpec, got {type(spec).__name__}")

    @property
    def spec(self) -> LyapunovSpec:
        """The spec of the buffer (decoded again only when the buffer changed)."""
        if not torch.equal(self.code, _encode(self._spec, self.code.device)):
            self._spec = _decode(self.code, self._spec)
        return self._spec

    @spec.setter
    def spec(self, value: LyapunovSpec) -> None:
        self._check(value)
        self._spec = value
        with torch.no_grad():
            self.code.copy_(_encode(value))

    @property
    def last_set(self) -> LyapunovSpec:
        """The spec as last set or loaded, without reading the buffer (for code that
        ``torch.compile`` traces: the loss's forward)."""
        return self._spec

    def _load_from_state_dict(self, state_dict, prefix, *args, **kwargs) -> None:
        if prefix + "code" not in state_dict:  # a state saved before the spec was in it
            return
        super()._load_from_state_dict(state_dict, prefix, *args, **kwargs)
        self._spec = _decode(self.code, self._spec)


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
