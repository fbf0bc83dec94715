r"""Batched REMUS-100 6-DoF model (Fossen's Python Vehicle Simulator version), in plain torch.

This is the model of ``shared/spec/remus100.md``: the REMUS-100 of T. I. Fossen's *Python Vehicle
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

import csv
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import torch

from torchrl_auv.physics._ops import small_matmul
from torchrl_auv.physics.euler import euler_matrices, trig_factors

__all__ = [
    "STATE_COLUMNS",
    "Remus100Params",
    "compiled_step",
    "coriolis",
    "dynamics",
    "kinematics",
    "propeller_forces",
    "rotation_matrix",
    "rpm_for_thrust",
    "saturate",
    "step",
    "step_unchecked",
]

# Column names of the reference CSV format, in state order (eta, nu, actuators).
ETA_COLUMNS = ("x", "y", "z", "phi", "theta", "psi")
NU_COLUMNS = ("u", "v", "w", "p", "q", "r")
ACTUATOR_COLUMNS = ("delta_r", "delta_s", "n")
COMMAND_COLUMNS = ("cmd_delta_r", "cmd_delta_s", "cmd_n")
CURRENT_COLUMNS = ("Vc", "beta_c")
STATE_COLUMNS = ETA_COLUMNS + NU_COLUMNS + ACTUATOR_COLUMNS


@dataclass(frozen=True)
class Remus100Params:
    """Physical parameters of the REMUS-100 (spec Sec. 2); derived quantities are properties.

    Every field is a primary constant of the model; mass, inertia, added mass, damping and the
    hull, cross-flow, propeller and fin coefficients are derived from them exactly as the
    simulator does (e.g. the mass matrix is inverted numerically once, in float64).

    Attributes:
        rho: water density (kg/m^3).
        g: gravity (m/s^2).
        length: hull length L (m).
        diameter: hull diameter D (m).
        z_g: centre of gravity below the centre of buoyancy (m).
        r44: roll added inertia as a fraction of I_x.
        t_surge, t_sway, t_heave, t_yaw: linear-damping time constants (s).
        zeta_roll, zeta_pitch: roll and pitch damping ratios.
        cd_hull: hull zero-lift drag coefficient (Allen et al. 2000).
        oswald: Oswald efficiency of the hull "wing".
        hoerner: the two Hoerner-curve points bracketing B/(2T) = 0.5, as (x0, y0, x1, y1).
        num_strips: cross-flow strip points.
        prop_diameter: propeller diameter D_p (m).
        thrust_deduction: t_p.
        wake_fraction_factor: V_a = factor * U (absolute speed).
        j_max, kt_0, kq_0, kt_max, kq_max: Wageningen B-series K_T/K_Q at J = 0 and J = J_max.
        fin_area: area of one fin (m^2); rudder and stern plane have two each.
        cl_rudder, cl_stern: fin lift coefficients.
        delta_max: fin angle limit (rad). n_max: propeller limit (rpm).
        t_fin, t_prop: actuator time constants (s).

    Examples:
        >>> p = Remus100Params()
        >>> round(p.mass, 6), round(p.inertia[1], 6)
        (31.029385, 4.027769)
    """

    rho: float = 1026.0
    g: float = 9.81
    length: float = 1.6
    diameter: float = 0.19
    z_g: float = 0.02
    r44: float = 0.3
    t_surge: float = 20.0
    t_sway: float = 20.0
    t_heave: float = 20.0
    t_yaw: float = 1.0
    zeta_roll: float = 0.3
    zeta_pitch: float = 0.8
    cd_hull: float = 0.42
    oswald: float = 0.7
    hoerner: tuple[float, float, float, float] = (0.4933, 1.2108, 0.5585, 1.0836)
    num_strips: int = 21
    prop_diameter: float = 0.14
    thrust_deduction: float = 0.1
    wake_fraction_factor: float = 0.944
    j_max: float = 0.6632
    kt_0: float = 0.4566
    kq_0: float = 0.0700
    kt_max: float = 0.1798
    kq_max: float = 0.0312
    fin_area: float = 0.00665
    cl_rudder: float = 0.5
    cl_stern: float = 0.7
    delta_max: float = 15.0 * 0.017453292519943295
    n_max: float = 1525.0
    t_fin: float = 0.1
    t_prop: float = 1.0
    _tensor_cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        positive = (
            "rho", "g", "length", "diameter", "t_surge", "t_sway", "t_heave", "t_yaw",
            "prop_diameter", "j_max", "fin_area", "delta_max", "n_max", "t_fin", "t_prop",
        )  # fmt: skip
        for name in positive:
            if not getattr(self, name) > 0:
                raise ValueError(f"Remus100Params.{name} must be > 0, got {getattr(self, name)}")
        if self.num_strips < 2:
            raise ValueError(f"Remus100Params.num_strips must be >= 2, got {self.num_strips}")
        # Evaluate every derived quantity now: the step reads plain attributes afterwards
        # (cheap in eager mode, and traceable by torch.compile).
        for name in _DERIVED:
            getattr(self, name)

    # -- rigid body (spec 2.2) ----------------------------------------------------------
    @cached_property
    def semi_axes(self) -> tuple[float, float]:
        """Spheroid semi-axes ``(a, b) = (L/2, D/2)`` (m)."""
        return self.length / 2, self.diameter / 2

    @cached_property
    def mass(self) -> float:
        r""":math:`m = \tfrac43 \pi \rho a b^2` (kg); neutrally buoyant, W = B."""
        a, b = self.semi_axes
        return 4.0 / 3.0 * math.pi * self.rho * a * b**2

    @cached_property
    def weight(self) -> float:
        """W = m g = B (N)."""
        return self.mass * self.g

    @cached_property
    def inertia(self) -> tuple[float, float, float]:
        r"""Spheroid inertias about the CG, :math:`(I_x, I_y, I_z)` (kg m^2)."""
        a, b = self.semi_axes
        ix = 2.0 / 5.0 * self.mass * b**2
        iy = 1.0 / 5.0 * self.mass * (a**2 + b**2)
        return ix, iy, iy

    # -- added mass (spec 2.3) ----------------------------------------------------------
    @cached_property
    def added_mass(self) -> tuple[float, ...]:
        r"""Diagonal added mass :math:`(A_{11}, \dots, A_{66})` from Lamb's k-factors."""
        a, b = self.semi_axes
        e = math.sqrt(1 - (b / a) ** 2)
        log_term = math.log((1 + e) / (1 - e))
        alpha0 = 2 * (1 - e**2) / e**3 * (0.5 * log_term - e)
        beta0 = 1 / e**2 - (1 - e**2) / (2 * e**3) * log_term
        k1 = alpha0 / (2 - alpha0)
        k2 = beta0 / (2 - beta0)
        k_prime = (
            e**4 * (beta0 - alpha0) / ((2 - e**2) * (2 * e**2 - (2 - e**2) * (beta0 - alpha0)))
        )
        m = self.mass
        ix, iy, _ = self.inertia
        return (m * k1, m * k2, m * k2, self.r44 * ix, k_prime * iy, k_prime * iy)

    # -- mass matrix (spec 2.4) ---------------------------------------------------------
    @cached_property
    def mass_matrix(self) -> tuple[tuple[float, ...], ...]:
        """Total mass matrix ``M = M_RB + M_A`` about the CO, as nested tuples (6x6)."""
        m, zg = self.mass, self.z_g
        ix, iy, iz = self.inertia
        mat = [[0.0] * 6 for _ in range(6)]
        mat[0][0] = mat[1][1] = mat[2][2] = m
        mat[0][4] = mat[4][0] = m * zg
        mat[1][3] = mat[3][1] = -m * zg
        mat[3][3] = ix + m * zg**2
        mat[4][4] = iy + m * zg**2
        mat[5][5] = iz
        for i, a_ii in enumerate(self.added_mass):
            mat[i][i] += a_ii
        return tuple(tuple(row) for row in mat)

    @cached_property
    def mass_matrix_inverse(self) -> tuple[tuple[float, ...], ...]:
        """``M^{-1}``, inverted numerically once in float64 as the simulator does."""
        inv = torch.linalg.inv(torch.tensor(self.mass_matrix, dtype=torch.float64))
        return tuple(tuple(float(v) for v in row) for row in inv)

    # -- damping (spec 2.5, 2.6) --------------------------------------------------------
    @cached_property
    def damping_base(self) -> tuple[float, ...]:
        r"""Linear damping diagonal before the :math:`e^{-3U_r}` fade of surge and sway."""
        mm = self.mass_matrix
        w_zg = self.weight * self.z_g  # z_b = 0
        w_roll = math.sqrt(w_zg / mm[3][3])
        w_pitch = math.sqrt(w_zg / mm[4][4])
        return (
            mm[0][0] / self.t_surge,
            mm[1][1] / self.t_sway,
            mm[2][2] / self.t_heave,
            2 * self.zeta_roll * w_roll * mm[3][3],
            2 * self.zeta_pitch * w_pitch * mm[4][4],
            mm[5][5] / self.t_yaw,
        )

    # -- hull lift/drag (spec 2.7) ------------------------------------------------------
    @cached_property
    def hull(self) -> tuple[float, float, float, float]:
        r"""``(S, C_D0, C_L_alpha, pi e AR)`` of the hull treated as a low-aspect-ratio wing."""
        _, b = self.semi_axes
        area = 0.7 * self.length * self.diameter
        cd0 = self.cd_hull * math.pi * b**2 / area
        aspect = self.diameter**2 / area
        cl_alpha = math.pi * aspect / (1 + math.sqrt(1 + (aspect / 2) ** 2))
        return area, cd0, cl_alpha, math.pi * self.oswald * aspect

    # -- cross-flow (spec 2.8) ----------------------------------------------------------
    @cached_property
    def crossflow_cd(self) -> float:
        """Hoerner 2-D drag coefficient, linearly interpolated at B/(2T) = 0.5."""
        x0, y0, x1, y1 = self.hoerner
        return y0 + (0.5 - x0) / (x1 - x0) * (y1 - y0)

    @cached_property
    def strip_positions(self) -> tuple[float, ...]:
        """Strip points built by repeated addition of ``dx`` to ``-L/2`` (as the simulator)."""
        dx = self.length / (self.num_strips - 1)
        points, x = [], -self.length / 2
        for _ in range(self.num_strips):
            points.append(x)
            x += dx
        return tuple(points)

    def tensors(self, dtype: torch.dtype, device: torch.device | None) -> dict[str, torch.Tensor]:
        """Constant tensors used by :func:`dynamics`, cached per ``(dtype, device)``."""
        key = (dtype, torch.device(device) if device is not None else torch.device("cpu"))
        cached = self._tensor_cache.get(key)
        if cached is None:
            kwargs = {"dtype": dtype, "device": key[1]}
            cached = {
                "strips": torch.tensor(self.strip_positions, **kwargs),
                "limits": torch.tensor((self.delta_max, self.delta_max, self.n_max), **kwargs),
                "time_constants": torch.tensor((self.t_fin, self.t_fin, self.t_prop), **kwargs),
                "faded": torch.tensor((True, True, False, False, False, False), device=key[1]),
                "powers": torch.tensor((0.0, 1.0, 2.0), **kwargs),
                "force_map": _force_map(self).to(**kwargs),
            }
            self._tensor_cache[key] = cached
        return cached


