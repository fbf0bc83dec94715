"""The REMUS-100's forces: actuator saturation, propeller, Coriolis, and the linear map from the
model's features to the acceleration (:mod:`~torchrl_auv.physics.remus100`)."""

from __future__ import annotations

import torch

from torchrl_auv.physics.remus100.params import DEFAULT_PARAMS, Remus100Params


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
    :math:`X_p/(\rho D_p^4) = K_{T0} n_s^2 + a\,(V_a/D_p)\,n_s` with
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
    ("propeller", 2),
    ("fins", 2),
    ("fin_drag", 2),
    ("hull", 6),
    ("crossflow", None),
    ("restoring", 2),
    ("coriolis", 36),
    ("damping", 6),
    ("current_rotation", 2),
)


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
    add(
        X=(1 - p.thrust_deduction) * (thrust[1] - thrust[0]).item(),
        K=(torque[1] - torque[0]).item() / 10.0,
    )
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


def model_tensors(
    params: Remus100Params, dtype: torch.dtype, device: torch.device | None
) -> dict[str, torch.Tensor]:
    """Constant tensors :func:`~torchrl_auv.physics.remus100.dynamics` reads (strip positions,
    actuator limits and time constants, the feature-to-acceleration map), cached on ``params``
    per ``(dtype, device)``.

    >>> from torchrl_auv.physics.remus100 import DEFAULT_PARAMS
    >>> model_tensors(DEFAULT_PARAMS, torch.float64, None)["limits"].tolist()[2]
    1525.0
    """
    key = (dtype, torch.device(device) if device is not None else torch.device("cpu"))
    cached = params._tensor_cache.get(key)
    if cached is None:
        kwargs = {"dtype": dtype, "device": key[1]}
        cached = {
            "strips": torch.tensor(params.strip_positions, **kwargs),
            "limits": torch.tensor((params.delta_max, params.delta_max, params.n_max), **kwargs),
            "time_constants": torch.tensor((params.t_fin, params.t_fin, params.t_prop), **kwargs),
            "faded": torch.tensor((True, True, False, False, False, False), device=key[1]),
            "powers": torch.tensor((0.0, 1.0, 2.0), **kwargs),
            "force_map": _force_map(params).to(**kwargs),
        }
        params._tensor_cache[key] = cached
    return cached
