r"""Sliding-mode heading control and SMC pitch control for depth (a paper baseline).

Heading: integral sliding-mode control on a first-order Nomoto model
:math:`T\dot r + r = K\delta_r` (Fossen 2021, *Handbook of Marine Craft Hydrodynamics and
Motion Control*, 2nd ed., Sec. 16.3), with :math:`\tilde\psi = \mathrm{wrap}(\psi - \psi_d)`
(clamped to :math:`\pm\tilde\psi_{max}` so a large step does not saturate the surface) and

.. math::

    s = r + 2\lambda\tilde\psi + \lambda^2 \int \tilde\psi,\qquad
    \delta_r = \frac{1}{K}\Big(r - T(2\lambda r + \lambda^2\tilde\psi)\Big)
               - K_d\, s - K_\sigma \operatorname{sat}(s/\phi_b).

Depth by successive loop closure through pitch: the depth error gives a desired pitch
(saturated at ``max_pitch``) and a pitch sliding surface :math:`s_\theta = q + \lambda_\theta
(\theta - \theta_d)` gives :math:`\delta_s = K_{d\theta}s_\theta + K_{\sigma\theta}
\operatorname{sat}(s_\theta/\phi_\theta)` (a positive stern plane pitches the nose down).

Nomoto parameters: :math:`K = 0.59` 1/s from the model's steady turn (10 deg rudder, 1525 rpm:
r = 0.103 rad/s) and :math:`T = 1` s; gains chosen on the tuning scenario of
:mod:`torchrl_auv.control.scenarios` (not the evaluation scenario).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from torchrl_auv.control.base import (
    Controller,
    Gains,
    build_gains,
    depth_to_pitch,
    register,
    wrap_angle,
)

__all__ = ["SMCController", "SMCGains"]


@dataclass(frozen=True)
class SMCGains(Gains):
    """Sliding-mode gains (SI units); see the module docstring for the control law."""

    nomoto_k: float = 0.59
    nomoto_t: float = 1.0
    lam: float = 0.3
    k_d: float = 0.5
    k_sigma: float = 0.05
    phi_b: float = 0.1
    max_heading_error: float = 0.2
    integral_limit: float = 5.0
    kp_depth: float = 0.1
    max_pitch: float = 0.35
    lam_pitch: float = 1.0
    kd_pitch: float = 2.0
    k_sigma_pitch: float = 0.05
    phi_pitch: float = 0.1


@register("smc")
class SMCController(Controller):
    """Integral SMC heading and SMC pitch/depth control; see the module docstring.

    >>> import torch
    >>> ctrl = SMCController()
    >>> mem = ctrl.init_memory(())
    >>> cmd, mem = ctrl(torch.tensor([5.0, 0.3, 1000.0]), torch.zeros(6), torch.zeros(6), mem, 0.05)
    >>> bool(cmd[0] > 0), bool(cmd[1] > 0)  # turn to starboard, dive
    (True, True)
    """

    def __init__(self, **gains: float) -> None:
        self.gains = build_gains(SMCGains, gains)
        if self.gains.nomoto_k <= 0 or self.gains.phi_b <= 0 or self.gains.phi_pitch <= 0:
            raise ValueError("nomoto_k, phi_b and phi_pitch must be > 0")

    def memory_keys(self) -> tuple[str, ...]:
        return ("heading_integral",)

    def _fins(self, setpoint, eta, nu, memory, dt):
        g = self.gains
        r = nu[..., 5]
        psi_err = wrap_angle(eta[..., 5] - setpoint[..., 1])
        psi_err = psi_err.clamp(-g.max_heading_error, g.max_heading_error)
        integral = (memory["heading_integral"] + psi_err * dt).clamp(
            -g.integral_limit, g.integral_limit
        )
        s = r + 2 * g.lam * psi_err + g.lam**2 * integral
        rudder = (
            (r - g.nomoto_t * (2 * g.lam * r + g.lam**2 * psi_err)) / g.nomoto_k
            - g.k_d * s
            - g.k_sigma * torch.clamp(s / g.phi_b, -1.0, 1.0)
        )
        theta_d = depth_to_pitch(setpoint[..., 0] - eta[..., 2], g.kp_depth, g.max_pitch)
        s_theta = nu[..., 4] + g.lam_pitch * (eta[..., 4] - theta_d)
        stern = g.kd_pitch * s_theta + g.k_sigma_pitch * torch.clamp(s_theta / g.phi_pitch, -1, 1)
        return rudder, stern, {"heading_integral": integral}
