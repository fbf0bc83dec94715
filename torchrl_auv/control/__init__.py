"""Low-level controllers: setpoints (depth m, heading rad, propeller rpm) to actuator commands.

Owns the S-Surface controller of the paper (eq. 17) and the PID and SMC baselines, all batched
plain torch behind one interface (:class:`~torchrl_auv.control.base.Controller`): memory the
caller carries as a :class:`~tensordict.TensorDict`, commands ready for
:func:`torchrl_auv.physics.remus100.step`, heading errors wrapped to (-pi, pi]. Also owns the
tracking scenario used to compare them (:mod:`torchrl_auv.control.scenarios`).

>>> import torch
>>> ctrl = make_controller("pid")
>>> memory = ctrl.init_memory((2,))
>>> setpoint = torch.tensor([[10.0, 1.0, 1200.0]] * 2)
>>> command, memory = ctrl(setpoint, torch.zeros(2, 6), torch.zeros(2, 6), memory, 0.05)
>>> command.shape
torch.Size([2, 3])
"""

from __future__ import annotations

from torchrl_auv.control.base import Controller, available_controllers, make_controller, wrap_angle
from torchrl_auv.control.pid import PIDController
from torchrl_auv.control.s_surface import SSurfaceController
from torchrl_auv.control.smc import SMCController

__all__ = [
    "Controller",
    "PIDController",
    "SMCController",
    "SSurfaceController",
    "available_controllers",
    "make_controller",
    "wrap_angle",
]
