"""The Wan2018 air-data model in numba (eqs. 1, 11, 15, 16, 20, 23, 42): one implementation.

``airdata``'s output function, its Jacobian, the transition Jacobians and the CAS relation wrap
:func:`outputs`, :func:`transition_jacobian`, :func:`input_matrix` and
:func:`cas_and_derivative`;
:func:`linearise_horizon` calls the same functions node by node for the MHE (eq. 42).

The transition itself (eq. 20 with the eq. 8 wind-acceleration term) is written twice, on
purpose: here, as the defect ``F(x_i, u_i) - x_{i+1}`` of eq. 42, the term is
``t_s ((u_wx sin - u_wz cos) / V_g)``; in ``airdata.airdata_f`` (the one-step prediction of
eq. 29 and the node the shift appends) it is ``(t_s (u_wx sin - u_wz cos)) / V_g``. The two
roundings differ about once in 10^4 evaluations, and each is pinned by the monitor's recorded
replays, so neither can take the other's form without changing the monitor's output.

The plain-float reference of the equivalence test is ``tests/reference/airdata.py``. Physical
constants come in as an argument (``airdata._JIT_CONSTS``), not as globals, so that a change in
``core/constants.py`` cannot leave a stale compiled copy in numba's cache. Loaded through
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
def cas_and_derivative(tas, alt, consts):
    """Calibrated airspeed and dV_c/dV_t (Wan2018 eq. 16), ISA temperature at ``alt``."""
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
    # d/dVt of sqrt(Y^(1/3.5) - 1) = Y^(1/3.5 - 1) * p_bar * a^2.5 * 2 Vt / (k T) / (2 rho)
    dy_root = (y_root / big_y) * p_bar * a25 * 2.0 * tas / (k_cas * t_k)
    return cas, sqrt_k_t0 * dy_root / (2.0 * rho)


@jit
def outputs(x, th, consts, h, C):
    """``y = h(x, Theta)`` (eqs. 1, 11, 15, 16) into ``h`` (4,), ``C = dh/dx`` (eq. 23,
    ``c_22 = 0``: Remark 1) into ``C`` (4, 4).

    ``x`` (4,) state; ``th`` (6,) Theta, or (8,) with bank and sideslip (``airdata.lateral``);
    ``consts`` ``airdata._JIT_CONSTS``. ``V_z`` is positive up and ``W_z`` positive down.
    """
    alpha, vg_x, wx, wz = x[0], x[1], x[2], x[3]
    vg, theta, alt = th[0], th[1], th[5]
    phi, beta = (th[6], th[7]) if th.shape[0] > 7 else (0.0, 0.0)  # airdata.lateral
    sa, ca = math.sin(alpha), math.cos(alpha)
    st, ct, cp = math.sin(theta), math.cos(theta), math.cos(phi)
    sb, cb = math.sin(beta), math.cos(beta)
    d = alpha - theta
    sd, cd = math.sin(d), math.cos(d)
    sg = ca * cb * st - (math.sin(phi) * sb + cp * sa * cb) * ct  # sin(-d) at phi = beta = 0
    dsg = -sa * cb * st - cp * ca * cb * ct  # -cos(d) at phi = beta = 0
    vz_up = vg * sg - wz  # eq. 15
    tas = vg - wx * cd - wz * sd  # eq. 11
    cas, dcas = cas_and_derivative(tas, alt, consts)  # eq. 16
    h[0] = vg_x
    h[1] = vz_up
    h[2] = alpha
    h[3] = cas
    for r in range(4):
        for c in range(4):
            C[r, c] = 0.0
    C[0, 1] = 1.0
    C[1, 0] = vg * dsg
    C[1, 3] = -1.0
    C[2, 0] = 1.0
    # dV_t/dalpha, dV_t/dW_x, dV_t/dW_z of eq. 11
    C[3, 0] = dcas * (wx * sd - wz * cd)
    C[3, 2] = -dcas * cd
    C[3, 3] = -dcas * sd


@jit
def transition_jacobian(x, u, th, dt, g, k_wacc, A):
    """``A = dF/dx`` of the transition (eq. 23, ``a_12 = 0``: Remark 1) into ``A`` (4, 4).

    ``k_wacc`` 1.0 adds the eq. 8 wind-acceleration term's entry
    (``AirDataModelParams.wind_accel_in_alpha``), 0.0 gives eq. 13 exactly (``u`` unused).
    """
    alpha = x[0]
    vg, theta, ax, az = th[0], th[1], th[3], th[4]
    phi = th[6] if th.shape[0] > 7 else 0.0  # airdata.lateral
    sa, ca = math.sin(alpha), math.cos(alpha)
    st, ct, cp = math.sin(theta), math.cos(theta), math.cos(phi)
    d = alpha - theta
    sd, cd = math.sin(d), math.cos(d)
    # derivatives of the gravity terms (airdata._gravity_terms): -g sin(d), g cos(d) at phi = 0
    d_falpha = -ax * ca - az * sa + g * (-sa * ct * cp + ca * st)
    d_fv = -ax * sa + az * ca + g * (ca * ct * cp + sa * st)
    for r in range(4):
        for c in range(4):
            A[r, c] = 0.0
        A[r, r] = 1.0
    A[0, 0] += dt * d_falpha / vg
    A[1, 0] = dt * d_fv
    if k_wacc != 0.0:
        A[0, 0] += dt * (u[2] * cd + u[3] * sd) / vg


@jit
def input_matrix(x, th, dt, k_wacc, B):
    """``B = dF/du`` of the transition (eq. 20: ``t_s I``) into ``B`` (4, 4), with the eq. 8
    term's ``u_w`` entries in the alpha row when ``k_wacc`` is 1.0."""
    for r in range(4):
        for c in range(4):
            B[r, c] = 0.0
        B[r, r] = dt
    if k_wacc != 0.0:
        d = x[0] - th[1]
        vg = th[0]
        B[0, 2] = dt * math.sin(d) / vg
        B[0, 3] = -dt * math.cos(d) / vg


