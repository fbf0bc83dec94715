"""The REMUS-100 equations of motion and one semi-implicit Euler step, eager or compiled
(:mod:`~torchrl_auv.physics.remus100`)."""

from __future__ import annotations

import torch

from torchrl_auv.physics._ops import small_matmul
from torchrl_auv.physics.euler import euler_matrices, trig_factors
from torchrl_auv.physics.remus100.forces import model_tensors, saturate
from torchrl_auv.physics.remus100.params import DEFAULT_PARAMS, Remus100Params


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
    const = model_tensors(p, nu.dtype, nu.device)
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

    >>> import math
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
    model_tensors(DEFAULT_PARAMS if params is None else params, eta.dtype, eta.device)  # eager
    fn = _COMPILED.get("step")
    if fn is None:
        fn = _COMPILED["step"] = torch.compile(step_unchecked, fullgraph=True, dynamic=False)
    return fn(eta, nu, actuators, command, current, dt, params)
