"""The rigid body in numba: its equations of motion and RK4 step, one implementation.

:func:`evaluate` is the derivative and outputs of the 6-DOF model (the equations are in the
``rigid_body`` module docstring: Lu2016 eq. 11 rows 1-3 with gravity eq. 12, the quaternion
kinematics, Beard & McLain eq. 3.17; aero and thrust as ``sim_vehicle.dynamics.aero``);
``RigidBody.evaluate`` wraps it for the trim and :func:`step` is the simulation loop's RK4
step. The plain-float reference of the equivalence test is ``tests/reference/rigid_body.py``.
The airframe's numbers travel in one float array built by :func:`pack_params`; the ``P_*``
names are its indices. Inputs are one array ``(da, de, dr, thr_cmd, wn, we, wd)``. Loaded
through ``gcs_monitor.core.kernels``.
"""
# mypy: disable-error-code="no-untyped-def"

from __future__ import annotations

import math

import numba
import numpy as np

from gcs_monitor.core import constants as k

# the earth and ISA constants below are compiled in as constants: see gcs_monitor.core.kernels
KERNEL_DEPENDENCIES = {"gcs_monitor.core.constants": "0b300fc9f27503d8"}

jit = numba.njit(cache=True, fastmath=False, nogil=True)

_R_E = k.EARTH_RADIUS_M
_OMEGA = k.EARTH_RATE_RADPS
_G_EQ = k.GRAVITY_EQUATOR_MPS2
_G_K1 = k.GRAVITY_LAT_K1
_G_K2 = k.GRAVITY_LAT_K2
_T0 = k.ISA_T0_K
_LAPSE = k.ISA_LAPSE_KPM
_P0 = k.ISA_P0_PA
_R_AIR = k.ISA_R_JPKGK
_RHO0 = k.ISA_RHO0_KGPM3
_GAS_EXP = -k.GRAVITY_STD_MPS2 / (k.ISA_R_JPKGK * k.ISA_LAPSE_KPM)

_NAMES = (
    # geometry and induced drag
    "S", "B", "C", "K_IND", "CL_Q_EFF", "CM_Q_EFF", "BLEND", "STALL_M", "STALL_A0",
    # aero coefficients
    "CL0", "CL_ALPHA", "CL_DE", "CD0", "CD_ALPHA", "CD_DE", "CL_MINDRAG", "CM0", "CM_ALPHA",
    "CM_DE", "CY_BETA", "CY_P", "CY_R", "CY_DA", "CY_DR", "CROLL_BETA", "CROLL_P", "CROLL_R",
    "CROLL_DA", "CROLL_DR", "CN_BETA", "CN_P", "CN_R", "CN_DA", "CN_DR",
    # propulsion
    "JET", "MAX_THRUST", "DENS_EXP", "K_MOTOR", "S_PROP", "C_PROP", "TAU_ENGINE",
    # mass
    "MASS", "G1", "G2", "G3", "G4", "G5", "G6", "G7", "G8", "JY",
)
(
    P_S, P_B, P_C, P_K_IND, P_CL_Q_EFF, P_CM_Q_EFF, P_BLEND, P_STALL_M, P_STALL_A0,
    P_CL0, P_CL_ALPHA, P_CL_DE, P_CD0, P_CD_ALPHA, P_CD_DE, P_CL_MINDRAG, P_CM0, P_CM_ALPHA,
    P_CM_DE, P_CY_BETA, P_CY_P, P_CY_R, P_CY_DA, P_CY_DR, P_CROLL_BETA, P_CROLL_P, P_CROLL_R,
    P_CROLL_DA, P_CROLL_DR, P_CN_BETA, P_CN_P, P_CN_R, P_CN_DA, P_CN_DR,
    P_JET, P_MAX_THRUST, P_DENS_EXP, P_K_MOTOR, P_S_PROP, P_C_PROP, P_TAU_ENGINE,
    P_MASS, P_G1, P_G2, P_G3, P_G4, P_G5, P_G6, P_G7, P_G8, P_JY,
) = range(len(_NAMES))
N_PARAMS = len(_NAMES)
N_STATE = 14
N_OUT = 8  # f_x, f_y, f_z, tas, alpha, beta, rho, thrust


