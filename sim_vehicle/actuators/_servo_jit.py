"""The servo bank in numba (Lu2017 eqs. 4-13): its one implementation.

Per surface: the hydraulic plant (eq. 4), the NDI valve law (eq. 13) tracking the third-order
reference model, the actuator faults on the valve command, RK4 over the simulation step and the
mechanical stop (:func:`step_bank`); a jammed surface keeps only its reference model running
(:func:`jam_step`). ``ServoBank`` calls them; the plain-float reference of the equivalence test
is ``tests/reference/servo_bank.py`` (and ``gcs_monitor.models.servo`` the equations in the
paper's form). The constants travel in one array built by :func:`pack_params`; the per-surface
inputs in a ``(3, N_IN)`` array whose columns are the ``I_*`` names below. Loaded through
``gcs_monitor.core.kernels``.
"""
# mypy: disable-error-code="no-untyped-def"

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numba
import numpy as np

if TYPE_CHECKING:  # pack_params reads their fields; no jitted code uses another module
    from gcs_monitor.models.servo import ServoLoopParams, ServoParams

jit = numba.njit(cache=True, fastmath=False, nogil=True)

# parameter array
(
    P_APS, P_BB, P_INV_M, P_VMAX, P_LEAK, P_CNUM, P_VM2, P_A2, P_W3, P_Z2W2, P_Z2W,
    P_K2, P_K1, P_K0, P_UMAX, P_STROKE,
) = range(16)
N_PARAMS = 16
# per-surface input columns: integrate? (1/0), rod command, sensor bias, fault on the valve
# (1/0), runaway direction, u replaced (1/0), replacement, additive u, stalled pressure at stop
(
    I_ACTIVE, I_Q_COM, I_BIAS, I_EFF, I_RUNAWAY, I_HAS_REP, I_REP, I_ADD, I_STALL_P,
) = range(9)
N_IN = 9


def pack_params(p: ServoParams, lp: ServoLoopParams, stroke_m: float) -> np.ndarray:
    """The constants of eqs. 4 and 13 and of the reference model, plus the rod stroke."""
    a = p.piston_area_m2
    vm = p.mean_chamber_volume_m3
    w = lp.ref_bandwidth_radps
    z2 = 2.0 * lp.ref_damping + 1.0
    lam = lp.ndi_pole_radps
    out = np.empty(N_PARAMS)
    out[P_APS] = a * p.supply_pressure_pa
    out[P_BB] = p.damping_nspm
    out[P_INV_M] = 1.0 / p.moving_mass_kg
    out[P_VMAX] = p.max_valve_flow_m3ps / a
    out[P_LEAK] = p.leakage_mps
    out[P_CNUM] = 2.0 * a * p.bulk_modulus_pa * vm / p.supply_pressure_pa
    out[P_VM2] = vm * vm
    out[P_A2] = a * a
    out[P_W3] = w * w * w
    out[P_Z2W2] = z2 * w * w
    out[P_Z2W] = z2 * w
    out[P_K2] = 3.0 * lam
    out[P_K1] = 3.0 * lam * lam
    out[P_K0] = lam * lam * lam
    out[P_UMAX] = lp.max_valve_cmd
    out[P_STROKE] = stroke_m
    return out


@jit
def _reference_jerk(r, rd, rdd, q_com, prm):
    """Third derivative of the reference model ``w^3 / ((s + w)(s^2 + 2 zeta w s + w^2))``
    driven by the rod command ``q_com``."""
    return prm[P_W3] * (q_com - r) - prm[P_Z2W2] * rd - prm[P_Z2W] * rdd