_DERIVED = (
    "semi_axes", "mass", "weight", "inertia", "added_mass", "mass_matrix",
    "mass_matrix_inverse", "damping_base", "hull", "crossflow_cd", "strip_positions",
)  # fmt: skip
DEFAULT_PARAMS = Remus100Params()


def saturate(value: torch.Tensor, limit: float | torch.Tensor) -> torch.Tensor:
    r"""Saturate a stored actuator state (spec Sec. 5).

    .. math:: \bar x = \operatorname{sign}(x)\,x_{max} \text{ if } |x| \ge x_{max}, \text{ else } x

    >>> saturate(torch.tensor([0.1, -0.5, 0.3]), 0.2617993877991494)
    tensor([ 0.1000, -0.2618,  0.2618])
    """
    return torch.where(value.abs() >= limit, torch.sign(value) * limit, value)


def propeller_forces(
    n_rpm: torch.Tensor, speed: torch.Tensor, params: Remus100Params | None = None
) -> tuple[torch.Tensor, torch.Tensor]:
    r"""Propeller thrust and torque (spec Sec. 4.6) for a *saturated* propeller speed.

    With :math:`n_s = n/60` (rev/s) and advance speed :math:`V_a = 0.944\,U`:

    .. math::

        X_p = \rho D_p^4 \Big(K_{T0} |n_s| n_s
              + \frac{K_{T,max} - K_{T0}}{J_{max}} \frac{V_a}{D_p} |n_s|\Big),\qquad
        Q_p = \rho D_p^5 \Big(K_{Q0} |n_s| n_s
              + \frac{K_{Q,max} - K_{Q0}}{J_{max}} \frac{V_a}{D_p} |n_s|\Big)

    for :math:`n_s > 0`; for :math:`n_s \le 0` only the first terms remain.

    Args:
        n_rpm: propeller speed (rpm), ``[*B]``.
        speed: the vehicle's absolute speed :math:`U = \|[u, v, w]\|` (m/s), ``[*B]``.
        params: vehicle parameters (default REMUS-100).

    Returns:
        ``(thrust, torque)`` in N and N m, the full torque before the model's roll scaling.

    >>> thrust, torque = propeller_forces(torch.tensor(1525.0), torch.tensor(0.0))
    >>> round(thrust.item(), 1), round(torque.item(), 2)
    (116.3, 2.49)
    """
    p = DEFAULT_PARAMS if params is None else params
    n_s = n_rpm / 60.0
    abs_n = n_s.abs()
    va_over_d = p.wake_fraction_factor * speed / p.prop_diameter
    d4 = p.rho * p.prop_diameter**4
    d5 = p.rho * p.prop_diameter**5
    forward = n_s > 0
    quad_t = p.kt_0 * abs_n * n_s
    quad_q = p.kq_0 * abs_n * n_s
    lin_t = (p.kt_max - p.kt_0) / p.j_max * va_over_d * abs_n
    lin_q = (p.kq_max - p.kq_0) / p.j_max * va_over_d * abs_n
    thrust = d4 * torch.where(forward, quad_t + lin_t, quad_t)
    torque = d5 * torch.where(forward, quad_q + lin_q, quad_q)
    return thrust, torque