def pack_params(body) -> np.ndarray:  # noqa: ANN001 - a RigidBody (import cycle)
    """The parameter array of a :class:`~sim_vehicle.dynamics.rigid_body.RigidBody`."""
    ae = body.aero
    a = ae.coef
    pr = ae.prop
    vals = {
        "S": ae.S, "B": ae.b, "C": ae.c, "K_IND": ae.k_ind, "CL_Q_EFF": ae.cl_q_eff,
        "CM_Q_EFF": ae.cm_q_eff, "BLEND": 1.0 if ae.blend else 0.0,
        "STALL_M": a.stall_blend_m, "STALL_A0": a.stall_alpha0_rad,
        "CL0": a.cl0, "CL_ALPHA": a.cl_alpha, "CL_DE": a.cl_de, "CD0": a.cd0,
        "CD_ALPHA": a.cd_alpha, "CD_DE": a.cd_de, "CL_MINDRAG": a.cl_mindrag, "CM0": a.cm0,
        "CM_ALPHA": a.cm_alpha, "CM_DE": a.cm_de, "CY_BETA": a.cy_beta, "CY_P": a.cy_p,
        "CY_R": a.cy_r, "CY_DA": a.cy_da, "CY_DR": a.cy_dr, "CROLL_BETA": a.croll_beta,
        "CROLL_P": a.croll_p, "CROLL_R": a.croll_r, "CROLL_DA": a.croll_da,
        "CROLL_DR": a.croll_dr, "CN_BETA": a.cn_beta, "CN_P": a.cn_p, "CN_R": a.cn_r,
        "CN_DA": a.cn_da, "CN_DR": a.cn_dr,
        "JET": 1.0 if ae.jet else 0.0, "MAX_THRUST": pr.max_thrust_n,
        "DENS_EXP": pr.density_exponent, "K_MOTOR": pr.k_motor_mps, "S_PROP": pr.s_prop_m2,
        "C_PROP": pr.c_prop, "TAU_ENGINE": body.tau_engine_s,
        "MASS": body.mass_kg, "G1": body.g1, "G2": body.g2, "G3": body.g3, "G4": body.g4,
        "G5": body.g5, "G6": body.g6, "G7": body.g7, "G8": body.g8, "JY": body.jy,
    }
    return np.array([float(vals[n]) for n in _NAMES])


@jit
def dcm_from_quat(q0, q1, q2, q3):
    """Row-major ``C_ned_frd`` of a unit quaternion (as ``gcs_monitor.core.frames``)."""
    return (
        1.0 - 2.0 * (q2 * q2 + q3 * q3),
        2.0 * (q1 * q2 - q0 * q3),
        2.0 * (q1 * q3 + q0 * q2),
        2.0 * (q1 * q2 + q0 * q3),
        1.0 - 2.0 * (q1 * q1 + q3 * q3),
        2.0 * (q2 * q3 - q0 * q1),
        2.0 * (q1 * q3 - q0 * q2),
        2.0 * (q2 * q3 + q0 * q1),
        1.0 - 2.0 * (q1 * q1 + q2 * q2),
    )


@jit
def gravity(lat, h):
    """Lu2016 eq. 12 (as ``gcs_monitor.core.atmosphere.gravity_mps2``)."""
    s = math.sin(lat)
    s2 = math.sin(2.0 * lat)
    ratio = _R_E / (_R_E + h)
    return _G_EQ * ratio * ratio * (1.0 + _G_K1 * s * s - _G_K2 * s2 * s2)


@jit
def isa_density(h):
    """ISA troposphere density (as ``gcs_monitor.core.atmosphere.isa_density_kgpm3``)."""
    t_k = _T0 + _LAPSE * h
    return _P0 * (t_k / _T0) ** _GAS_EXP / (_R_AIR * t_k)


