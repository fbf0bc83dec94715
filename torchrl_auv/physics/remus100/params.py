"""REMUS-100 parameters (spec Secs. 2-6) and the quantities derived from them, as plain floats
(:mod:`~torchrl_auv.physics.remus100`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import torch


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
    #: constant tensors per (dtype, device), filled by :func:`~.forces.model_tensors`
    _tensor_cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        positive = (
            "rho",
            "g",
            "length",
            "diameter",
            "t_surge",
            "t_sway",
            "t_heave",
            "t_yaw",
            "prop_diameter",
            "j_max",
            "fin_area",
            "delta_max",
            "n_max",
            "t_fin",
            "t_prop",
        )
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


_DERIVED = (
    "semi_axes",
    "mass",
    "weight",
    "inertia",
    "added_mass",
    "mass_matrix",
    "mass_matrix_inverse",
    "damping_base",
    "hull",
    "crossflow_cd",
    "strip_positions",
)
DEFAULT_PARAMS = Remus100Params()