def rpm_for_thrust(
    thrust: torch.Tensor, speed: torch.Tensor, params: Remus100Params | None = None
) -> torch.Tensor:
    r"""The propeller speed that gives ``thrust`` at the absolute speed ``speed``: the inverse
        of :func:`propeller_forces` in :math:`n > 0`.

        The thrust is a quadratic in :math:`n_s = n/60`,
        :math:`X_p/(
    ho D_p^4) = K_{T0} n_s^2 + a\,(V_a/D_p)\,n_s` with
        :math:`a = (K_{T,max} - K_{T0})/J_{max} < 0`; its positive root is returned. Because
        :math:`V_a = 0.944\,U` uses the speed over ground (the model's, after PVS), a propeller
        turning at the rpm that holds a speed through still water pushes harder on a vehicle
        held still against a current of that speed: holding station needs fewer rpm.

        Args:
            thrust: wanted thrust (N, >= 0), ``[*B]``.
            speed: the vehicle's absolute speed :math:`U` (m/s), ``[*B]``.
            params: vehicle parameters (default REMUS-100).

        Returns:
            ``[*B]`` propeller speed (rpm, >= 0).

        >>> thrust, _ = propeller_forces(torch.tensor(600.0), torch.tensor(1.0))
        >>> round(rpm_for_thrust(thrust, torch.tensor(1.0)).item(), 3)  # the round trip
        600.0
        >>> round(rpm_for_thrust(thrust, torch.tensor(0.0)).item())  # the same thrust at rest
        372
    """
    p = DEFAULT_PARAMS if params is None else params
    linear = (p.kt_max - p.kt_0) / p.j_max * p.wake_fraction_factor * speed / p.prop_diameter
    need = thrust.clamp_min(0.0) / (p.rho * p.prop_diameter**4)
    n_s = (-linear + (linear.square() + 4.0 * p.kt_0 * need).sqrt()) / (2.0 * p.kt_0)
    return 60.0 * n_s