@jit
def evaluate(s, inp, prm, deriv, out):
    """Fill ``deriv`` (14) and ``out`` (8) at state ``s`` with inputs ``inp`` (7).

    ``out`` is (f_x, f_y, f_z, tas, alpha, beta, rho, thrust): specific force FRD (m/s^2), air
    data (m/s, rad), density (kg/m^3), thrust (N).
    """
    lat = s[0]
    h = s[2]
    vn = s[3]
    ve = s[4]
    vd = s[5]
    q0 = s[6]
    q1 = s[7]
    q2 = s[8]
    q3 = s[9]
    p = s[10]
    q = s[11]
    r = s[12]
    thr = s[13]
    da = inp[0]
    de = inp[1]
    dr = inp[2]
    c00, c01, c02, c10, c11, c12, c20, c21, c22 = dcm_from_quat(q0, q1, q2, q3)
    an = vn - inp[4]
    ae = ve - inp[5]
    ad = vd - inp[6]
    u = c00 * an + c10 * ae + c20 * ad
    v = c01 * an + c11 * ae + c21 * ad
    w = c02 * an + c12 * ae + c22 * ad
    rho = isa_density(h)
    # aero forces and moments (sim_vehicle.dynamics.aero)
    tas = math.sqrt(u * u + v * v + w * w)
    if tas < 1.0e-3:
        fx = fy = fz = ml = mm = mn = 0.0
    else:
        alpha = math.atan2(w, u)
        beta = math.asin(v / tas)
        qbar_s = 0.5 * rho * tas * tas * prm[P_S]
        half_inv_v = 0.5 / tas
        qhat = prm[P_C] * q * half_inv_v
        phat = prm[P_B] * p * half_inv_v
        rhat = prm[P_B] * r * half_inv_v
        lin = prm[P_CL0] + prm[P_CL_ALPHA] * alpha
        if prm[P_BLEND] != 0.0:
            m = prm[P_STALL_M]
            a0 = prm[P_STALL_A0]
            e1 = math.exp(-m * (alpha - a0))
            e2 = math.exp(m * (alpha + a0))
            sig = (1.0 + e1 + e2) / ((1.0 + e1) * (1.0 + e2))
            sa = math.sin(alpha)
            flat = 2.0 * math.copysign(1.0, alpha) * sa * sa * math.cos(alpha)
            lin = (1.0 - sig) * lin + sig * flat
        cl = lin + prm[P_CL_Q_EFF] * qhat + prm[P_CL_DE] * de
        dcl = cl - prm[P_CL_MINDRAG]
        cd = (
            prm[P_CD0] + prm[P_CD_ALPHA] * alpha + prm[P_CD_DE] * abs(de)
            + prm[P_K_IND] * dcl * dcl
        )
        ca = math.cos(alpha)
        sa = math.sin(alpha)
        fx = qbar_s * (-cd * ca + cl * sa)
        fz = qbar_s * (-cd * sa - cl * ca)
        fy = qbar_s * (
            prm[P_CY_BETA] * beta + prm[P_CY_P] * phat + prm[P_CY_R] * rhat
            + prm[P_CY_DA] * da + prm[P_CY_DR] * dr
        )
        ml = qbar_s * prm[P_B] * (
            prm[P_CROLL_BETA] * beta + prm[P_CROLL_P] * phat + prm[P_CROLL_R] * rhat
            + prm[P_CROLL_DA] * da + prm[P_CROLL_DR] * dr
        )
        mm = qbar_s * prm[P_C] * (
            prm[P_CM0] + prm[P_CM_ALPHA] * alpha + prm[P_CM_Q_EFF] * qhat + prm[P_CM_DE] * de
        )
        mn = qbar_s * prm[P_B] * (
            prm[P_CN_BETA] * beta + prm[P_CN_P] * phat + prm[P_CN_R] * rhat
            + prm[P_CN_DA] * da + prm[P_CN_DR] * dr
        )
    # thrust (sim_vehicle.dynamics.aero)
    if prm[P_JET] != 0.0:
        thrust = thr * prm[P_MAX_THRUST] * (rho / _RHO0) ** prm[P_DENS_EXP]
    else:
        km = prm[P_K_MOTOR] * thr
        thrust = 0.5 * rho * prm[P_S_PROP] * prm[P_C_PROP] * (km * km - tas * tas)
    inv_m = 1.0 / prm[P_MASS]
    ax = (fx + thrust) * inv_m
    ay = fy * inv_m
    az = fz * inv_m
    fn = c00 * ax + c01 * ay + c02 * az
    fe = c10 * ax + c11 * ay + c12 * az
    fd = c20 * ax + c21 * ay + c22 * az
    rh = _R_E + h
    om = _OMEGA
    sl = math.sin(lat)
    cl_ = math.cos(lat)
    tl = sl / cl_
    g = gravity(lat, h)
    # Lu2016 eq. 11 rows 1-3 (transport rate + Coriolis)
    deriv[0] = vn / rh
    deriv[1] = ve / (rh * cl_)
    deriv[2] = -vd
    deriv[3] = fn + vn * vd / rh - ve * ve * tl / rh - 2.0 * om * ve * sl
    deriv[4] = fe + vn * ve * tl / rh + ve * vd / rh + 2.0 * om * (vn * sl + vd * cl_)
    deriv[5] = fd - vn * vn / rh - ve * ve / rh - 2.0 * om * ve * cl_ + g
    # omega_in (earth rate + transport rate), NED, then body; quaternion kinematics
    win = ve / rh + om * cl_
    wie = -vn / rh
    wid = -ve * tl / rh - om * sl
    pb = p - (c00 * win + c10 * wie + c20 * wid)
    qb = q - (c01 * win + c11 * wie + c21 * wid)
    rb = r - (c02 * win + c12 * wie + c22 * wid)
    deriv[6] = 0.5 * (-q1 * pb - q2 * qb - q3 * rb)
    deriv[7] = 0.5 * (q0 * pb + q2 * rb - q3 * qb)
    deriv[8] = 0.5 * (q0 * qb - q1 * rb + q3 * pb)
    deriv[9] = 0.5 * (q0 * rb + q1 * qb - q2 * pb)
    # Euler's equations (Beard eq. 3.17)
    g1 = prm[P_G1]
    g4 = prm[P_G4]
    deriv[10] = g1 * p * q - prm[P_G2] * q * r + prm[P_G3] * ml + g4 * mn
    deriv[11] = prm[P_G5] * p * r - prm[P_G6] * (p * p - r * r) + mm / prm[P_JY]
    deriv[12] = prm[P_G7] * p * q - g1 * q * r + g4 * ml + prm[P_G8] * mn
    deriv[13] = (inp[3] - thr) / prm[P_TAU_ENGINE]
    out[0] = ax
    out[1] = ay
    out[2] = az
    out[3] = tas
    out[4] = math.atan2(w, u)
    if tas > 0.0:
        out[5] = math.asin(max(-1.0, min(1.0, v / tas)))
    else:
        out[5] = 0.0
    out[6] = rho
    out[7] = thrust


