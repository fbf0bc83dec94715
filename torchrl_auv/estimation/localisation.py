r"""AUV localisation: a position-velocity Kalman filter fed by DVL, depth and USBL.

State :math:`x = [p_N, p_E, p_D, v_N, v_E, v_D]` (NED, m and m/s) with a white-noise
acceleration model,

.. math::

    F = \begin{bmatrix} I & h I \\ 0 & I \end{bmatrix},\qquad
    Q = \sigma_a^2 \begin{bmatrix} h^4/4\, I & h^3/2\, I \\ h^3/2\, I & h^2 I \end{bmatrix}.

Every physics step the onboard sensors update it as one measurement
:math:`z = [R(\phi, \theta, \hat\psi)\,v_{DVL};\ d]`: the DVL body velocity rotated to NED with
the compass heading :math:`\hat\psi` (roll and pitch from the attitude sensor are taken as
exact, ours), with diagonal covariance :math:`\sigma_{DVL}^2 I` plus the heading error's
cross-track variance :math:`(\sigma_\psi |v_h|)^2` on both horizontal axes (conservative, and it
keeps :math:`R` diagonal so the update is four cheap scalar updates), and the depth sensor.
Without bottom lock (altitude above the DVL's range) the three velocity updates are skipped and
only the depth updates the filter (``dvl_valid``); the velocity is then carried by the motion
model and the USBL fixes alone. Once per decision a USBL fix updates the position with its
range-dependent covariance; a lost fix is skipped. The fix's covariance includes the ASV's GNSS
error variance (:func:`~torchrl_auv.estimation.sensors.usbl_fix_from_asv`), which the filter
treats as white: it is in fact correlated over about 60 s and cannot be separated from the
vehicle's position by any sensor here, so the filter's covariance understates that part.
"""

from __future__ import annotations

import torch

from torchrl_auv.estimation.kalman import kf_predict, kf_update, kf_update_sequential
from torchrl_auv.estimation.sensors import SensorNoise
from torchrl_auv.physics._ops import small_matmul
from torchrl_auv.physics.remus100 import rotation_matrix

__all__ = ["Localiser"]


