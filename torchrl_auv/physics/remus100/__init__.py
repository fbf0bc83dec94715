r"""Batched REMUS-100 6-DoF model (Fossen's Python Vehicle Simulator version), in plain torch.

This is the model of ``docs/spec/remus100.md``: the REMUS-100 of T. I. Fossen's *Python Vehicle
Simulator* (Fossen 2021, *Handbook of Marine Craft Hydrodynamics and Motion Control*, 2nd ed.,
Sec. 8.4.2; Allen, Vorus and Prestero 2000), re-written from the specification as closed-form
tensor expressions batched over any leading dimensions ``[*B]``.

State and units (NED earth frame, body frame ``x`` forward, ``y`` starboard, ``z`` down):

* ``eta = [x, y, z, phi, theta, psi]``: position (m, ``z`` = depth) and zyx Euler angles (rad),
  never wrapped;
* ``nu = [u, v, w, p, q, r]``: body-frame velocity relative to the earth (m/s) and rates (rad/s);
* ``actuators = [delta_r, delta_s, n]``: the *stored* rudder and stern-plane angles (rad) and
  propeller speed (rpm). They may exceed the limits; saturation acts at the start of each step;
* ``command``: the same three quantities, commanded (never clipped);
* ``current = [V_c, beta_c]`` or ``[V_c, beta_c, w_c]``: horizontal current speed (m/s) and
  direction (rad, the direction the water flows towards), and optionally the water's vertical
  velocity :math:`w_c` (m/s, NED, positive down; e.g. the wave orbital velocity of
  :func:`torchrl_auv.physics.ocean.current_at`). The 2-wide form is exactly the PVS model
  (:math:`w_c = 0`), and so is a 3-wide one with :math:`w_c = +0`.

*Vertical water velocity* (ours, spec ``data_collection.md`` v2, a departure from PVS, whose
current is horizontal): PVS resolves the current in the body frame with the yaw angle only,
:math:`u_c = V_c\cos(\beta_c - \psi)`, :math:`v_c = V_c\sin(\beta_c - \psi)`, i.e. it treats
the body's :math:`x`-:math:`y` plane as horizontal. Consistently, :math:`w_c` is subtracted from
the body-frame heave, :math:`w_r = w - w_c`, as if the body :math:`z` axis were vertical (the
exact body components, :math:`w_c[-\sin\theta, \cos\theta\sin\phi, \cos\theta\cos\phi]`,
differ by the order of the pitch and roll angles, a few degrees). :math:`\dot\nu_c` keeps
PVS's yaw-rate terms only (yaw does not rotate a vertical velocity). The water's acceleration
(Froude-Krylov and added-mass forces of the orbital flow) is not modelled, for the vertical
as for the horizontal part: the flow acts only through the relative velocity :math:`\nu_r`.

Sign conventions: ``delta_r > 0`` turns the vehicle to starboard (positive yaw rate),
``delta_s > 0`` pitches the nose down so the vehicle dives, ``n > 0`` gives forward thrust.

One call of :func:`step` is one semi-implicit Euler step in the order of the spec's Sec. 7:

.. math::

    \nu_{k+1} = \nu_k + h\,\dot\nu(\eta_k, \nu_k, \bar u_{a,k}),\qquad
    u_{a,k+1} = \bar u_{a,k} + h\,(u_c - \bar u_{a,k}) / T_a,

    p_{k+1} = p_k + h\,R(\Theta_k)\,v_{k+1},\qquad
    \Theta_{k+1} = \Theta_k + h\,T(\Theta_k)\,\omega_{k+1},

with :math:`\bar u_a` the saturated actuator state. The model has no free surface and no seabed;
those are environment limits, see :mod:`torchrl_auv.physics.limits`.

Replay a reference CSV (format of ``tests/data/remus100/README.md``)::

    python -m torchrl_auv.cli.remus100 replay IN.csv OUT.csv
"""

from __future__ import annotations

from torchrl_auv.physics.remus100.dynamics import (
    compiled_step,
    dynamics,
    kinematics,
    rotation_matrix,
    step,
    step_unchecked,
)
from torchrl_auv.physics.remus100.forces import (
    FEATURES,
    coriolis,
    model_tensors,
    propeller_forces,
    rpm_for_thrust,
    saturate,
)
from torchrl_auv.physics.remus100.params import DEFAULT_PARAMS, Remus100Params
from torchrl_auv.physics.remus100.replay import STATE_COLUMNS, replay

__all__ = [
    "DEFAULT_PARAMS",
    "FEATURES",
    "STATE_COLUMNS",
    "Remus100Params",
    "compiled_step",
    "coriolis",
    "dynamics",
    "kinematics",
    "model_tensors",
    "propeller_forces",
    "replay",
    "rotation_matrix",
    "rpm_for_thrust",
    "saturate",
    "step",
    "step_unchecked",
]
