r"""The S-Surface controller of the paper (eq. 17), for heading and depth.

.. math::

    u = \frac{2}{1 + \exp(-\zeta_1 e - \zeta_2 \dot e)} - 1 + \Delta u \in (-1, 1) + \Delta u

with the paper's gains (Table I): yaw :math:`(\zeta_1, \zeta_2) = (2, 1)`, depth :math:`(1, 1)`.
Errors are normalised so the gains act on dimensionless quantities: heading
:math:`e = \mathrm{wrap}(\psi_d - \psi) / e_\psi` with :math:`e_\psi = 0.5` rad and
:math:`\dot e = -r / \dot e_\psi` with :math:`\dot e_\psi = 0.2` rad/s; depth
:math:`e = (z_d - z) / e_z` with :math:`e_z = 2` m and :math:`\dot e = -\dot z / \dot e_z` with
:math:`\dot e_z = 0.5` m/s (``zdot`` the NED vertical speed from the estimated state).

Outputs: the heading surface maps to the rudder, :math:`\delta_r = \delta_{max}\,u`. The depth
surface maps to a desired pitch, :math:`\theta_d = -\theta_{max}\,u` (diving needs the nose
down), which an inner pitch PD loop turns into the stern plane (successive loop closure, as in
the AUV S-surface literature: Liu et al., "S-surface controller for AUVs", and Fossen 2021
Sec. 16.2); a direct depth-to-fin surface oscillated on the REMUS-100 because of the slow pitch
dynamics. Fins saturate at :math:`\delta_{max}` = 15 deg.

:math:`\Delta u`, the online estimate of a constant disturbance, is a leaky integral of the
normalised error, :math:`\dot{\Delta u} = \kappa e - \Delta u / \tau`, clamped to
:math:`\pm\Delta u_{max}`: under a constant disturbance it settles where the steady error is
small, and it decays when the error vanishes, which limits windup.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from torchrl_auv.control.base import FIN_LIMIT, Controller, Gains, build_gains, register, wrap_angle

__all__ = ["SSurfaceController", "SSurfaceGains"]


def s_surface(e: torch.Tensor, e_dot: torch.Tensor, zeta1: float, zeta2: float) -> torch.Tensor:
    """The S-surface :math:`2 / (1 + e^{-\\zeta_1 e - \\zeta_2 \\dot e}) - 1` in (-1, 1)."""
    return 2.0 * torch.sigmoid(zeta1 * e + zeta2 * e_dot) - 1.0


@dataclass(frozen=True)
class SSurfaceGains(Gains):
    """S-surface gains. ``zeta*`` from the paper's Table I; the normalisations, ``kappa``,
    ``tau`` and the pitch loop chosen on the tuning scenario of
    :mod:`torchrl_auv.control.scenarios` (not the evaluation scenario)."""

    zeta1_heading: float = 2.0
    zeta2_heading: float = 1.0
    zeta1_depth: float = 1.0
    zeta2_depth: float = 1.0
    heading_scale: float = 0.5
    heading_rate_scale: float = 0.2
    depth_scale: float = 2.0
    depth_rate_scale: float = 0.5
    max_pitch: float = 0.35
    kp_pitch: float = 2.0
    kd_pitch: float = 2.0
    kappa: float = 0.01
    tau: float = 60.0
    max_delta_u: float = 0.3


@register("s_surface")
class SSurfaceController(Controller):
    """S-Surface heading and depth control (paper eq. 17); see the module docstring.

    >>> import torch
    >>> ctrl = SSurfaceController()
    >>> mem = ctrl.init_memory(())
    >>> cmd, mem = ctrl(torch.tensor([5.0, 0.3, 1000.0]), torch.zeros(6), torch.zeros(6), mem, 0.05)
    >>> bool(cmd[0] > 0), bool(cmd[1] > 0)  # turn to starboard, dive
    (True, True)
    """

    def __init__(self, **gains: float) -> None:
        self.gains = build_gains(SSurfaceGains, gains)

    def memory_keys(self) -> tuple[str, ...]:
        return ("delta_u_heading", "delta_u_depth")

    def _fins(self, setpoint, eta, nu, memory, dt):
        g = self.gains
        e_psi = wrap_angle(setpoint[..., 1] - eta[..., 5]) / g.heading_scale
        e_psi_dot = -nu[..., 5] / g.heading_rate_scale
        du_psi = _leaky_integral(memory["delta_u_heading"], e_psi, g, dt)
        u_psi = s_surface(e_psi, e_psi_dot, g.zeta1_heading, g.zeta2_heading) + du_psi
        rudder = FIN_LIMIT * u_psi

        z_dot = _vertical_speed(eta, nu)
        e_z = (setpoint[..., 0] - eta[..., 2]) / g.depth_scale
        e_z_dot = -z_dot / g.depth_rate_scale
        du_z = _leaky_integral(memory["delta_u_depth"], e_z, g, dt)
        u_z = (s_surface(e_z, e_z_dot, g.zeta1_depth, g.zeta2_depth) + du_z).clamp(-1.0, 1.0)
        theta_d = -g.max_pitch * u_z
        stern = -g.kp_pitch * (theta_d - eta[..., 4]) + g.kd_pitch * nu[..., 4]
        return rudder, stern, {"delta_u_heading": du_psi, "delta_u_depth": du_z}


def _leaky_integral(delta_u, error, g: SSurfaceGains, dt: float) -> torch.Tensor:
    updated = delta_u + dt * (g.kappa * error - delta_u / g.tau)
    return updated.clamp(-g.max_delta_u, g.max_delta_u)


def _vertical_speed(eta: torch.Tensor, nu: torch.Tensor) -> torch.Tensor:
    """NED vertical speed (m/s) from body velocities and attitude."""
    c_phi, c_th = torch.cos(eta[..., 3]), torch.cos(eta[..., 4])
    s_phi, s_th = torch.sin(eta[..., 3]), torch.sin(eta[..., 4])
    return -s_th * nu[..., 0] + c_th * s_phi * nu[..., 1] + c_th * c_phi * nu[..., 2]