@jit
def linearise_horizon(n, x_lin, u_lin, th, dts, ym, mk, g, k_wacc, consts, a, b, f, cm, ry):
    """Wan2018 eq. 42 over nodes 0..n-1 (``filters.mhe`` linearisation loop, this model).

    Writes A_i, B_i (:func:`transition_jacobian`, :func:`input_matrix`), defects
    f_i = F(x_i, u_i) - x_{i+1} (i < n-1), and the masked C_i and r_y,i = (y_i - h(x_i)) * mask_i
    (i < n, :func:`outputs`). Rows from n on are left untouched.

    Parameters
    ----------
    x_lin : (N, 4) linearisation states; u_lin : (N-1, 4) inputs; th : (N, 6) Theta_i
    (or (N, 8) with phi, beta: ``airdata.lateral``)
    dts : (N,) t_s from node i to i+1; ym, mk : (N, 4) outputs and output mask
    g : gravity (m/s^2); k_wacc : 1.0 to keep the eq. 8 wind-acceleration term in alpha
    (``AirDataModelParams.wind_accel_in_alpha``), 0.0 for eq. 13; consts : ``airdata._JIT_CONSTS``
    """
    h = np.empty(4)
    C = np.empty((4, 4))
    for i in range(n):
        outputs(x_lin[i], th[i], consts, h, C)
        for r in range(4):
            m = mk[i, r]
            ry[i, r] = (ym[i, r] - h[r]) * m
            for c in range(4):
                cm[i, r, c] = C[r, c] * m
        if i < n - 1:
            dt = dts[i]
            transition_jacobian(x_lin[i], u_lin[i], th[i], dt, g, k_wacc, a[i])
            input_matrix(x_lin[i], th[i], dt, k_wacc, b[i])
            alpha, vg_x, wx, wz = x_lin[i, 0], x_lin[i, 1], x_lin[i, 2], x_lin[i, 3]
            vg, theta, q, ax, az = th[i, 0], th[i, 1], th[i, 2], th[i, 3], th[i, 4]
            phi = th[i, 6] if th.shape[1] > 7 else 0.0  # airdata.lateral
            sa, ca = math.sin(alpha), math.cos(alpha)
            st, ct, cp = math.sin(theta), math.cos(theta), math.cos(phi)
            d = alpha - theta
            sd, cd = math.sin(d), math.cos(d)
            # gravity terms (airdata._gravity_terms): g cos(d), g sin(d) at phi = 0
            f_alpha = -ax * sa + az * ca + g * (ca * ct * cp + sa * st)
            f_v = ax * ca + az * sa + g * (sa * ct * cp - ca * st)
            # eq. 20 and the defect of eq. 42 (the eq. 8 term: module docstring)
            uwx, uwz = u_lin[i, 2], u_lin[i, 3]
            wacc = k_wacc * (uwx * sd - uwz * cd) / vg  # eq. 8 term (or 0: eq. 13)
            f[i, 0] = alpha + dt * (f_alpha / vg + q + u_lin[i, 0]) + dt * wacc - x_lin[i + 1, 0]
            f[i, 1] = vg_x + dt * (f_v + u_lin[i, 1]) - x_lin[i + 1, 1]
            f[i, 2] = wx + dt * (0.0 + u_lin[i, 2]) - x_lin[i + 1, 2]
            f[i, 3] = wz + dt * (0.0 + u_lin[i, 3]) - x_lin[i + 1, 3]
