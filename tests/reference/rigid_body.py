"""Plain-float reference of the rigid-body kernels (``sim_vehicle/dynamics/_rigid_body_jit.py``).

The equations of motion, aero and thrust, and the RK4 step as ``RigidBody.evaluate``,
``AeroModel`` and ``rigid_body.rk4_step`` computed them in Python before they wrapped the kernels
(the equations are in the ``rigid_body`` and ``aero`` module docstrings).
"""

from __future__ import annotations

import math
from typing import cast

from gcs_monitor.core import constants as k
from sim_vehicle.dynamics.aero import AeroModel
from sim_vehicle.dynamics.rigid_body import RigidBody

_GAS_EXP = -k.GRAVITY_STD_MPS2 / (k.ISA_R_JPKGK * k.ISA_LAPSE_KPM)


def isa_density_fast(h_m: float) -> float:
    """ISA troposphere density (same as gcs_monitor.core.atmosphere.isa_density_kgpm3)."""
    t = k.ISA_T0_K + k.ISA_LAPSE_KPM * h_m
    return cast(float, k.ISA_P0_PA * (t / k.ISA_T0_K) ** _GAS_EXP / (k.ISA_R_JPKGK * t))


def gravity_fast(lat: float, h: float) -> float:
    """Lu2016 eq. 12 (same as gcs_monitor.core.atmosphere.gravity_mps2)."""
    s = math.sin(lat)
    s2 = math.sin(2.0 * lat)
    ratio = k.EARTH_RADIUS_M / (k.EARTH_RADIUS_M + h)
    return (
        k.GRAVITY_EQUATOR_MPS2
        * ratio
        * ratio
        * (1.0 + k.GRAVITY_LAT_K1 * s * s - k.GRAVITY_LAT_K2 * s2 * s2)
    )


def dcm_from_quat_fast(q0: float, q1: float, q2: float, q3: float) -> tuple[float, ...]:
    """Row-major C_ned_frd of a unit quaternion (as gcs_monitor.core.frames.dcm_from_quat)."""
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


def lift_coeff(aero: AeroModel, alpha: float, qhat: float, de: float) -> float:
    a = aero.coef
    lin = a.cl0 + a.cl_alpha * alpha
    if aero.blend:
        m = a.stall_blend_m
        a0 = a.stall_alpha0_rad
        e1 = math.exp(-m * (alpha - a0))
        e2 = math.exp(m * (alpha + a0))
        sig = (1.0 + e1 + e2) / ((1.0 + e1) * (1.0 + e2))
        sa = math.sin(alpha)
        flat = 2.0 * math.copysign(1.0, alpha) * sa * sa * math.cos(alpha)
        lin = (1.0 - sig) * lin + sig * flat
    return lin + aero.cl_q_eff * qhat + a.cl_de * de

def thrust_n(
    aero: AeroModel, throttle: float, tas_mps: float, rho_kgpm3: float, rho0_kgpm3: float
) -> float:
    pr = aero.prop
    if aero.jet:
        return cast(float, throttle * pr.max_thrust_n
                    * (rho_kgpm3 / rho0_kgpm3) ** pr.density_exponent)
    k = pr.k_motor_mps * throttle
    return 0.5 * rho_kgpm3 * pr.s_prop_m2 * pr.c_prop * (k * k - tas_mps * tas_mps)

def forces_moments(
    aero: AeroModel,
    u: float,
    v: float,
    w: float,
    p: float,
    q: float,
    r: float,
    da: float,
    de: float,
    dr: float,
    rho: float,
) -> tuple[float, float, float, float, float, float]:
    """Aerodynamic force (N) and moment (N m) in FRD from body air velocity (u, v, w) m/s."""
    a = aero.coef
    tas = math.sqrt(u * u + v * v + w * w)
    if tas < 1.0e-3:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    alpha = math.atan2(w, u)
    beta = math.asin(v / tas)
    qbar_s = 0.5 * rho * tas * tas * aero.S
    half_inv_v = 0.5 / tas
    qhat = aero.c * q * half_inv_v
    phat = aero.b * p * half_inv_v
    rhat = aero.b * r * half_inv_v
    cl = lift_coeff(aero, alpha, qhat, de)
    dcl = cl - a.cl_mindrag
    cd = a.cd0 + a.cd_alpha * alpha + a.cd_de * abs(de) + aero.k_ind * dcl * dcl
    ca = math.cos(alpha)
    sa = math.sin(alpha)
    fx = qbar_s * (-cd * ca + cl * sa)
    fz = qbar_s * (-cd * sa - cl * ca)
    fy = qbar_s * (
        a.cy_beta * beta + a.cy_p * phat + a.cy_r * rhat + a.cy_da * da + a.cy_dr * dr
    )
    ml = (
        qbar_s
        * aero.b
        * (
            a.croll_beta * beta
            + a.croll_p * phat
            + a.croll_r * rhat
            + a.croll_da * da
            + a.croll_dr * dr
        )
    )
    mm = qbar_s * aero.c * (a.cm0 + a.cm_alpha * alpha + aero.cm_q_eff * qhat + a.cm_de * de)
    mn = (
        qbar_s
        * aero.b
        * (a.cn_beta * beta + a.cn_p * phat + a.cn_r * rhat + a.cn_da * da + a.cn_dr * dr)
    )
    return fx, fy, fz, ml, mm, mn


