"""The GS-KM (Lu2016 eqs. 11-13) in numba: the one implementation of the model.

``kinematics.gs_km_f``, the Jacobian functions and ``kinematics.GsKm`` wrap these kernels; the
ATSEKF hot path (``estimators/imu_ts.py``) calls them directly. The plain-float reference of
the equivalence test (bit for bit: same expressions, same order) is
``tests/reference/kinematics.py``; tests/gcs_monitor/models/test_kinematics.py also checks the
Jacobians against central differences and the kinematics against the DCM. Every function
writes into arrays the caller passes in. Loaded through ``gcs_monitor.core.kernels``.
"""
# ruff: noqa: N803, N806
# mypy: disable-error-code="no-untyped-def"

from __future__ import annotations

import math

import numba

from gcs_monitor.core import constants as c

# the earth constants below are compiled in as constants: see gcs_monitor.core.kernels
KERNEL_DEPENDENCIES = {"gcs_monitor.core.constants": "0b300fc9f27503d8"}

jit = numba.njit(cache=True, fastmath=False, nogil=True)

EARTH_RADIUS_M = c.EARTH_RADIUS_M
EARTH_RATE_RADPS = c.EARTH_RATE_RADPS


@jit
def rates(x, u, lat_rad, alt_m, g_mps2, out):
    """Lu2016 eq. 11 (psi row with the corrected sign, ``kinematics`` module docstring) into
    ``out`` (6,), gravity ``g_mps2`` of eq. 12 given."""
    un, ue, ud, phi, th, psi = x[0], x[1], x[2], x[3], x[4], x[5]
    ax, ay, az, p, q, r = u[0], u[1], u[2], u[3], u[4], u[5]
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(th), math.cos(th)
    sps, cps = math.sin(psi), math.cos(psi)
    sd, cd = math.sin(lat_rad), math.cos(lat_rad)
    td = sd / cd
    tth = sth / cth
    rr = EARTH_RADIUS_M + alt_m
    om = EARTH_RATE_RADPS
    an = cth * cps * ax + (sph * sth * cps - cph * sps) * ay + (cph * sth * cps + sph * sps) * az
    ae = cth * sps * ax + (sph * sth * sps + cph * cps) * ay + (cph * sth * sps - sph * cps) * az
    ad = -sth * ax + sph * cth * ay + cph * cth * az
    out[0] = an + (un * ud - ue * ue * td) / rr - 2.0 * om * ue * sd
    out[1] = ae + (un * ue * td + ue * ud) / rr + 2.0 * om * (un * sd + ud * cd)
    out[2] = ad - (un * un + ue * ue) / rr - 2.0 * om * ue * cd + g_mps2
    a_ = ue / rr + om * cd
    b_ = un / rr
    hor = -a_ * cps + b_ * sps
    qsr = q * sph + r * cph
    out[3] = p + qsr * tth + hor / cth
    out[4] = q * cph - r * sph + a_ * sps + b_ * cps
    out[5] = qsr / cth + hor * tth + ue * td / rr + om * sd


@jit
def propagate(x, u0, u1, lat_rad, alt_m, g_mps2, dt_s, out):
    """``x + int f(x, u) dt`` over ``dt_s`` (Lu2016 eq. 31) by Heun's method, the input linear
    from ``u0`` to ``u1``, into ``out`` (6,)."""
    k1 = x.copy()
    rates(x, u0, lat_rad, alt_m, g_mps2, k1)
    xe = x.copy()
    for i in range(6):
        xe[i] = x[i] + dt_s * k1[i]
    k2 = x.copy()
    rates(xe, u1, lat_rad, alt_m, g_mps2, k2)
    half = dt_s / 2.0
    for i in range(6):
        out[i] = x[i] + half * (k1[i] + k2[i])


@jit
def input_matrix(x, G):
    """``G = df/df^i = -df/du`` (Lu2016 eq. 13) into ``G`` (6, 6): the specific-force rows are
    ``-C_ned_frd``, the rate rows ``-E(phi, theta)`` (body rates to Euler rates)."""
    phi, th, psi = x[3], x[4], x[5]
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(th), math.cos(th)
    sps, cps = math.sin(psi), math.cos(psi)
    for i in range(6):
        for j in range(6):
            G[i, j] = -0.0
    G[0, 0] = -(cth * cps)
    G[0, 1] = -(sph * sth * cps - cph * sps)
    G[0, 2] = -(cph * sth * cps + sph * sps)
    G[1, 0] = -(cth * sps)
    G[1, 1] = -(sph * sth * sps + cph * cps)
    G[1, 2] = -(cph * sth * sps - sph * cps)
    G[2, 0] = sth
    G[2, 1] = -(sph * cth)
    G[2, 2] = -(cph * cth)
    G[3, 3] = -1.0
    G[3, 4] = -(sph * sth / cth)
    G[3, 5] = -(cph * sth / cth)
    G[4, 4] = -cph
    G[4, 5] = sph
    G[5, 4] = -(sph / cth)
    G[5, 5] = -(cph / cth)


@jit
def jacobians(x, u, lat_rad, alt_m, F, G):
    """F = df/dx and G = df/df^i = -df/du (eqs. 13, 34) into ``F``, ``G`` (6, 6)."""
    un, ue, ud, phi, th, psi = x[0], x[1], x[2], x[3], x[4], x[5]
    ax, ay, az, q, r = u[0], u[1], u[2], u[4], u[5]  # p does not enter F or G
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(th), math.cos(th)
    sps, cps = math.sin(psi), math.cos(psi)
    sd, cd = math.sin(lat_rad), math.cos(lat_rad)
    td = sd / cd
    tth = sth / cth
    rr = EARTH_RADIUS_M + alt_m
    om = EARTH_RATE_RADPS
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
    F[0, 0] = ud / rr
    F[0, 1] = -2.0 * ue * td / rr - 2.0 * om * sd
    F[0, 2] = un / rr
    F[0, 3] = dn_dphi
    F[0, 4] = dn_dth
    F[0, 5] = dn_dpsi
    F[1, 0] = ue * td / rr + 2.0 * om * sd
    F[1, 1] = (un * td + ud) / rr
    F[1, 2] = ue / rr + 2.0 * om * cd
    F[1, 3] = de_dphi
    F[1, 4] = de_dth
    F[1, 5] = de_dpsi
    F[2, 0] = -2.0 * un / rr
    F[2, 1] = -2.0 * ue / rr - 2.0 * om * cd
    F[2, 2] = 0.0
    F[2, 3] = dd_dphi
    F[2, 4] = dd_dth
    F[2, 5] = 0.0
    F[3, 0] = sps / (rr * cth)
    F[3, 1] = -cps / (rr * cth)
    F[3, 2] = 0.0
    F[3, 3] = qcr * tth
    F[3, 4] = (qsr + hor * sth) / c2
    F[3, 5] = dhor_dpsi / cth
    F[4, 0] = cps / rr
    F[4, 1] = sps / rr
    F[4, 2] = 0.0
    F[4, 3] = -qsr
    F[4, 4] = 0.0
    F[4, 5] = -hor
    F[5, 0] = sps * tth / rr
    F[5, 1] = -cps * tth / rr + td / rr
    F[5, 2] = 0.0
    F[5, 3] = qcr / cth
    F[5, 4] = (qsr * sth + hor) / c2
    F[5, 5] = dhor_dpsi * tth
    input_matrix(x, G)
