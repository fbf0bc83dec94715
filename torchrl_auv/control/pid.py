"""PID heading and depth control (a baseline of the paper's Table III).

Heading: :math:`\\delta_r = K_p e_\\psi + K_i \\int e_\\psi - K_d r` with
:math:`e_\\psi = \\mathrm{wrap}(\\psi_d - \\psi)`.
Depth, by successive loop closure through pitch (Fossen 2021, *Handbook of Marine Craft
Hydrodynamics and Motion Control*, 2nd ed., Sec. 16.2; the structure of the REMUS-100 depth
autopilot of Fossen's Python Vehicle Simulator): an outer PI loop turns the depth error into a
desired pitch :math:`\\theta_d` (saturated at ``max_pitch``), an inner PID loop on pitch
commands the stern plane,
:math:`\\delta_s = -(K_{p\\theta} e_\\theta + K_{i\\theta}\\int e_\\theta) + K_{d\\theta} q`.

Anti-windup: every integrator is clamped to ``+-integral_limit`` (in units of error x s).
"""

from __future__ import annotations

from dataclasses import dataclass

from torchrl_auv.control.base import (
    Controller,
    Gains,
    build_gains,
    depth_to_pitch,
    register,
    wrap_angle,
)

__all__ = ["PIDController", "PIDGains"]


@dataclass(frozen=True)
class PIDGains(Gains):
    """PID gains (SI units: rad per rad, rad per rad/s, ...).

    Defaults chosen on the tuning scenario of :mod:`torchrl_auv.control.scenarios`
    (a 45 deg heading step and a 5 m depth step at 1200 rpm in still water; not the evaluation
    scenario), starting from the PVS REMUS-100 depth autopilot's structure.
    """

    kp_heading: float = 2.0
    ki_heading: float = 0.02
    kd_heading: float = 0.5
    kp_depth: float = 0.1
    ki_depth: float = 0.002
    max_pitch: float = 0.35
    kp_pitch: float = 2.0
    ki_pitch: float = 0.1
    kd_pitch: float = 2.0
    integral_limit: float = 5.0


@register("pid")
class PIDController(Controller):
    """PID heading and depth control with clamped integrators; see the module docstring.

    >>> import torch
    >>> ctrl = PIDController(kp_heading=0.5)
    >>> mem = ctrl.init_memory(())
    >>> cmd, mem = ctrl(torch.tensor([5.0, 0.3, 1000.0]), torch.zeros(6), torch.zeros(6), mem, 0.05)
    >>> bool(cmd[0] > 0), bool(cmd[1] > 0)  # turn to starboard, dive
    (True, True)
    """

    def __init__(self, **gains: float) -> None:
        self.gains = build_gains(PIDGains, gains)

    def memory_keys(self) -> tuple[str, ...]:
        return ("heading_integral", "depth_integral", "pitch_integral")

    def _fins(self, setpoint, eta, nu, memory, dt):
        g = self.gains
        lim = g.integral_limit
        e_psi = wrap_angle(setpoint[..., 1] - eta[..., 5])
        i_psi = (memory["heading_integral"] + e_psi * dt).clamp(-lim, lim)
        rudder = g.kp_heading * e_psi + g.ki_heading * i_psi - g.kd_heading * nu[..., 5]
        e_z = setpoint[..., 0] - eta[..., 2]
        i_z = (memory["depth_integral"] + e_z * dt).clamp(-lim, lim)
        theta_d = depth_to_pitch(
            e_z + g.ki_depth / max(g.kp_depth, 1e-9) * i_z, g.kp_depth, g.max_pitch
        )
        e_theta = theta_d - eta[..., 4]
        i_theta = (memory["pitch_integral"] + e_theta * dt).clamp(-lim, lim)
        stern = -(g.kp_pitch * e_theta + g.ki_pitch * i_theta) + g.kd_pitch * nu[..., 4]
        memory_out = {"heading_integral": i_psi, "depth_integral": i_z, "pitch_integral": i_theta}
        return rudder, stern, memory_out