def coriolis(nu_r: torch.Tensor, params: Remus100Params | None = None) -> torch.Tensor:
    r""":math:`C(\nu_r)\nu_r` (spec Sec. 2.4-2.5), ``[*B, 6]``: :math:`C_{RB}(\nu_r)\nu_r =
    [\omega \times a;\ v \times a + \omega \times b]` with :math:`[a; b] = M_{RB}\nu_r`, plus
    :math:`C_A` without its eight Munk entries.

    :func:`dynamics` does not call this function: it uses the quadratic form's coefficients,
    read off this function once per parameter set (:meth:`Remus100Params.tensors`).

    >>> nu_r = torch.tensor([1.0, 0.0, 0.0, 0.0, 0.0, 0.1], dtype=torch.float64)
    >>> round(coriolis(nu_r)[1].item(), 4)  # surge and yaw rate: sway force r m u (N)
    3.1029
    """
    p = DEFAULT_PARAMS if params is None else params
    u_r, v_r, w_r, rate_p, rate_q, rate_r = nu_r.unbind(-1)
    m, zg = p.mass, p.z_g
    ix, iy, iz = p.inertia
    _, a22, a33, a44, a55, a66 = p.added_mass
    a_1 = m * (u_r + zg * rate_q)
    a_2 = m * (v_r - zg * rate_p)
    a_3 = m * w_r
    b_1 = -m * zg * v_r + (ix + m * zg**2) * rate_p
    b_2 = m * zg * u_r + (iy + m * zg**2) * rate_q
    b_3 = iz * rate_r
    return torch.stack(
        (
            rate_q * a_3 - rate_r * a_2,
            rate_r * a_1 - rate_p * a_3 - a33 * w_r * rate_p,
            rate_p * a_2 - rate_q * a_1 + a22 * v_r * rate_p,
            (v_r * a_3 - w_r * a_2)
            + (rate_q * b_3 - rate_r * b_2)
            + (a33 - a22) * v_r * w_r
            + (a66 - a55) * rate_q * rate_r,
            (w_r * a_1 - u_r * a_3) + (rate_r * b_1 - rate_p * b_3) + (a44 - a66) * rate_p * rate_r,
            (u_r * a_2 - v_r * a_1) + (rate_p * b_2 - rate_q * b_1) + (a55 - a44) * rate_p * rate_q,
        ),
        -1,
    )


#: The features :func:`dynamics` computes, in order, with their widths. The generalised force
#: is linear in them (:func:`_force_map`): propeller (:math:`n|n|`, :math:`U\max(n, 0)`, rpm),
#: fins (:math:`U_{rh}^2\delta_r`, :math:`U_{rv}^2\delta_s` and those times
#: the fin angle), hull lift and drag (:math:`U_r^2 [\cos\alpha, \sin\alpha] \otimes
#: [1, \alpha, \alpha^2]`), cross-flow (:math:`|v_r + x_i r|(v_r + x_i r)` per strip),
#: restoring (:math:`\cos\theta\sin\phi`, :math:`\sin\theta`), Coriolis
#: (:math:`\nu_r \otimes \nu_r`), damping (:math:`\nu_r`, surge and sway faded) and the
#: current's rotation (:math:`r u_c, r v_c`, added to :math:`\dot\nu` directly).
FEATURES = (
    ("propeller", 2), ("fins", 2), ("fin_drag", 2), ("hull", 6), ("crossflow", None),
    ("restoring", 2), ("coriolis", 36), ("damping", 6), ("current_rotation", 2),
)  # fmt: skip


