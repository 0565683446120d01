"""Plain-float reference of the GS-KM kernel (Lu2016 eqs. 11-13; ``models/_kinematics_jit.py``).

The same expressions in the same order as the kernel, in Python floats: the equivalence test
expects identical numbers. :func:`propagate` and :func:`jacobians` are what ``GsKm``'s methods
computed before they wrapped the kernel.
"""

from __future__ import annotations

import math

import numpy as np

from gcs_monitor.core import constants as c
from gcs_monitor.core.atmosphere import gravity_mps2


def gs_km_rates(
    x: list[float], u: list[float], lat_rad: float, alt_m: float, g_mps2: float
) -> list[float]:
    """Plain-float body of Lu2016 eq. 11 (psi row with the corrected sign, see module doc)."""
    un, ue, ud, phi, th, psi = x
    ax, ay, az, p, q, r = u
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(th), math.cos(th)
    sps, cps = math.sin(psi), math.cos(psi)
    sd, cd = math.sin(lat_rad), math.cos(lat_rad)
    td = sd / cd
    tth = sth / cth
    rr = c.EARTH_RADIUS_M + alt_m
    om = c.EARTH_RATE_RADPS
    # specific force rotated to NED (C_ned_frd @ a)
    an = cth * cps * ax + (sph * sth * cps - cph * sps) * ay + (cph * sth * cps + sph * sps) * az
    ae = cth * sps * ax + (sph * sth * sps + cph * cps) * ay + (cph * sth * sps - sph * cps) * az
    ad = -sth * ax + sph * cth * ay + cph * cth * az
    dun = an + (un * ud - ue * ue * td) / rr - 2.0 * om * ue * sd
    due = ae + (un * ue * td + ue * ud) / rr + 2.0 * om * (un * sd + ud * cd)
    dud = ad - (un * un + ue * ue) / rr - 2.0 * om * ue * cd + g_mps2
    a_ = ue / rr + om * cd  # north component of the navigation-frame rate
    b_ = un / rr  # minus its east component
    hor = -a_ * cps + b_ * sps  # cos(theta) * phi_dot contribution of the frame rate
    qsr = q * sph + r * cph
    dphi = p + qsr * tth + hor / cth
    dth = q * cph - r * sph + a_ * sps + b_ * cps
    dpsi = qsr / cth + hor * tth + ue * td / rr + om * sd
    return [dun, due, dud, dphi, dth, dpsi]


def gs_km_jac_x_rows(
    x: list[float], u: list[float], lat_rad: float, alt_m: float
) -> list[list[float]]:
    un, ue, ud, phi, th, psi = x
    ax, ay, az, p, q, r = u
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(th), math.cos(th)
    sps, cps = math.sin(psi), math.cos(psi)
    sd, cd = math.sin(lat_rad), math.cos(lat_rad)
    td = sd / cd
    tth = sth / cth
    rr = c.EARTH_RADIUS_M + alt_m
    om = c.EARTH_RATE_RADPS
    # d(C a)/d(phi, theta, psi)
    dn_dphi = (cph * sth * cps + sph * sps) * ay + (-sph * sth * cps + cph * sps) * az
    de_dphi = (cph * sth * sps - sph * cps) * ay + (-sph * sth * sps - cph * cps) * az
    dd_dphi = cph * cth * ay - sph * cth * az
    dn_dth = -sth * cps * ax + sph * cth * cps * ay + cph * cth * cps * az
    de_dth = -sth * sps * ax + sph * cth * sps * ay + cph * cth * sps * az
    dd_dth = -cth * ax - sph * sth * ay - cph * sth * az
    dn_dpsi = (
        -cth * sps * ax + (-sph * sth * sps - cph * cps) * ay + (-cph * sth * sps + sph * cps) * az
    )
    de_dpsi = (
        cth * cps * ax + (sph * sth * cps - cph * sps) * ay + (cph * sth * cps + sph * sps) * az
    )
    a_ = ue / rr + om * cd
    b_ = un / rr
    hor = -a_ * cps + b_ * sps
    dhor_dpsi = a_ * sps + b_ * cps
    qsr = q * sph + r * cph
    qcr = q * cph - r * sph
    c2 = cth * cth
    return [
        [ud / rr, -2.0 * ue * td / rr - 2.0 * om * sd, un / rr, dn_dphi, dn_dth, dn_dpsi],
        [
            ue * td / rr + 2.0 * om * sd,
            (un * td + ud) / rr,
            ue / rr + 2.0 * om * cd,
            de_dphi,
            de_dth,
            de_dpsi,
        ],
        [-2.0 * un / rr, -2.0 * ue / rr - 2.0 * om * cd, 0.0, dd_dphi, dd_dth, 0.0],
        [
            sps / (rr * cth),
            -cps / (rr * cth),
            0.0,
            qcr * tth,
            (qsr + hor * sth) / c2,
            dhor_dpsi / cth,
        ],
        [cps / rr, sps / rr, 0.0, -qsr, 0.0, -hor],
        [
            sps * tth / rr,
            -cps * tth / rr + td / rr,
            0.0,
            qcr / cth,
            (qsr * sth + hor) / c2,
            dhor_dpsi * tth,
        ],
    ]


def gs_km_jac_u_rows(x: list[float]) -> list[list[float]]:
    phi, th, psi = x[3], x[4], x[5]
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(th), math.cos(th)
    sps, cps = math.sin(psi), math.cos(psi)
    e = _euler_kin_rows(phi, th)
    return [
        [cth * cps, sph * sth * cps - cph * sps, cph * sth * cps + sph * sps, 0.0, 0.0, 0.0],
        [cth * sps, sph * sth * sps + cph * cps, cph * sth * sps - sph * cps, 0.0, 0.0, 0.0],
        [-sth, sph * cth, cph * cth, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, *e[0]],
        [0.0, 0.0, 0.0, *e[1]],
        [0.0, 0.0, 0.0, *e[2]],
    ]


def _euler_kin_rows(phi: float, th: float) -> list[list[float]]:
    """Body rates -> Euler rates, E(phi, theta) (Lu2016 eq. 18 rows 4-6)."""
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(th), math.cos(th)
    return [[1.0, sph * sth / cth, cph * sth / cth], [0.0, cph, -sph], [0.0, sph / cth, cph / cth]]


def propagate(x: np.ndarray, u0: np.ndarray, u1: np.ndarray, lat_rad: float, alt_m: float,
              dt_s: float) -> np.ndarray:
    """``x + int_{t0}^{t1} f(x, u) dt`` by Heun's method, input linear between samples."""
    g = gravity_mps2(lat_rad, alt_m)
    xl = x.tolist()
    k1 = gs_km_rates(xl, u0.tolist(), lat_rad, alt_m, g)
    xe = [xi + dt_s * ki for xi, ki in zip(xl, k1, strict=True)]
    k2 = gs_km_rates(xe, u1.tolist(), lat_rad, alt_m, g)
    half = dt_s / 2.0
    return np.array([xi + half * (a + b) for xi, a, b in zip(xl, k1, k2, strict=True)])


def jacobians(x: np.ndarray, u: np.ndarray, lat_rad: float, alt_m: float
              ) -> tuple[np.ndarray, np.ndarray]:
    """``(F, G) = (df/dx, df/df^i = -df/du)`` at ``(x, u)`` (Lu2016 eqs. 13, 34)."""
    xl = x.tolist()
    F = np.array(gs_km_jac_x_rows(xl, u.tolist(), lat_rad, alt_m))
    G = np.array(gs_km_jac_u_rows(xl))
    np.negative(G, out=G)
    return F, G