class Localiser:
    """The AUV's navigation filter; see the module docstring for the model.

    Args:
        noise: onboard sensor noise (DVL, depth, compass).
        accel_sigma: process noise, white acceleration (m/s^2).

    Examples:
        >>> loc = Localiser()
        >>> mean, cov = loc.init(torch.tensor([[0.0, 0.0, 5.0]]), position_sigma=2.0)
        >>> mean, cov = loc.predict(mean, cov, 0.05)
        >>> att = torch.zeros(1, 3)
        >>> mean, cov = loc.update_onboard(mean, cov, torch.tensor([[1.0, 0, 0]]), att,
        ...                                torch.tensor([5.0]))
        >>> round(mean[0, 3].item(), 2)  # north velocity estimate (m/s)
        1.0
    """

    def __init__(self, noise: SensorNoise | None = None, accel_sigma: float = 0.2) -> None:
        if not accel_sigma > 0:
            raise ValueError(f"accel_sigma must be > 0, got {accel_sigma}")
        self.noise = SensorNoise() if noise is None else noise
        self.accel_sigma = accel_sigma
        self._cache: dict = {}

    def _matrices(self, dt: float, dtype: torch.dtype, device) -> dict[str, torch.Tensor]:
        key = (dt, dtype, device)
        if key not in self._cache:
            eye = torch.eye(3, dtype=dtype, device=device)
            zero = torch.zeros(3, 3, dtype=dtype, device=device)
            transition = torch.cat([torch.cat([eye, dt * eye], 1), torch.cat([zero, eye], 1)], 0)
            q = self.accel_sigma**2
            process = q * torch.cat(
                [
                    torch.cat([dt**4 / 4 * eye, dt**3 / 2 * eye], 1),
                    torch.cat([dt**3 / 2 * eye, dt**2 * eye], 1),
                ],
                0,
            )
            onboard_h = torch.zeros(4, 6, dtype=dtype, device=device)
            onboard_h[0, 3] = onboard_h[1, 4] = onboard_h[2, 5] = onboard_h[3, 2] = 1.0
            usbl_h = torch.cat([eye, zero], 1)
            self._cache[key] = {
                "F": transition,
                "Q": process,
                "H_onboard": onboard_h,
                "H_usbl": usbl_h,
            }
        return self._cache[key]

    def init(
        self,
        position: torch.Tensor,
        *,
        position_sigma: float = 1.0,
        velocity_sigma: float = 0.5,
        velocity: torch.Tensor | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Initial mean ``[*B, 6]`` and covariance ``[*B, 6, 6]`` around a position (m)."""
        if position.shape[-1] != 3:
            raise ValueError(f"position must be shaped [*B, 3], got {tuple(position.shape)}")
        vel = torch.zeros_like(position) if velocity is None else velocity
        mean = torch.cat([position, vel], -1)
        diag = torch.tensor(
            [position_sigma**2] * 3 + [velocity_sigma**2] * 3,
            dtype=position.dtype,
            device=position.device,
        )
        cov = torch.diag_embed(diag.expand(*position.shape[:-1], 6)).clone()
        return mean, cov

    def predict(self, mean: torch.Tensor, cov: torch.Tensor, dt: float):
        """Propagate by ``dt`` seconds."""
        m = self._matrices(dt, mean.dtype, mean.device)
        return kf_predict(mean, cov, m["F"], m["Q"])

    def update_onboard(
        self,
        mean: torch.Tensor,
        cov: torch.Tensor,
        dvl_velocity: torch.Tensor,
        attitude: torch.Tensor,
        depth: torch.Tensor,
        dvl_valid: torch.Tensor | None = None,
    ):
        """Update with DVL body velocity ``[*B, 3]``, attitude ``[*B, 3]`` (roll, pitch, compass
        heading, rad) and a depth reading ``[*B]`` (m).

        ``dvl_valid`` (``[*B]`` bool, e.g. from
        :func:`~torchrl_auv.estimation.sensors.dvl_bottom_lock`) skips the DVL part where it
        is ``False``: there only the depth updates the filter. ``None`` means bottom lock
        everywhere (the same result as an all-``True`` mask)."""
        rot = rotation_matrix(attitude)
        v_ned = small_matmul(rot, dvl_velocity.unsqueeze(-1)).squeeze(-1)
        z = torch.cat([v_ned, depth.unsqueeze(-1)], -1)
        # the compass error adds (sigma_psi |v_h|)^2 across track; it is spread over both
        # horizontal axes (conservative), which keeps R diagonal: four scalar updates.
        cross = (self.noise.compass * v_ned[..., :2].norm(dim=-1)).square()
        var_v = self.noise.dvl**2 + cross
        variances = torch.stack(
            (
                var_v,
                var_v,
                torch.full_like(var_v, self.noise.dvl**2),
                torch.full_like(var_v, max(self.noise.depth, 1e-6) ** 2),
            ),
            -1,
        )
        if dvl_valid is None:
            return kf_update_sequential(mean, cov, z, (3, 4, 5, 2), variances)
        # the same scalar updates in the same order, the DVL's three masked
        mean, cov = kf_update_sequential(
            mean, cov, z[..., :3], (3, 4, 5), variances[..., :3], mask=dvl_valid
        )
        return kf_update_sequential(mean, cov, z[..., 3:], (2,), variances[..., 3:])

    def update_usbl(
        self,
        mean: torch.Tensor,
        cov: torch.Tensor,
        fix: torch.Tensor,
        fix_cov: torch.Tensor,
        valid: torch.Tensor | None = None,
    ):
        """Update the position with a USBL fix ``[*B, 3]`` and its covariance ``[*B, 3, 3]``."""
        m = self._matrices(0.0, mean.dtype, mean.device)
        return kf_update(mean, cov, fix, m["H_usbl"], fix_cov, mask=valid)