@jit
def _deriv(s, k, inp, prm, d):
    """``d = f(s)`` of surface ``k``: plant (Lu2017 eq. 4), NDI law (eq. 13) on the biased rod
    sensor (eq. 5), valve faults, reference model."""
    x1 = s[0]
    x2 = s[1]
    x3 = s[2]
    r = s[3]
    rd = s[4]
    rdd = s[5]
    aps = prm[P_APS]
    bb = prm[P_BB]
    inv_m = prm[P_INV_M]
    vmax = prm[P_VMAX]
    leak = prm[P_LEAK]
    cnum = prm[P_CNUM]
    vm2 = prm[P_VM2]
    a2 = prm[P_A2]
    umax = prm[P_UMAX]
    rddd = _reference_jerk(r, rd, rdd, inp[k, I_Q_COM], prm)
    y = x1 + inp[k, I_BIAS]
    ydd = (aps * x3 - bb * x2) * inv_m
    cy = cnum / (vm2 - a2 * y * y)
    lf3h = (aps * cy * (-leak * x3 - x2) - bb * ydd) * inv_m
    num = (rddd + prm[P_K2] * (rdd - ydd) + prm[P_K1] * (rd - x2) + prm[P_K0] * (r - y)
           - lf3h)
    sg = 1.0 if num >= 0.0 else -1.0
    arg = 1.0 - sg * x3
    u = num / (aps * inv_m * cy * vmax * math.sqrt(arg if arg > 1.0e-6 else 1.0e-6))
    u = umax if u > umax else (-umax if u < -umax else u)
    if inp[k, I_EFF] != 0.0:  # faults.apply_to_valve
        if inp[k, I_RUNAWAY] != 0.0:
            u = inp[k, I_RUNAWAY]
        elif inp[k, I_HAS_REP] != 0.0:
            u = inp[k, I_REP]
        else:
            u = u + inp[k, I_ADD]
    sg = 1.0 if u >= 0.0 else -1.0
    arg = 1.0 - sg * x3
    flow = vmax * (math.sqrt(arg) if arg > 0.0 else 0.0) * u
    d[0] = x2
    d[1] = ydd
    d[2] = cnum / (vm2 - a2 * x1 * x1) * (flow - leak * x3 - x2)
    d[3] = rd
    d[4] = rdd
    d[5] = rddd


@jit
def step_bank(xs, inp, dt_s, prm):
    """RK4 over ``dt_s`` of every surface with ``inp[k, I_ACTIVE]`` set; ``xs`` (3, 6) in place."""
    ka = np.empty(6)
    kb = np.empty(6)
    kc = np.empty(6)
    kd = np.empty(6)
    t = np.empty(6)
    h = 0.5 * dt_s
    e = dt_s / 6.0
    stroke = prm[P_STROKE]
    for k in range(xs.shape[0]):
        if inp[k, I_ACTIVE] == 0.0:
            continue
        s = xs[k]
        _deriv(s, k, inp, prm, ka)
        for i in range(6):
            t[i] = s[i] + h * ka[i]
        _deriv(t, k, inp, prm, kb)
        for i in range(6):
            t[i] = s[i] + h * kb[i]
        _deriv(t, k, inp, prm, kc)
        for i in range(6):
            t[i] = s[i] + dt_s * kc[i]
        _deriv(t, k, inp, prm, kd)
        for i in range(6):
            s[i] = s[i] + e * (ka[i] + 2.0 * (kb[i] + kc[i]) + kd[i])
        if s[0] > stroke or s[0] < -stroke:  # mechanical stop (see ServoBank.step)
            s[0] = stroke if s[0] > 0.0 else -stroke
            s[1] = 0.0
            u_end = inp[k, I_RUNAWAY] if inp[k, I_EFF] != 0.0 else 0.0
            if u_end * s[0] > 0.0:
                s[2] = inp[k, I_STALL_P]


@jit
def jam_step(s, q_com, dt_s, prm, jam_pos):
    """A jammed surface over ``dt_s``: the rod held at ``jam_pos`` (``x2 = 0``), the reference
    model stepped by explicit Euler; ``s`` (6,) in place."""
    rd = s[4]
    rdd = s[5]
    rddd = _reference_jerk(s[3], rd, rdd, q_com, prm)
    s[3] += dt_s * rd
    s[4] += dt_s * rdd
    s[5] += dt_s * rddd
    s[0] = jam_pos
    s[1] = 0.0