def evaluate(
body: RigidBody,
    s: list[float],
    da: float,
    de: float,
    dr: float,
    thr_cmd: float,
    wn: float,
    we: float,
    wd: float,
) -> tuple[list[float], tuple[float, ...]]:
    """State derivative and outputs.

    Returns
    -------
    deriv : (14,) list
    out : (f_x, f_y, f_z, tas, alpha, beta, rho, thrust) specific force FRD (m/s^2), air data
    """
    lat, _lon, h, vn, ve, vd, q0, q1, q2, q3, p, q, r, thr = s
    c00, c01, c02, c10, c11, c12, c20, c21, c22 = dcm_from_quat_fast(q0, q1, q2, q3)
    # air velocity in body axes
    an, ae, ad = vn - wn, ve - we, vd - wd
    u = c00 * an + c10 * ae + c20 * ad
    v = c01 * an + c11 * ae + c21 * ad
    w = c02 * an + c12 * ae + c22 * ad
    rho = isa_density_fast(h)
    fx, fy, fz, ml, mm, mn = forces_moments(body.aero, u, v, w, p, q, r, da, de, dr, rho)
    tas = math.sqrt(u * u + v * v + w * w)
    thrust = thrust_n(body.aero, thr, tas, rho, k.ISA_RHO0_KGPM3)
    inv_m = 1.0 / body.mass_kg
    ax = (fx + thrust) * inv_m
    ay = fy * inv_m
    az = fz * inv_m
    # specific force to NED
    fn = c00 * ax + c01 * ay + c02 * az
    fe = c10 * ax + c11 * ay + c12 * az
    fd = c20 * ax + c21 * ay + c22 * az
    rh = k.EARTH_RADIUS_M + h
    om = k.EARTH_RATE_RADPS
    sl = math.sin(lat)
    cl = math.cos(lat)
    tl = sl / cl
    g = gravity_fast(lat, h)
    # Lu2016 eq. 11 rows 1-3
    vn_d = fn + vn * vd / rh - ve * ve * tl / rh - 2.0 * om * ve * sl
    ve_d = fe + vn * ve * tl / rh + ve * vd / rh + 2.0 * om * (vn * sl + vd * cl)
    vd_d = fd - vn * vn / rh - ve * ve / rh - 2.0 * om * ve * cl + g
    # omega_in (earth rate + transport rate), NED, then body
    win = ve / rh + om * cl
    wie = -vn / rh
    wid = -ve * tl / rh - om * sl
    pb = p - (c00 * win + c10 * wie + c20 * wid)
    qb = q - (c01 * win + c11 * wie + c21 * wid)
    rb = r - (c02 * win + c12 * wie + c22 * wid)
    q0d = 0.5 * (-q1 * pb - q2 * qb - q3 * rb)
    q1d = 0.5 * (q0 * pb + q2 * rb - q3 * qb)
    q2d = 0.5 * (q0 * qb - q1 * rb + q3 * pb)
    q3d = 0.5 * (q0 * rb + q1 * qb - q2 * pb)
    # Euler's equations (Beard eq. 3.17)
    pd = body.g1 * p * q - body.g2 * q * r + body.g3 * ml + body.g4 * mn
    qd = body.g5 * p * r - body.g6 * (p * p - r * r) + mm / body.jy
    rd = body.g7 * p * q - body.g1 * q * r + body.g4 * ml + body.g8 * mn
    thr_d = (thr_cmd - thr) / body.tau_engine_s
    deriv = [
        vn / rh,
        ve / (rh * cl),
        -vd,
        vn_d,
        ve_d,
        vd_d,
        q0d,
        q1d,
        q2d,
        q3d,
        pd,
        qd,
        rd,
        thr_d,
    ]
    alpha = math.atan2(w, u)
    beta = math.asin(max(-1.0, min(1.0, v / tas))) if tas > 0.0 else 0.0
    return deriv, (ax, ay, az, tas, alpha, beta, rho, thrust)


def rk4_step(
    body: RigidBody,
    s: list[float],
    dt_s: float,
    inp0: tuple[float, ...],
    inp1: tuple[float, ...],
    k1: list[float] | None = None,
) -> list[float]:
    """One classical RK4 step; inputs (da, de, dr, thr_cmd, wn, we, wd) vary linearly inp0->inp1.

    Linear interpolation of the surfaces and the wind keeps the specific force continuous
    across steps, so a trapezoidal re-integration of the published samples is O(dt^2) exact.
    ``k1`` may pass the derivative at (s, inp0) when the caller already has it.
    """
    mid = tuple(0.5 * (a + b) for a, b in zip(inp0, inp1, strict=True))
    if k1 is None:
        k1, _ = evaluate(body, s, *inp0)
    h = 0.5 * dt_s
    s2 = [x + h * d for x, d in zip(s, k1, strict=True)]
    k2, _ = evaluate(body, s2, *mid)
    s3 = [x + h * d for x, d in zip(s, k2, strict=True)]
    k3, _ = evaluate(body, s3, *mid)
    s4 = [x + dt_s * d for x, d in zip(s, k3, strict=True)]
    k4, _ = evaluate(body, s4, *inp1)
    d6 = dt_s / 6.0
    out = [
        x + d6 * (a + 2.0 * (b + c) + e) for x, a, b, c, e in zip(s, k1, k2, k3, k4, strict=True)
    ]
    n = math.sqrt(out[6] ** 2 + out[7] ** 2 + out[8] ** 2 + out[9] ** 2)
    out[6] /= n
    out[7] /= n
    out[8] /= n
    out[9] /= n
    return out
