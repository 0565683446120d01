"""Plain-float reference of the monitor's closed-loop servo model (``models/_servo_jit.py``).

The servo as the ground monitor models it (Lu2017 eqs. 4-13, relative degree 3): the hydraulic
plant (eq. 4) driven by the NDI valve law (eq. 13) on the model's own states, tracking the
third-order reference model driven by the rod command, with the input fault f^i added to the
saturated valve command. State ``s = [x1, x2, x3, r, r', r'']``.

:func:`deriv` is the derivative, :func:`jacobian` its analytic Jacobian with respect to the
plant states (the closed loop: the NDI law depends on them) and the input fault,
:func:`propagate` the RK4 integration over one sample interval with the transition matrix
``Phi`` and the fault input matrix ``Gamma`` (the tangent of the RK4 map) and the discrete
process noise ``Q_d`` accumulated over the substeps.
"""

from __future__ import annotations

import math

import numpy as np

from gcs_monitor.models.servo import ServoLoopParams, ServoParams

SQRT_FLOOR = 1.0e-6  # the NDI law's floor under sqrt(1 - sign x3), as the simulator's servo


class Consts:
    """The constants of eqs. 4 and 13 and of the reference model."""

    def __init__(self, p: ServoParams, lp: ServoLoopParams, stroke_m: float) -> None:
        a = p.piston_area_m2
        vm = p.mean_chamber_volume_m3
        self.aps = a * p.supply_pressure_pa
        self.bb = p.damping_nspm
        self.inv_m = 1.0 / p.moving_mass_kg
        self.vmax = p.max_valve_flow_m3ps / a
        self.leak = p.leakage_mps
        self.cnum = 2.0 * a * p.bulk_modulus_pa * vm / p.supply_pressure_pa
        self.vm2 = vm * vm
        self.a2 = a * a
        w = lp.ref_bandwidth_radps
        z2 = 2.0 * lp.ref_damping + 1.0
        self.w3, self.z2w2, self.z2w = w ** 3, z2 * w * w, z2 * w
        lam = lp.ndi_pole_radps
        self.k2, self.k1, self.k0 = 3.0 * lam, 3.0 * lam * lam, lam ** 3
        self.umax = lp.max_valve_cmd
        self.stroke = stroke_m


def chamber(c: Consts, x1: float) -> tuple[float, float]:
    """Chamber gain ``c(x1)`` and ``dc/dx1``, x1 clamped to the stroke."""
    if x1 > c.stroke:
        x1, inside = c.stroke, False
    elif x1 < -c.stroke:
        x1, inside = -c.stroke, False
    else:
        inside = True
    den = c.vm2 - c.a2 * x1 * x1
    g = c.cnum / den
    return g, (g * 2.0 * c.a2 * x1 / den if inside else 0.0)


def ndi(c: Consts, s: list[float], q_com: float) -> tuple[float, list[float]]:
    """Saturated NDI valve command and ``[du/dx1, du/dx2, du/dx3, dnum/dr, dnum/dr', dnum/dr'',
    1/b]`` (six zeros when saturated: u depends on no state)."""
    x1, x2, x3, r, rd, rdd = s
    rddd = c.w3 * (q_com - r) - c.z2w2 * rd - c.z2w * rdd
    cy, dcy = chamber(c, x1)
    ydd = (c.aps * x3 - c.bb * x2) * c.inv_m
    lf3h = (c.aps * cy * (-c.leak * x3 - x2) - c.bb * ydd) * c.inv_m
    num = rddd + c.k2 * (rdd - ydd) + c.k1 * (rd - x2) + c.k0 * (r - x1) - lf3h
    sg = 1.0 if num >= 0.0 else -1.0
    arg = 1.0 - sg * x3
    floor = arg <= SQRT_FLOOR
    sq = math.sqrt(SQRT_FLOOR if floor else arg)
    b = c.aps * c.inv_m * cy * c.vmax * sq
    u = num / b
    if u > c.umax or u < -c.umax:
        return (c.umax if u > 0.0 else -c.umax), [0.0] * 6
    dydd = [0.0, -c.bb * c.inv_m, c.aps * c.inv_m]
    dlf = [c.aps * dcy * (-c.leak * x3 - x2) * c.inv_m,
           (-c.aps * cy - c.bb * dydd[1]) * c.inv_m,
           (-c.aps * cy * c.leak - c.bb * dydd[2]) * c.inv_m]
    dnum = [-c.k0 - dlf[0], -c.k1 - c.k2 * dydd[1] - dlf[1], -c.k2 * dydd[2] - dlf[2]]
    db = [b * dcy / cy, 0.0, 0.0 if floor else -b * sg / (2.0 * arg)]
    dx = [(dn - u * dbi) / b for dn, dbi in zip(dnum, db, strict=True)]
    # num = r''' + k2 r'' + k1 r' + k0 r + ... with r''' = w^3 (q - r) - z2 w^2 r' - z2 w r'';
    # returned as d num / dr and 1 / b (the kernel's order of operations)
    return u, dx + [c.k0 - c.w3, c.k1 - c.z2w2, c.k2 - c.z2w, 1.0 / b]


def deriv(c: Consts, s: list[float], q_com: float, f_in: float) -> list[float]:
    """``ds/dt`` of the closed loop with input fault ``f_in`` (valve units)."""
    x1, x2, x3, r, rd, rdd = s
    u, _ = ndi(c, s, q_com)
    ut = u + f_in
    sg = 1.0 if ut >= 0.0 else -1.0
    arg = 1.0 - sg * x3
    flow = c.vmax * (math.sqrt(arg) if arg > 0.0 else 0.0) * ut
    cx, _ = chamber(c, x1)
    rddd = c.w3 * (q_com - r) - c.z2w2 * rd - c.z2w * rdd
    return [x2, (c.aps * x3 - c.bb * x2) * c.inv_m, cx * (flow - c.leak * x3 - x2), rd, rdd, rddd]