def _force_map(p: Remus100Params) -> torch.Tensor:
    r"""``[F, 6]`` float64 map from the features (:data:`FEATURES`) to :math:`\dot\nu`:
    the force coefficients of spec Secs. 3-6 times :math:`M^{-1}` (the current's rotation
    enters :math:`\dot\nu` directly)."""
    rows: list[list[float]] = []

    def add(**lanes: float) -> None:
        row = [0.0] * 6
        for name, value in lanes.items():
            row["XYZKMN".index(name)] = value
        rows.append(row)

    # propeller, per n|n| and per U max(n, 0) (rpm): read off propeller_forces, which is
    # c0 n|n| + c1 U |n| for n > 0 (at n = 1 rpm: c0 from U = 0, c1 from U = 1 m/s)
    n, speed = torch.ones(2, dtype=torch.float64), torch.tensor([0.0, 1.0], dtype=torch.float64)
    thrust, torque = propeller_forces(n, speed, p)
    add(X=(1 - p.thrust_deduction) * thrust[0].item(), K=torque[0].item() / 10.0)
    add(X=(1 - p.thrust_deduction) * (thrust[1] - thrust[0]).item(),
        K=(torque[1] - torque[0]).item() / 10.0)  # fmt: skip
    fin = 0.5 * p.rho * 2 * p.fin_area
    y_r, z_s, x_fin = -fin * p.cl_rudder, -fin * p.cl_stern, -p.length / 2
    add(Y=y_r, N=x_fin * y_r)
    add(Z=z_s, M=-x_fin * z_s)
    add(X=y_r)
    add(X=z_s)
    area, cd0, cl_alpha, pi_e_ar = p.hull
    half = 0.5 * p.rho * area
    induced = cl_alpha * cl_alpha / pi_e_ar  # c_D = c_D0 + (c_L alpha)^2 / (pi e AR)
    add(X=-half * cd0)  # cos, 1
    add(Z=-half * cl_alpha)  # cos, alpha
    add(X=-half * induced)  # cos, alpha^2
    add(Z=-half * cd0)  # sin, 1
    add(X=half * cl_alpha)  # sin, alpha
    add(Z=-half * induced)  # sin, alpha^2
    dx = p.length / (p.num_strips - 1)
    cf_gain = 0.5 * p.rho * p.diameter * p.crossflow_cd * dx
    for x in p.strip_positions:
        add(Y=-cf_gain, N=-cf_gain * x)
    zg_w = p.z_g * p.weight
    add(K=-zg_w)
    add(M=-zg_w)
    # C(nu_r) nu_r is quadratic: its coefficients are half its (constant) Hessian
    hessian = torch.func.hessian(lambda v: coriolis(v, p))(torch.zeros(6, dtype=torch.float64))
    for i in range(6):
        for j in range(6):
            add(**{"XYZKMN"[k]: -0.5 * hessian[k, i, j].item() for k in range(6)})
    for k, d in enumerate(p.damping_base):
        add(**{"XYZKMN"[k]: -d})
    forces = torch.tensor(rows, dtype=torch.float64)
    nu_dot = forces @ torch.tensor(p.mass_matrix_inverse, dtype=torch.float64).T
    rotation = torch.tensor([[0.0, -1.0, 0, 0, 0, 0], [1.0, 0, 0, 0, 0, 0]], dtype=torch.float64)
    return torch.cat((nu_dot, rotation))  # [r v_c, -r u_c, 0, 0, 0, 0] from (r u_c, r v_c)


def _same_batch(*tensors: torch.Tensor) -> tuple[torch.Tensor, ...]:
    """The inputs broadcast to one batch shape (views; no copy when they already agree)."""
    shapes = {t.shape[:-1] for t in tensors}
    if len(shapes) == 1:
        return tensors
    batch = torch.broadcast_shapes(*shapes)
    return tuple(t.expand(*batch, t.shape[-1]) for t in tensors)