@jit
def step(s, dt_s, inp, k1, prm, s_new, deriv_new, out_new):
    """One classical RK4 step with ``k1`` given, then :func:`evaluate` at the new state.

    ``inp`` (14) holds the inputs at the step start then at its end: they vary linearly, so
    that the surfaces and the wind keep the specific force continuous across steps;
    writes the new state, its derivative and outputs (with the end inputs) to the last three
    arrays, which must not alias ``s`` or ``k1``.
    """
    n = s.shape[0]
    inp0 = inp[:7]
    inp1 = inp[7:]
    mid = np.empty(7)
    for i in range(7):
        mid[i] = 0.5 * (inp0[i] + inp1[i])
    k2 = np.empty(n)
    k3 = np.empty(n)
    k4 = np.empty(n)
    x = s_new
    h = 0.5 * dt_s
    for i in range(n):
        x[i] = s[i] + h * k1[i]
    evaluate(x, mid, prm, k2, out_new)
    for i in range(n):
        x[i] = s[i] + h * k2[i]
    evaluate(x, mid, prm, k3, out_new)
    for i in range(n):
        x[i] = s[i] + dt_s * k3[i]
    evaluate(x, inp1, prm, k4, out_new)
    d6 = dt_s / 6.0
    for i in range(n):
        x[i] = s[i] + d6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i])
    nq = math.sqrt(x[6] ** 2 + x[7] ** 2 + x[8] ** 2 + x[9] ** 2)
    for i in range(6, 10):
        x[i] /= nq
    evaluate(x, inp1, prm, deriv_new, out_new)
