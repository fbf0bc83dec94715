r"""A batched linear Kalman filter in torch (means ``[*B, n]``, covariances ``[*B, n, n]``).

Predict and update follow the textbook equations that ``filterpy.kalman.KalmanFilter`` implements
(filterpy is the test oracle; torch is the engine):

.. math::

    x^- = F x + B u,\qquad P^- = F P F^\top + Q

    y = z - H x^-,\quad S = H P^- H^\top + R,\quad K = P^- H^\top S^{-1}

    x^+ = x^- + K y,\qquad P^+ = (I - K H) P^- (I - K H)^\top + K R K^\top \ \text{(Joseph form)}

The Joseph form keeps :math:`P` symmetric positive definite under rounding; the result is
symmetrised once more. A per-element ``mask`` skips the update where a measurement is missing.
"""

from __future__ import annotations

import torch

__all__ = ["kf_predict", "kf_update"]


def kf_predict(
    mean: torch.Tensor,
    cov: torch.Tensor,
    transition: torch.Tensor,
    process_noise: torch.Tensor,
    control_matrix: torch.Tensor | None = None,
    control: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Kalman predict step, batched; matrices broadcast against ``[*B, n, n]``.

    >>> x, P = torch.zeros(2), torch.eye(2)
    >>> F = torch.tensor([[1.0, 1.0], [0.0, 1.0]])
    >>> x, P = kf_predict(x + torch.tensor([0.0, 1.0]), P, F, 0.1 * torch.eye(2))
    >>> x.tolist(), P.tolist()
    ([1.0, 1.0], [[2.0999999046325684, 1.0], [1.0, 1.100000023841858]])
    """
    if mean.shape[-1] != cov.shape[-1] or cov.shape[-1] != cov.shape[-2]:
        raise ValueError(
            f"mean [*B, n] and cov [*B, n, n] disagree: {tuple(mean.shape)}, {tuple(cov.shape)}"
        )
    mean = (transition @ mean.unsqueeze(-1)).squeeze(-1)
    if control is not None:
        if control_matrix is None:
            raise ValueError("control given without control_matrix")
        mean = mean + (control_matrix @ control.unsqueeze(-1)).squeeze(-1)
    cov = transition @ cov @ transition.transpose(-1, -2) + process_noise
    return mean, cov


def kf_update(
    mean: torch.Tensor,
    cov: torch.Tensor,
    measurement: torch.Tensor,
    observation: torch.Tensor,
    measurement_noise: torch.Tensor,
    mask: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Kalman update with the Joseph-form covariance, batched.

    Args:
        mean: ``[*B, n]``; cov: ``[*B, n, n]``.
        measurement: ``[*B, m]``; observation ``H``: ``[*B, m, n]`` or ``[m, n]``;
        measurement_noise ``R``: ``[*B, m, m]`` or ``[m, m]``.
        mask: optional ``[*B]`` bool, ``False`` where the measurement is missing (no update).

    >>> x, P = torch.zeros(2), torch.eye(2)
    >>> H, R = torch.tensor([[1.0, 0.0]]), torch.tensor([[1.0]])
    >>> x, P = kf_update(x, P, torch.tensor([2.0]), H, R)
    >>> x.tolist(), P.diagonal().tolist()
    ([1.0, 0.0], [0.5, 1.0])
    """
    if measurement.shape[-1] != observation.shape[-2]:
        raise ValueError(
            f"measurement has {measurement.shape[-1]} entries, observation expects "
            f"{observation.shape[-2]}"
        )
    h_t = observation.transpose(-1, -2)
    innovation = measurement - (observation @ mean.unsqueeze(-1)).squeeze(-1)
    s = observation @ cov @ h_t + measurement_noise
    gain = torch.linalg.solve(s, (cov @ h_t).transpose(-1, -2)).transpose(-1, -2)
    new_mean = mean + (gain @ innovation.unsqueeze(-1)).squeeze(-1)
    eye = torch.eye(cov.shape[-1], dtype=cov.dtype, device=cov.device)
    i_kh = eye - gain @ observation
    new_cov = i_kh @ cov @ i_kh.transpose(-1, -2) + gain @ measurement_noise @ gain.transpose(
        -1, -2
    )
    new_cov = 0.5 * (new_cov + new_cov.transpose(-1, -2))
    if mask is not None:
        new_mean = torch.where(mask.unsqueeze(-1), new_mean, mean)
        new_cov = torch.where(mask[..., None, None], new_cov, cov)
    return new_mean, new_cov