def _features_and_rates(eta, nu, actuators, command, current, p, cos, sin):
    """:func:`dynamics` from the cosines and sines of ``(phi, theta, psi, beta_c - psi)``:
    ``(nu_dot, actuator_rate, saturated)``."""
    const = p.tensors(nu.dtype, nu.device)
    # 1-2. current in the body frame (yaw only) and relative velocity; a vertical water
    # velocity, if given, acts along body z (yaw-only resolution, as PVS)
    flow_c = current[..., :1] * torch.cat((cos[..., 3:], sin[..., 3:]), -1)  # u_c, v_c
    if current.shape[-1] == 3:
        flow_c = torch.cat((flow_c, current[..., 2:]), -1)
    nu_r = nu - torch.nn.functional.pad(flow_c, (0, 6 - flow_c.shape[-1]))
    speeds_sq = torch.stack((nu[..., :3], nu_r[..., :3]), -2).square()  # [*B, 2, 3]
    norms_sq = speeds_sq.sum(-1)
    speed, speed_r = norms_sq.sqrt().unbind(-1)  # U and U_r, [*B]
    u_r_sq = speeds_sq[..., 1, :1]
    fin_speed_sq = u_r_sq + speeds_sq[..., 1, 1:]  # U_rh^2, U_rv^2
    alpha = torch.atan2(nu_r[..., 2:3], nu_r[..., :1])
    # 3-4. saturated actuators, propeller
    saturated = saturate(actuators, const["limits"])
    rpm = saturated[..., 2:]  # (rpm -> rev/s in the force map)
    propeller = torch.cat((rpm * rpm.abs(), speed[..., None] * rpm.clamp_min(0.0)), -1)
    # 9. fins; 7. hull lift and drag; cross-flow per strip; 8. restoring
    fins = fin_speed_sq * saturated[..., :2]
    lift_drag = norms_sq[..., 1:] * torch.cat((alpha.cos(), alpha.sin()), -1)
    hull = lift_drag[..., :, None] * alpha.pow(const["powers"])[..., None, :]  # alpha^0..2
    strip_flow = nu_r[..., 1:2] + const["strips"] * nu_r[..., 5:6]
    restoring = torch.cat((cos[..., 1:2] * sin[..., :1], sin[..., 1:2]), -1)
    # 5-6. Coriolis (quadratic), linear damping with surge and sway faded by e^{-3 U_r}
    fade = torch.where(const["faded"], torch.exp(-3.0 * speed_r)[..., None], 1.0)
    features = torch.cat(
        (
            propeller,
            fins,
            fins * saturated[..., :2],
            hull.flatten(-2),
            strip_flow.abs() * strip_flow,
            restoring,
            (nu_r[..., :, None] * nu_r[..., None, :]).flatten(-2),
            nu_r * fade,
            nu[..., 5:6] * flow_c[..., :2],
        ),
        -1,
    )
    nu_dot = small_matmul(features, const["force_map"])
    # 11. actuator rates from the saturated states
    actuator_rate = (command - saturated) / const["time_constants"]
    return nu_dot, actuator_rate, saturated


