"""The body-frame GS model in numba (Atmaca2025 eqs. 9-19, 25-27, 51): its one implementation.

``kinematics_body``'s model functions wrap these kernels; the estimator's hot path
(``estimators/imu_hosm.py``) calls them directly, :func:`prediction` included. The plain-float
reference of the equivalence test is ``tests/reference/kinematics_body.py``;
tests/gcs_monitor/models/test_kinematics_body.py also checks the Jacobians against central
differences. Every function writes into arrays the caller passes in. Loaded through
``gcs_monitor.core.kernels``.
"""
# ruff: noqa: N803, N806
# mypy: disable-error-code="no-untyped-def"

from __future__ import annotations

import math

import numba
import numpy as np

jit = numba.njit(cache=True, fastmath=False, nogil=True)


@jit
def derivative(x, u_m, f_hat, g, out):
    """Eqs. 9-14 into ``out`` (6,): the approximate model, ``f_hat`` subtracted only in the
    cross terms (``kinematics_body`` module docstring)."""
    u, v, w, phi, theta = x[0], x[1], x[2], x[3], x[4]
    pm, qm, rm = u_m[3], u_m[4], u_m[5]
    pe = pm - f_hat[3]
    qe = qm - f_hat[4]
    re = rm - f_hat[5]
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(theta), math.cos(theta)
    tth = sth / cth
    out[0] = v * re - w * qe + u_m[0] - g * sth
    out[1] = -u * re + w * pe + u_m[1] + g * cth * sph
    out[2] = u * qe - v * pe + u_m[2] + g * cth * cph
    out[3] = pm + qe * sph * tth + re * cph * tth
    out[4] = qm * cph - re * sph
    out[5] = qe * sph / cth + rm * cph / cth


@jit
def jac_x(x, u_m, f_hat, g, F):
    """F = df/dx of eqs. 9-14 (eq. 26) into ``F`` (6, 6)."""
    phi, theta = x[3], x[4]
    pm, qm, rm = u_m[3], u_m[4], u_m[5]
    pe = pm - f_hat[3]
    qe = qm - f_hat[4]
    re = rm - f_hat[5]
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(theta), math.cos(theta)
    tth = sth / cth
    c2 = cth * cth
    for i in range(6):
        for j in range(6):
            F[i, j] = 0.0
    F[0, 1] = re
    F[0, 2] = -qe
    F[0, 4] = -g * cth
    F[1, 0] = -re
    F[1, 2] = pe
    F[1, 3] = g * cth * cph
    F[1, 4] = -g * sth * sph
    F[2, 0] = qe
    F[2, 1] = -pe
    F[2, 3] = -g * cth * sph
    F[2, 4] = -g * sth * cph
    F[3, 3] = (qe * cph - re * sph) * tth
    F[3, 4] = (qe * sph + re * cph) / c2
    F[4, 3] = -qm * sph - re * cph
    F[5, 3] = (qe * cph - rm * sph) / cth
    F[5, 4] = (qe * sph + rm * cph) * sth / c2


@jit
def noise_matrix(x, G):
    """G = -df/du_m (eq. 15, with ``G[0, 4] = +w``: ``kinematics_body.body_gs_noise_matrix``)
    into ``G`` (6, 6)."""
    u, v, w, phi, theta = x[0], x[1], x[2], x[3], x[4]
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(theta), math.cos(theta)
    tth = sth / cth
    for i in range(6):
        for j in range(6):
            G[i, j] = 0.0
    G[0, 0] = G[1, 1] = G[2, 2] = G[3, 3] = -1.0
    G[0, 4] = w
    G[0, 5] = -v
    G[1, 3] = -w
    G[1, 5] = u
    G[2, 3] = v
    G[2, 4] = -u
    G[3, 4] = -sph * tth
    G[3, 5] = -cph * tth
    G[4, 4] = -cph
    G[4, 5] = sph
    G[5, 4] = -sph / cth
    G[5, 5] = -cph / cth


@jit
def measurement(x, h, H):
    """h(x) into ``h`` (6,) and H = dh/dx into ``H`` (6, 6) (eqs. 16-19, 26)."""
    phi, theta, psi = x[3], x[4], x[5]
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(theta), math.cos(theta)
    sps, cps = math.sin(psi), math.cos(psi)
    for i in range(6):
        for j in range(6):
            H[i, j] = 0.0
    # C_ned_frd (ZYX)
    H[0, 0] = cth * cps
    H[0, 1] = sph * sth * cps - cph * sps
    H[0, 2] = cph * sth * cps + sph * sps
    H[1, 0] = cth * sps
    H[1, 1] = sph * sth * sps + cph * cps
    H[1, 2] = cph * sth * sps - sph * cps
    H[2, 0] = -sth
    H[2, 1] = sph * cth
    H[2, 2] = cph * cth
    u, v, w = x[0], x[1], x[2]
    for i in range(3):
        h[i] = H[i, 0] * u + H[i, 1] * v + H[i, 2] * w
        h[3 + i] = x[3 + i]
    # partials of C v with respect to phi, theta, psi
    H[0, 3] = (cph * sth * cps + sph * sps) * v + (-sph * sth * cps + cph * sps) * w
    H[1, 3] = (cph * sth * sps - sph * cps) * v + (-sph * sth * sps - cph * cps) * w
    H[2, 3] = cph * cth * v - sph * cth * w
    H[0, 4] = -sth * cps * u + sph * cth * cps * v + cph * cth * cps * w
    H[1, 4] = -sth * sps * u + sph * cth * sps * v + cph * cth * sps * w
    H[2, 4] = -cth * u - sph * sth * v - cph * sth * w
    H[0, 5] = (
        -cth * sps * u + (-sph * sth * sps - cph * cps) * v + (-cph * sth * sps + sph * cps) * w
    )
    H[1, 5] = cth * cps * u + (sph * sth * cps - cph * sps) * v + (cph * sth * cps + sph * sps) * w
    H[2, 5] = 0.0
    H[3, 3] = H[4, 4] = H[5, 5] = 1.0