def jacobian(c: Consts, s: list[float], q_com: float, f_in: float) -> tuple[np.ndarray,
                                                                          np.ndarray]:
    """``A = ds_dot/ds`` (6, 6) of the closed loop and ``G = ds_dot/df^i`` (6,)."""
    x1, x2, x3 = s[0], s[1], s[2]
    u, du = ndi(c, s, q_com)
    ut = u + f_in
    sg = 1.0 if ut >= 0.0 else -1.0
    arg = 1.0 - sg * x3
    sq = math.sqrt(arg) if arg > 0.0 else 0.0
    dsq = -sg / (2.0 * sq) if sq > 0.0 else 0.0
    cx, dcx = chamber(c, x1)
    A = np.zeros((6, 6))
    A[0, 1] = 1.0
    A[1, 1] = -c.bb * c.inv_m
    A[1, 2] = c.aps * c.inv_m
    A[2, 0] = dcx * (c.vmax * sq * ut - c.leak * x3 - x2) + cx * c.vmax * sq * du[0]
    A[2, 1] = cx * (c.vmax * sq * du[1] - 1.0)
    A[2, 2] = cx * (c.vmax * (dsq * ut + sq * du[2]) - c.leak)
    if len(du) > 6:  # unsaturated
        k = cx * c.vmax * sq * du[6]
        for j in range(3):
            A[2, 3 + j] = k * du[3 + j]
    A[3, 4] = 1.0
    A[4, 5] = 1.0
    A[5, 3:] = [-c.w3, -c.z2w2, -c.z2w]
    G = np.array([0.0, 0.0, cx * c.vmax * sq, 0.0, 0.0, 0.0])
    return A, G


def command_at(qc0: float, qc1: float, t: float, t_knee: float) -> float:
    """Linear from qc0 to qc1 until t_knee, qc1 after."""
    return qc1 if t >= t_knee else qc0 + (qc1 - qc0) * t / t_knee


def propagate(c: Consts, s0: list[float], qc0: float, qc1: float, f_in: float, dt: float,
              n_sub: int, q_valve: float, q_state: tuple[float, ...], t_knee: float | None = None
              ) -> tuple[list[float], np.ndarray, np.ndarray, np.ndarray]:
    """RK4 over ``dt`` in ``n_sub`` substeps, the command linear from qc0 to qc1 until
    ``t_knee`` (default: dt), then held.

    Returns the state at the end, ``Phi`` (6, 6), ``Gamma`` (6,) and ``Q_d`` (6, 6): per
    substep the tangent ``M = [Phi_i | Gamma_i]`` of the RK4 map (``M' = A M + [0 | G]`` with
    the same stages, from ``[I | 0]``), ``Phi = Phi_n ... Phi_1``, ``Gamma <- Phi_i Gamma +
    Gamma_i``, ``Q_d <- Phi_i Q_d Phi_i^T + (G q_valve G^T + diag(q_state)) h`` with ``G`` at
    the substep's start.
    """
    h = dt / n_sub
    s = np.array(s0, dtype=float)
    Phi = np.eye(6)
    Gam = np.zeros(6)
    Qd = np.zeros((6, 6))
    tk = dt if t_knee is None else t_knee

    def rates(x: np.ndarray, q: float, M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        A, G = jacobian(c, list(x), q, f_in)
        K = A @ M
        K[:, 6] += G
        return np.array(deriv(c, list(x), q, f_in)), K

    for i in range(n_sub):
        t0 = i * h
        qa = command_at(qc0, qc1, t0, tk)
        qm = command_at(qc0, qc1, t0 + 0.5 * h, tk)
        qb = command_at(qc0, qc1, t0 + h, tk)
        M = np.hstack([np.eye(6), np.zeros((6, 1))])
        _, G0 = jacobian(c, list(s), qa, f_in)
        k1, K1 = rates(s, qa, M)
        k2, K2 = rates(s + 0.5 * h * k1, qm, M + 0.5 * h * K1)
        k3, K3 = rates(s + 0.5 * h * k2, qm, M + 0.5 * h * K2)
        k4, K4 = rates(s + h * k3, qb, M + h * K3)
        s = s + h / 6.0 * (k1 + 2.0 * (k2 + k3) + k4)
        M = M + h / 6.0 * (K1 + 2.0 * (K2 + K3) + K4)
        Pi, Gi = M[:, :6], M[:, 6]
        Phi = Pi @ Phi
        Gam = Pi @ Gam + Gi
        Qd = Pi @ Qd @ Pi.T + (np.outer(G0, G0) * q_valve + np.diag(q_state)) * h
    return list(s), Phi, Gam, 0.5 * (Qd + Qd.T)


def command_timing_noise(c: Consts, s: list[float], qc0: float, qc1: float, f_in: float,
                         dt: float, n_sub: int) -> np.ndarray:
    """``e e^T / 12`` with ``e`` the end-state difference between the command at qc1 and at
    qc0 all along the interval."""
    if qc1 == qc0:
        return np.zeros((6, 6))
    z = (0.0,) * 6
    sa = np.array(propagate(c, s, qc1, qc1, f_in, dt, n_sub, 0.0, z)[0])
    sb = np.array(propagate(c, s, qc0, qc0, f_in, dt, n_sub, 0.0, z)[0])
    e = sa - sb
    return np.outer(e, e) / 12.0