def _trig(eta: torch.Tensor, current: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Cosines and sines of ``(phi, theta, psi, beta_c - psi)``, ``[*B, 4]`` each."""
    angles = torch.cat((eta[..., 3:], current[..., 1:2] - eta[..., 5:6]), -1)
    return angles.cos(), angles.sin()


def dynamics(
    eta: torch.Tensor,
    nu: torch.Tensor,
    actuators: torch.Tensor,
    command: torch.Tensor,
    current: torch.Tensor,
    params: Remus100Params | None = None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    r"""Accelerations and actuator rates (spec Secs. 3-6), all forces about the CO.

    .. math::

        \dot\nu = \dot\nu_c + M^{-1}\big(\tau + \tau_{ld} + \tau_{cf}
                  - C(\nu_r)\nu_r - D(U_r)\nu_r - g(\eta)\big)

    with :math:`\nu_r = \nu - \nu_c`, :math:`\nu_c = [V_c\cos(\beta_c-\psi),
    V_c\sin(\beta_c-\psi), w_c, 0, 0, 0]` and :math:`\dot\nu_c = [r v_c, -r u_c, 0, 0, 0, 0]`,
    :math:`w_c` the vertical water velocity (m/s, positive down) when ``current`` is
    ``[*B, 3]``, else 0 (PVS: :math:`w_r = w`; see the module docstring for the approximation).
    :math:`C = C_{RB}(\nu_r) + C_A(\nu_r)` (eight Munk entries of :math:`C_A` removed),
    :math:`D` diagonal with surge and sway faded by :math:`e^{-3U_r}`, :math:`\tau_{ld}` the hull
    lift/drag at the angle of attack :math:`\alpha = \operatorname{atan2}(w_r, u_r)`,
    :math:`\tau_{cf}` the 21-strip cross-flow drag, :math:`g` the restoring forces and
    :math:`\tau` the propeller and fin forces at the saturated actuator states.

    Returns:
        ``(nu_dot, actuator_rate, saturated_actuators)``: ``[*B, 6]``, ``[*B, 3]`` and
        ``[*B, 3]``; the actuator rate is taken from the saturated state:
        :math:`(u_c - \bar u_a)/T_a`.

    >>> z6 = torch.zeros(6, dtype=torch.float64)
    >>> act = torch.tensor([0.0, 0.0, 1525.0], dtype=torch.float64)
    >>> nu_dot, _, _ = dynamics(z6, z6, act, act, torch.zeros(2, dtype=torch.float64))
    >>> round(nu_dot[0].item(), 4)  # (1 - t_p) X_p (M^-1)_11 from rest at full rpm (m/s^2)
    3.2887
    """
    p = DEFAULT_PARAMS if params is None else params
    eta, nu, actuators, command, current = _same_batch(eta, nu, actuators, command, current)
    cos, sin = _trig(eta, current)
    return _features_and_rates(eta, nu, actuators, command, current, p, cos, sin)


def rotation_matrix(angles: torch.Tensor) -> torch.Tensor:
    r"""zyx Euler rotation :math:`R(\phi, \theta, \psi)` from body to NED, ``[*B, 3, 3]``
    (:mod:`~torchrl_auv.physics.euler`).

    >>> rotation_matrix(torch.tensor([0.0, 0.0, math.pi / 2])).round(decimals=6) + 0.0
    tensor([[ 0., -1.,  0.],
            [ 1.,  0.,  0.],
            [ 0.,  0.,  1.]])
    """
    return euler_matrices(trig_factors(angles.cos(), angles.sin()), rotation_only=True)


def _eta_dot(cos: torch.Tensor, sin: torch.Tensor, nu: torch.Tensor) -> torch.Tensor:
    matrices = euler_matrices(trig_factors(cos, sin))  # R and T, [*B, 2, 3, 3]
    return small_matmul(matrices, nu.unflatten(-1, (2, 3))[..., None]).flatten(-3)


def kinematics(eta: torch.Tensor, nu: torch.Tensor) -> torch.Tensor:
    r"""Euler-angle kinematics :math:`\dot\eta = [R(\Theta) v;\ T(\Theta)\omega]`, ``[*B, 6]``
    (:mod:`~torchrl_auv.physics.euler`; singular at :math:`\theta = \pm 90°`, unguarded as in
    the source).

    >>> nu = torch.tensor([1.0, 0.0, 0.0, 0.0, 0.0, 0.1])
    >>> kinematics(torch.zeros(6), nu)
    tensor([1.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.1000])
    """
    eta, nu = _same_batch(eta, nu)
    return _eta_dot(eta[..., 3:].cos(), eta[..., 3:].sin(), nu)


def _check_inputs(tensors: dict[str, torch.Tensor], widths: dict[str, tuple[int, ...]], dt) -> None:
    dtype = None
    for name, tensor in tensors.items():
        if not isinstance(tensor, torch.Tensor):
            raise ValueError(f"{name} must be a torch.Tensor, got {type(tensor).__name__}")
        if tensor.ndim == 0 or tensor.shape[-1] not in widths[name]:
            allowed = " or ".join(f"[*B, {w}]" for w in widths[name])
            raise ValueError(f"{name} must be shaped {allowed}, got {tuple(tensor.shape)}")
        if not tensor.is_floating_point():
            raise ValueError(f"{name} must be a floating tensor, got {tensor.dtype}")
        if dtype is None:
            dtype = tensor.dtype
        elif tensor.dtype != dtype:
            raise ValueError(
                f"{name} has dtype {tensor.dtype}, expected {dtype} like eta: all inputs must "
                "share one dtype"
            )
    try:
        torch.broadcast_shapes(*(t.shape[:-1] for t in tensors.values()))
    except RuntimeError as err:
        shapes = {k: tuple(t.shape) for k, t in tensors.items()}
        raise ValueError(
            f"batch dims of eta, nu, actuators, command, current must broadcast: {shapes}"
        ) from err
    if isinstance(dt, torch.Tensor):
        if not bool((dt > 0).all()):
            raise ValueError("dt must be > 0 (seconds)")
    elif not dt > 0:
        raise ValueError(f"dt must be > 0 (seconds), got {dt}")


_WIDTHS = {"eta": (6,), "nu": (6,), "actuators": (3,), "command": (3,), "current": (2, 3)}


def _check_step_inputs(eta, nu, actuators, command, current, dt) -> None:
    inputs = {"eta": eta, "nu": nu, "actuators": actuators, "command": command}
    if current is not None:
        inputs["current"] = current
    _check_inputs(inputs, _WIDTHS, dt)


def step(
    eta: torch.Tensor,
    nu: torch.Tensor,
    actuators: torch.Tensor,
    command: torch.Tensor,
    current: torch.Tensor,
    dt: float | torch.Tensor,
    params: Remus100Params | None = None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    r"""One semi-implicit Euler step of the REMUS-100 (spec Sec. 7), batched over ``[*B]``.

    .. math::

        \nu_{k+1} = \nu_k + h\,\dot\nu,\quad
        u_{a,k+1} = \bar u_{a,k} + h\,\frac{u_c - \bar u_{a,k}}{T_a},\quad
        \eta_{k+1} = \eta_k + h\,J(\eta_k)\,\nu_{k+1}

    Args:
        eta: ``[*B, 6]`` NED position (m) and Euler angles (rad).
        nu: ``[*B, 6]`` body velocities relative to the earth (m/s, rad/s).
        actuators: ``[*B, 3]`` stored rudder (rad), stern plane (rad), propeller (rpm).
        command: ``[*B, 3]`` actuator commands, same units (never clipped).
        current: ``[*B, 2]`` current speed (m/s) and direction (rad), or ``[*B, 3]`` with the
            vertical water velocity :math:`w_c` (m/s, positive down) as the third column
            (:math:`w_r = w - w_c`; see the module docstring).
        dt: step ``h`` in seconds (> 0), a float or a tensor broadcastable to ``[*B, 1]``.
        params: vehicle parameters (default REMUS-100).

    Returns:
        New ``(eta, nu, actuators)``; the inputs are not modified. The returned actuator states
        are the *unsaturated* result of the update and may exceed the limits.

    Batch dims of the five inputs must broadcast; all must share one floating dtype.

    >>> eta, nu, act = torch.zeros(6), torch.zeros(6), torch.zeros(3)
    >>> cmd, current = torch.tensor([0.0, 0.0, 1525.0]), torch.zeros(2)
    >>> for _ in range(1200):  # 60 s at full rpm from rest
    ...     eta, nu, act = step(eta, nu, act, cmd, current, 0.05)
    >>> round(nu[0].item(), 3)  # steady surge speed (m/s)
    2.554
    """
    _check_step_inputs(eta, nu, actuators, command, current, dt)
    return step_unchecked(eta, nu, actuators, command, current, dt, params)


def step_unchecked(eta, nu, actuators, command, current, dt, params=None):
    """:func:`step` without input checks (for compiled inner loops); same arguments."""
    p = DEFAULT_PARAMS if params is None else params
    eta, nu, actuators, command, current = _same_batch(eta, nu, actuators, command, current)
    cos, sin = _trig(eta, current)  # shared by the dynamics and the kinematics (both at eta_k)
    nu_dot, actuator_rate, saturated = _features_and_rates(
        eta, nu, actuators, command, current, p, cos, sin
    )
    nu_next = nu + dt * nu_dot
    actuators_next = saturated + dt * actuator_rate
    eta_next = eta + dt * _eta_dot(cos[..., :3], sin[..., :3], nu_next)
    return eta_next, nu_next, actuators_next


_COMPILED: dict[str, object] = {}


def compiled_step(
    eta: torch.Tensor,
    nu: torch.Tensor,
    actuators: torch.Tensor,
    command: torch.Tensor,
    current: torch.Tensor,
    dt: float | torch.Tensor,
    params: Remus100Params | None = None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """:func:`step` through ``torch.compile`` (same arguments, same results to rounding).

    The first call per input shape compiles (about 2-20 s on a 2-core CPU; cached on disk by
    torch afterwards); later calls fuse the whole step into a few kernels, which removes most
    of eager mode's per-op overhead: on the development machine one vehicle took ~45 us per
    step instead of ~450 us, and 4096 vehicles ~8M instead of ~2.8M vehicle-steps/s
    (``benchmarks/bench_physics.py``). Inputs are validated eagerly before the compiled call.
    """
    _check_step_inputs(eta, nu, actuators, command, current, dt)
    (DEFAULT_PARAMS if params is None else params).tensors(eta.dtype, eta.device)  # not traced
    fn = _COMPILED.get("step")
    if fn is None:
        fn = _COMPILED["step"] = torch.compile(step_unchecked, fullgraph=True, dynamic=False)
    return fn(eta, nu, actuators, command, current, dt, params)


# -- replay CLI ---------------------------------------------------------------------------
def _read_rows(path: str) -> tuple[list[str], list[dict[str, str]]]:
    with open(path, newline="") as handle:
        reader = csv.DictReader(handle)
        rows = list(reader)
        header = list(reader.fieldnames or [])
    missing = [
        c
        for c in ("step", "t", *COMMAND_COLUMNS, *CURRENT_COLUMNS, *STATE_COLUMNS)
        if c not in header
    ]
    if missing:
        raise ValueError(f"{path}: missing columns {missing}")
    if len(rows) < 1:
        raise ValueError(f"{path}: no rows")
    return header, rows


def replay(
    in_path: str, out_path: str, *, dtype: torch.dtype = torch.float64, dt: float = 0.05
) -> None:
    """Simulate a reference CSV's commands from its row-0 state and write the same format.

    Only row 0's state columns are read; every later row contributes its command and current
    columns, and the written state columns are simulated. Floats are written with ``repr``
    (shortest round-trip). ``dt`` is the step of the reference format (0.05 s).
    """
    header, rows = _read_rows(in_path)

    def column_block(row: dict[str, str], names: Sequence[str]) -> torch.Tensor:
        return torch.tensor([float(row[n]) for n in names], dtype=torch.float64).to(dtype)

    eta = column_block(rows[0], ETA_COLUMNS)
    nu = column_block(rows[0], NU_COLUMNS)
    act = column_block(rows[0], ACTUATOR_COLUMNS)
    out_rows = []
    for k, row in enumerate(rows):
        if k > 0:
            command = column_block(row, COMMAND_COLUMNS)
            current = column_block(row, CURRENT_COLUMNS)
            eta, nu, act = step(eta, nu, act, command, current, dt)
        state = torch.cat((eta, nu, act)).to(torch.float64).tolist()
        out = {name: row[name] for name in header}
        out.update({name: repr(value) for name, value in zip(STATE_COLUMNS, state, strict=True)})
        out_rows.append(out)
    with open(out_path, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=header, lineterminator="\n")
        writer.writeheader()
        writer.writerows(out_rows)
