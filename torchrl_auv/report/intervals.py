"""Intervals over training runs, as a referee asks for them: the ``rliable`` package's
stratified bootstrap (Agarwal et al., "Deep RL at the Edge of the Statistical Precipice",
NeurIPS 2021).

Scores are one number per training run (a seed's final evaluation: SDR, cost, ...).
:func:`interval` gives a statistic over the runs (the mean, or the interquartile mean ``iqm``,
the mean of the middle 50 % of runs, which one outlying seed moves less) with its percentile
bootstrap confidence interval; :func:`probability_of_improvement` the probability that a run
of ``x`` scores higher than a run of ``y`` (ties count a half; the Mann-Whitney statistic
over pairs of runs) with its interval. For a metric where lower is better (a cost), pass the
negated scores. The bootstrap is seeded (``seed``; numpy's global generator is seeded for
the call and restored after, as rliable 1.2 draws from it): the same scores and seed give the
same interval.

``rliable`` (and ``arch``, which it imports; ``arch`` 7.2 needs ``pandas < 3``) is an extra:
``pip install 'torchrl-auv[stats]'``; the README's set-up installs it.

Examples:
    >>> ssn = [9.0, 11.0, 10.0, 12.0, 8.0]  # five seeds
    >>> mean = interval(ssn, reps=500)
    >>> mean.point, mean.low <= 10.0 <= mean.high
    (10.0, True)
    >>> probability_of_improvement([5.0, 6.0], [1.0, 2.0], reps=500).point
    1.0
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["STATISTICS", "Interval", "interval", "probability_of_improvement"]

#: the statistics :func:`interval` takes
STATISTICS = ("mean", "iqm")


def _rliable():
    try:
        from rliable import library, metrics
    except ImportError as error:  # arch's import fails under pandas 3 as well
        raise ImportError(
            "intervals need the rliable package (and pandas < 3 for its arch dependency): "
            "pip install 'torchrl-auv[stats]'"
        ) from error
    return library, metrics


@dataclass(frozen=True)
class Interval:
    """A point estimate and its confidence interval ``[low, high]``."""

    point: float
    low: float
    high: float

    def __contains__(self, value: float) -> bool:
        return self.low <= value <= self.high

    def __str__(self) -> str:
        return f"{self.point:.3g} [{self.low:.3g}, {self.high:.3g}]"


def _runs(name: str, scores: Sequence[float]) -> np.ndarray:
    array = np.asarray(scores, dtype=np.float64).reshape(-1)
    if array.size < 1 or not np.isfinite(array).all():
        raise ValueError(f"{name} must be one or more finite scores (one per run), got {scores!r}")
    return array[:, None]  # rliable's [runs, tasks]


def _check(statistic: str, confidence: float, reps: int) -> None:
    if statistic not in STATISTICS:
        raise ValueError(f"statistic must be one of {STATISTICS}, got {statistic!r}")
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must be in (0, 1), got {confidence!r}")
    if isinstance(reps, bool) or not isinstance(reps, int) or reps < 100:
        raise ValueError(f"reps must be an int >= 100, got {reps!r}")


def _estimate(score_dict: dict, func, confidence: float, reps: int, seed: int) -> Interval:
    library, _ = _rliable()
    # rliable 1.2's StratifiedBootstrap draws from numpy's global generator whatever
    # random_state says: seed that too, and give the caller's state back
    state = np.random.get_state()  # noqa: NPY002 (rliable draws from the legacy global)
    np.random.seed(seed)  # noqa: NPY002
    try:
        with warnings.catch_warnings():  # rliable hands arch a RandomState; arch 7 deprecates it
            warnings.filterwarnings("ignore", "random_state is deprecated", FutureWarning)
            points, intervals = library.get_interval_estimates(
                score_dict,
                func,
                reps=reps,
                confidence_interval_size=confidence,
                random_state=np.random.RandomState(seed),
            )
    finally:
        np.random.set_state(state)  # noqa: NPY002
    (key,) = points
    low, high = np.asarray(intervals[key]).reshape(2)
    return Interval(float(np.asarray(points[key]).reshape(-1)[0]), float(low), float(high))


def interval(
    scores: Sequence[float],
    statistic: str = "mean",
    *,
    confidence: float = 0.95,
    reps: int = 2000,
    seed: int = 0,
) -> Interval:
    """``statistic`` (``"mean"`` or ``"iqm"``) of ``scores`` (one per run) and its
    ``confidence`` percentile-bootstrap interval over runs (``reps`` resamples)."""
    _check(statistic, confidence, reps)
    _, metrics = _rliable()
    aggregate = metrics.aggregate_mean if statistic == "mean" else metrics.aggregate_iqm
    runs = _runs("scores", scores)
    return _estimate({"x": runs}, lambda x: np.array([aggregate(x)]), confidence, reps, seed)


def probability_of_improvement(
    x: Sequence[float],
    y: Sequence[float],
    *,
    confidence: float = 0.95,
    reps: int = 2000,
    seed: int = 0,
) -> Interval:
    """P(a run of ``x`` scores higher than a run of ``y``) with its ``confidence`` interval
    (both resampled over runs, independently)."""
    _check("mean", confidence, reps)
    _, metrics = _rliable()
    pair = (_runs("x", x), _runs("y", y))

    def improvement(a, b):
        return np.array([metrics.probability_of_improvement(a, b)])

    return _estimate({"x,y": pair}, improvement, confidence, reps, seed)