@jit
def _rk2(x, u_m, f_hat, g, dt, out, k, xm):
    """Midpoint step of eqs. 9-14 into ``out`` (``imu_hosm._rk2``)."""
    derivative(x, u_m, f_hat, g, k)
    for i in range(6):
        xm[i] = x[i] + 0.5 * dt * k[i]
    derivative(xm, u_m, f_hat, g, k)
    for i in range(6):
        out[i] = x[i] + dt * k[i]


@jit
def prediction(
    x_hat,
    x_bar,
    V,
    mu,
    u_m,
    f_hat,
    g,
    dt,
    q_imu_diag,
    drift_var_rate,
    corrected,
    Phi,
    B,
    Qx,
    Qxmu,
    Qmu,
    x_bar_prop,
):
    """Model quantities of one OTSEKF step (Atmaca2025 eqs. 20, 25-27); see
    ``imu_hosm.ImuHosmEstimator._prediction`` for the reference and the choices made.

    Writes ``Phi, B, Qx, Qxmu, Qmu`` (6, 6) and ``x_bar_prop`` (6,).
    """
    F = np.empty((6, 6))
    G = np.empty((6, 6))
    jac_x(x_hat, u_m, f_hat, g, F)  # eq. 26 at x_hat_{k-1|k-1}
    noise_matrix(x_hat, G)
    for i in range(6):
        for j in range(6):
            F[i, j] *= dt
    # eq. 25 truncated after the second-order term; M = I + F dt / 2 for eq. 27
    M = np.empty((6, 6))
    for i in range(6):
        for j in range(6):
            acc = 0.0
            for t in range(6):
                acc += F[i, t] * F[t, j]
            Phi[i, j] = F[i, j] + 0.5 * acc
            M[i, j] = 0.5 * F[i, j]
        Phi[i, i] += 1.0
        M[i, i] += 1.0
    Gam = np.empty((6, 6))
    for i in range(6):
        for j in range(6):
            acc = 0.0
            for t in range(6):
                acc += M[i, t] * G[t, j]
            Gam[i, j] = acc * dt
    for i in range(6):
        for j in range(6):
            acc = 0.0
            for t in range(6):
                acc += Gam[i, t] * q_imu_diag[t] * Gam[j, t]
            Qx[i, j] = acc
            Qmu[i, j] = 0.0
            Qxmu[i, j] = 0.0
        q = drift_var_rate[i] * dt
        Qmu[i, i] = q
        Qxmu[i, i] = -q
        Qx[i, i] += q
    k = np.empty(6)
    xm = np.empty(6)
    if corrected:
        # f_d(x_hat) - Phi V mu
        _rk2(x_hat, u_m, f_hat, g, dt, x_bar_prop, k, xm)
        for i in range(6):
            acc = 0.0
            for t in range(V.shape[1]):
                acc += V[i, t] * mu[t]
            k[i] = acc
        for i in range(6):
            acc = 0.0
            for t in range(6):
                acc += Phi[i, t] * k[t]
            x_bar_prop[i] -= acc
        for i in range(6):
            for j in range(6):
                B[i, j] = 0.0
    else:
        _rk2(x_bar, u_m, f_hat, g, dt, x_bar_prop, k, xm)
        for i in range(6):
            for j in range(6):
                B[i, j] = Phi[i, j]
            B[i, i] -= 1.0


@jit
def fault_from_drift_rate(r, x, out):
    """``A(x)^{-1} r`` in closed form (``kinematics_body.fault_from_drift_rate``) into ``out``."""
    u, v, w, phi, theta = x[0], x[1], x[2], x[3], x[4]
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(theta), math.cos(theta)
    fp = r[3] - sth * r[5]
    fq = cph * r[4] + sph * cth * r[5]
    fr = -sph * r[4] + cph * cth * r[5]
    out[0] = r[0] - (v * fr - w * fq)
    out[1] = r[1] - (w * fp - u * fr)
    out[2] = r[2] - (u * fq - v * fp)
    out[3] = fp
    out[4] = fq
    out[5] = fr


@jit
def fault_integral_step(x, mu, mu_prev, f_int):
    """``f_int += A(x)^{-1} (mu - mu_prev)`` in place (``imu_hosm._fault_update``)."""
    d = np.empty(6)
    for i in range(6):
        d[i] = mu[i] - mu_prev[i]
    df = np.empty(6)
    fault_from_drift_rate(d, x, df)
    for i in range(6):
        f_int[i] += df[i]
