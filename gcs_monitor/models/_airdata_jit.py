"""Numba version of the Wan2018 air-data model linearised over an MHE horizon (eqs. 20, 23, 42).

The same equations as ``airdata.py`` (the reference, checked against finite differences) written
for numba; imported lazily by ``airdata.compiled_kernels`` and cached on disk. Physical constants
come in as an argument (``airdata._JIT_CONSTS``), not as globals, so that a change in
``core/constants.py`` cannot leave a stale compiled copy in numba's cache; no function here calls
a function of another module. tests/gcs_monitor/models/test_airdata.py checks both versions agree.
"""
# ruff: noqa: N803, N806
# mypy: disable-error-code="no-untyped-def"

from __future__ import annotations

import math

import numba

jit = numba.njit(cache=True, fastmath=False, nogil=True)


@jit
def _cas_and_derivative(tas, alt, consts):
    """``airdata.cas_from_tas_with_derivative`` (Wan2018 eq. 16)."""
    k_cas, sqrt_k_t0, t0_k, lapse_kpm, gas_exp, exp_isentropic = consts
    t_k = t0_k + lapse_kpm * alt
    p_bar = (1.0 + lapse_kpm * alt / t0_k) ** gas_exp
    a = 1.0 + tas * tas / (k_cas * t_k)
    a25 = a**2.5
    big_y = (a25 * a - 1.0) * p_bar + 1.0
    y_root = big_y ** (1.0 / exp_isentropic)
    rho = math.sqrt(max(y_root - 1.0, 0.0))
    cas = sqrt_k_t0 * rho
    if rho <= 0.0:
        return cas, 0.0
    dy_root = (y_root / big_y) * p_bar * a25 * 2.0 * tas / (k_cas * t_k)
    return cas, sqrt_k_t0 * dy_root / (2.0 * rho)


@jit
def linearise_horizon(n, x_lin, u_lin, th, dts, ym, mk, g, k_wacc, consts, a, b, f, cm, ry):
    """Wan2018 eq. 42 over nodes 0..n-1 (``filters.mhe`` linearisation loop, this model).

    Writes A_i = dF/dx, B_i = t_s I, defects f_i = F(x_i, u_i) - x_{i+1} (i < n-1), and the
    masked C_i and r_y,i = (y_i - h(x_i)) * mask_i (i < n). Rows from n on are left untouched.

    Parameters
    ----------
    x_lin : (N, 4) linearisation states; u_lin : (N-1, 4) inputs; th : (N, 6) Theta_i
    (or (N, 8) with phi, beta: ``airdata.lateral``)
    dts : (N,) t_s from node i to i+1; ym, mk : (N, 4) outputs and output mask
    g : gravity (m/s^2); k_wacc : 1.0 to keep the eq. 8 wind-acceleration term in alpha
    (``AirDataModelParams.wind_accel_in_alpha``), 0.0 for eq. 13; consts : ``airdata._JIT_CONSTS``
    """
    for i in range(n):
        alpha, vg_x, wx, wz = x_lin[i, 0], x_lin[i, 1], x_lin[i, 2], x_lin[i, 3]
        vg, theta, q, ax, az, alt = th[i, 0], th[i, 1], th[i, 2], th[i, 3], th[i, 4], th[i, 5]
        phi, beta = (th[i, 6], th[i, 7]) if th.shape[1] > 7 else (0.0, 0.0)  # airdata.lateral
        sa, ca = math.sin(alpha), math.cos(alpha)
        st, ct, cp = math.sin(theta), math.cos(theta), math.cos(phi)
        sb, cb = math.sin(beta), math.cos(beta)
        # outputs (eqs. 1, 11, 15, 16) and their Jacobian (eq. 23, c_22 = 0)
        d = alpha - theta
        sd, cd = math.sin(d), math.cos(d)
        sg = ca * cb * st - (math.sin(phi) * sb + cp * sa * cb) * ct  # sin(-d) at phi = beta = 0
        dsg = -sa * cb * st - cp * ca * cb * ct  # -cos(d) at phi = beta = 0
        vz_up = vg * sg - wz
        tas = vg - wx * cd - wz * sd
        cas, dcas = _cas_and_derivative(tas, alt, consts)
        h0, h1, h2, h3 = vg_x, vz_up, alpha, cas
        m0, m1, m2, m3 = mk[i, 0], mk[i, 1], mk[i, 2], mk[i, 3]
        ry[i, 0] = (ym[i, 0] - h0) * m0
        ry[i, 1] = (ym[i, 1] - h1) * m1
        ry[i, 2] = (ym[i, 2] - h2) * m2
        ry[i, 3] = (ym[i, 3] - h3) * m3
        for r in range(4):
            for c in range(4):
                cm[i, r, c] = 0.0
        cm[i, 0, 1] = 1.0 * m0
        cm[i, 1, 0] = vg * dsg * m1
        cm[i, 1, 3] = -1.0 * m1
        cm[i, 2, 0] = 1.0 * m2
        cm[i, 3, 0] = dcas * (wx * sd - wz * cd) * m3
        cm[i, 3, 2] = -dcas * cd * m3
        cm[i, 3, 3] = -dcas * sd * m3
        if i < n - 1:
            dt = dts[i]
            # gravity terms (airdata._gravity_terms): g cos(d), g sin(d) at phi = 0
            f_alpha = -ax * sa + az * ca + g * (ca * ct * cp + sa * st)
            f_v = ax * ca + az * sa + g * (sa * ct * cp - ca * st)
            # eq. 20 and the defect of eq. 42
            uwx, uwz = u_lin[i, 2], u_lin[i, 3]
            wacc = k_wacc * (uwx * sd - uwz * cd) / vg  # eq. 8 term (or 0: eq. 13)
            f[i, 0] = alpha + dt * (f_alpha / vg + q + u_lin[i, 0]) + dt * wacc - x_lin[i + 1, 0]
            f[i, 1] = vg_x + dt * (f_v + u_lin[i, 1]) - x_lin[i + 1, 1]
            f[i, 2] = wx + dt * (0.0 + u_lin[i, 2]) - x_lin[i + 1, 2]
            f[i, 3] = wz + dt * (0.0 + u_lin[i, 3]) - x_lin[i + 1, 3]
            d_falpha = -ax * ca - az * sa + g * (-sa * ct * cp + ca * st)
            d_fv = -ax * sa + az * ca + g * (ca * ct * cp + sa * st)
            for r in range(4):
                for c in range(4):
                    a[i, r, c] = 0.0
                    b[i, r, c] = 0.0
                a[i, r, r] = 1.0
                b[i, r, r] = dt
            a[i, 0, 0] += dt * d_falpha / vg
            a[i, 1, 0] = dt * d_fv
            if k_wacc != 0.0:
                a[i, 0, 0] += dt * (uwx * cd + uwz * sd) / vg
                b[i, 0, 2] = dt * sd / vg
                b[i, 0, 3] = -dt * cd / vg
