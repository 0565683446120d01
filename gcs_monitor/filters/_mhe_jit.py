"""Numba kernels of the real-time MHE (Wan2018 sec. V, Algorithms 1-2): the implementation.

``mhe.mhe_step`` runs them (loaded through ``gcs_monitor.core.kernels.load_kernels``); the
numpy reference of the equivalence test is ``tests/reference/mhe.py``. Model-agnostic: the
linearisation over the horizon (eq. 42) comes from the model (its optional compiled
``linearise_horizon``, or its methods node by node, ``mhe._linearise``) between :func:`shift`
and :func:`rti_solve`.

Products are loops (4x4 to 8x8 matrices: a BLAS call per product costs more than the arithmetic);
the Cholesky factorisation and solves are ``filters/_linalg.py``'s.
``error_model="numpy"``: a division by zero gives inf/NaN, which the finiteness check of
:func:`rti_solve` turns into ``numerics_ok = False``, instead of raising inside the pipeline.
"""
# ruff: noqa: N803, N806
# mypy: disable-error-code="no-untyped-def"

from __future__ import annotations

import math

import numba
import numpy as np

from gcs_monitor.filters._linalg import cho_solve, cholesky

# this file calls _linalg's jitted functions: see gcs_monitor.core.kernels
KERNEL_DEPENDENCIES = {"gcs_monitor.filters._linalg": "67db0d1c07e50a4e"}

jit = numba.njit(cache=True, fastmath=False, nogil=True, error_model="numpy")


@jit
def _clip_row(v, lb, ub):
    """Clip one row into the box, a thousandth of each finite width inside it, in place."""
    for c in range(v.shape[0]):
        w = ub[c] - lb[c]
        margin = w * 1.0e-3 if math.isfinite(w) else 0.0
        lo = lb[c] + margin
        hi = ub[c] - margin
        x = v[c]
        if x < lo:  # np.maximum(v, lo)
            x = lo
        if x > hi:  # np.minimum(., hi)
            x = hi
        v[c] = x


@jit
def shift(
    x,
    u,
    theta,
    dt_in,
    y_in,
    mask_in,
    s_n,
    x_node,
    y,
    y_mask,
    theta_p,
    dt_s,
    x_lb,
    x_ub,
    u_lb,
    u_ub,
    constrained,
    x_lin,
    u_lin,
    th,
    dts,
    ym,
    mk,
):
    """Shift the horizon by one sample (real-time iteration) and clip it into the box.

    Drops node l-1 when the horizon is full, appends ``x_node = x_hat_{k|k-1}`` with
    ``u_hat = 0``, the new Theta, y (0 where masked) and mask. Rows from ``n`` on are zero.
    Returns ``n``, the number of nodes in use.
    """
    big_n = x.shape[0]
    drop = 1 if s_n == big_n else 0
    n = s_n + 1 - drop
    keep = s_n - drop
    x_lin[:, :] = 0.0
    u_lin[:, :] = 0.0
    th[:, :] = 0.0
    dts[:] = 0.0
    ym[:, :] = 0.0
    mk[:, :] = 0.0
    for i in range(keep):
        x_lin[i, :] = x[drop + i, :]
        th[i, :] = theta[drop + i, :]
        dts[i] = dt_in[drop + i]
        ym[i, :] = y_in[drop + i, :]
        mk[i, :] = mask_in[drop + i, :]
    for i in range(max(keep - 1, 0)):
        u_lin[i, :] = u[drop + i, :]
    dts[keep - 1] = dt_s  # keep = 0 only for N = 1, where node 0 is overwritten below
    x_lin[keep, :] = x_node
    th[keep, :] = theta_p
    for c in range(y.shape[0]):
        ym[keep, c] = y[c] if y_mask[c] > 0 else 0.0
        mk[keep, c] = y_mask[c]
    dts[keep] = 0.0
    if constrained:
        # the barrier needs a strictly interior linearisation point
        for i in range(n):
            _clip_row(x_lin[i], x_lb, x_ub)
        for i in range(n - 1):
            _clip_row(u_lin[i], u_lb, u_ub)
    return n


@jit
def ip_solve(
    n,
    p_diag,
    q_diag,
    r_diag,
    a,
    b,
    cm,
    f,
    ry,
    ru,
    dxl,
    dxu,
    dul,
    duu,
    constrained,
    n_kappa,
    n_qp,
    kappa_init,
    kappa_factor,
    n_s_max,
    dx,
    du,
    steps,
):
    """Algorithm 1 (barrier IP) + Algorithm 2 (Riccati) on the QP of eq. 42.

    Writes dx (N, n_x), du (N-1, n_u) and the step sizes; returns False if a Cholesky
    factorisation failed.
    """
    n_x = dx.shape[1]
    n_u = du.shape[1]
    n_y = cm.shape[1]
    m = n_y + n_x if constrained else n_y
    cbar = np.zeros((n, m, n_x))
    rybar = np.zeros((n, m))
    qbar = np.zeros((n, n_u))
    rubar = np.zeros((n, n_u))
    rp = np.zeros((n, n_x))
    pi_ = np.zeros((n, m, n_x))
    om = np.zeros((n, n_x, m))
    kg = np.zeros((n, n_x, m))
    pf = np.zeros((n, n_x, n_x))
    s_mat = np.zeros((m, m))
    rhs = np.zeros((m, n_x))
    p_hat = np.zeros((n_x, n_x))
    tmp = np.zeros((n_x, n_x))
    xp = np.zeros((n, n_x))
    rr = np.zeros((n, m))
    x_hat = np.zeros(n_x)
    x_next = np.zeros(n_x)
    d = np.zeros((n, n_x))
    e = np.zeros((n, n_u))
    lam = np.zeros(n_x)
    xi_v = np.zeros(n_x)
    w_m = np.zeros(m)
    dx[:, :] = 0.0
    du[:, :] = 0.0
    kappa = kappa_init
    ok = True
    for j in range(n_kappa * n_qp):
        sk = math.sqrt(kappa)
        # --- linearisation (46)
        for i in range(n):
            for r_ in range(n_y):
                acc = ry[i, r_]
                for c_ in range(n_x):
                    cbar[i, r_, c_] = cm[i, r_, c_]
                    acc -= cm[i, r_, c_] * dx[i, c_]
                rybar[i, r_] = acc
            if constrained:
                for c_ in range(n_x):
                    iu = 1.0 / (dxu[i, c_] - dx[i, c_])
                    il = 1.0 / (dx[i, c_] - dxl[i, c_])
                    lsq = math.sqrt(iu * iu + il * il)
                    for cc in range(n_x):
                        cbar[i, n_y + c_, cc] = 0.0
                    cbar[i, n_y + c_, c_] = sk * lsq
                    rybar[i, n_y + c_] = -sk * (iu - il) / lsq if lsq > 0.0 else 0.0
            if i < n - 1:
                for c_ in range(n_u):
                    gu = 0.0
                    lu2 = 0.0
                    if constrained:
                        iu = 1.0 / (duu[i, c_] - du[i, c_])
                        il = 1.0 / (du[i, c_] - dul[i, c_])
                        gu = iu - il
                        lu2 = iu * iu + il * il
                    qbar[i, c_] = 1.0 / (1.0 / q_diag[c_] + kappa * lu2)
                    rubar[i, c_] = qbar[i, c_] * ((ru[i, c_] - du[i, c_]) / q_diag[c_] - kappa * gu)
                for r_ in range(n_x):
                    acc = -f[i, r_] + dx[i + 1, r_]
                    for c_ in range(n_x):
                        acc -= a[i, r_, c_] * dx[i, c_]
                    for c_ in range(n_u):
                        acc -= b[i, r_, c_] * du[i, c_]
                    rp[i, r_] = acc
        # --- Algorithm 2, factorisation (lines 1-9)
        for r_ in range(n_x):
            for c_ in range(n_x):
                p_hat[r_, c_] = 0.0
            p_hat[r_, r_] = p_diag[r_]
        for i in range(n):
            # Pi = C_bar P_hat
            for r_ in range(m):
                for c_ in range(n_x):
                    acc = 0.0
                    for k in range(n_x):
                        acc += cbar[i, r_, k] * p_hat[k, c_]
                    pi_[i, r_, c_] = acc
            # S = Pi C_bar^T + R_bar
            for r_ in range(m):
                for c_ in range(m):
                    acc = 0.0
                    for k in range(n_x):
                        acc += pi_[i, r_, k] * cbar[i, c_, k]
                    s_mat[r_, c_] = acc
            for r_ in range(n_y):
                s_mat[r_, r_] += r_diag[r_]
            for r_ in range(n_y, m):
                s_mat[r_, r_] += 1.0
            for r_ in range(m):
                for c_ in range(n_x):
                    rhs[r_, c_] = cbar[i, r_, c_]
            # Xi C_bar = S^{-1} C_bar (line 5), S factorised in place
            if cholesky(s_mat, s_mat):
                cho_solve(s_mat, rhs)
            else:
                ok = False
            for r_ in range(n_x):
                for c_ in range(m):
                    om[i, r_, c_] = rhs[c_, r_]  # Omega = C_bar^T Xi (Xi symmetric)
            # K = P_hat Omega, P_f = P_hat - K Pi
            for r_ in range(n_x):
                for c_ in range(m):
                    acc = 0.0
                    for k in range(n_x):
                        acc += p_hat[r_, k] * om[i, k, c_]
                    kg[i, r_, c_] = acc
            for r_ in range(n_x):
                for c_ in range(n_x):
                    acc = 0.0
                    for k in range(m):
                        acc += kg[i, r_, k] * pi_[i, k, c_]
                    pf[i, r_, c_] = p_hat[r_, c_] - acc
            if i < n - 1:
                # P_hat = A P_f A^T + B Qbar B^T
                for r_ in range(n_x):
                    for c_ in range(n_x):
                        acc = 0.0
                        for k in range(n_x):
                            acc += a[i, r_, k] * pf[i, k, c_]
                        tmp[r_, c_] = acc
                for r_ in range(n_x):
                    for c_ in range(n_x):
                        acc = 0.0
                        for k in range(n_x):
                            acc += tmp[r_, k] * a[i, c_, k]
                        acc2 = 0.0
                        for k in range(n_u):
                            acc2 += b[i, r_, k] * qbar[i, k] * b[i, c_, k]
                        p_hat[r_, c_] = acc + acc2
        # forward recursion (lines 10-18)
        for c_ in range(n_x):
            x_hat[c_] = -dx[0, c_]
        for i in range(n):
            for r_ in range(m):
                acc = 0.0
                for k in range(n_x):
                    acc += cbar[i, r_, k] * x_hat[k]
                rr[i, r_] = rybar[i, r_] - acc
            for r_ in range(n_x):
                acc = 0.0
                for k in range(m):
                    acc += kg[i, r_, k] * rr[i, k]
                xp[i, r_] = x_hat[r_] + acc
            if i < n - 1:
                for r_ in range(n_x):
                    acc = 0.0
                    for k in range(n_x):
                        acc += a[i, r_, k] * xp[i, k]
                    acc2 = 0.0
                    for k in range(n_u):
                        acc2 += b[i, r_, k] * rubar[i, k]
                    x_next[r_] = -rp[i, r_] + acc + acc2
                for r_ in range(n_x):
                    x_hat[r_] = x_next[r_]
        # backward recursion (lines 19-27)
        for c_ in range(n_x):
            d[n - 1, c_] = xp[n - 1, c_]
        for r_ in range(n_x):
            acc = 0.0
            for k in range(m):
                acc += om[n - 1, r_, k] * rr[n - 1, k]
            lam[r_] = -acc
        for i in range(n - 2, -1, -1):
            for r_ in range(n_x):
                acc = 0.0
                for k in range(n_x):
                    acc += a[i, k, r_] * lam[k]
                xi_v[r_] = acc
            for r_ in range(n_u):
                acc = 0.0
                for k in range(n_x):
                    acc += b[i, k, r_] * lam[k]
                e[i, r_] = rubar[i, r_] - qbar[i, r_] * acc
            for r_ in range(n_x):
                acc = 0.0
                for k in range(n_x):
                    acc += pf[i, r_, k] * xi_v[k]
                d[i, r_] = xp[i, r_] - acc
            if i > 0:
                for r_ in range(m):
                    acc = 0.0
                    for k in range(n_x):
                        acc += pi_[i, r_, k] * xi_v[k]
                    w_m[r_] = rr[i, r_] + acc
                for r_ in range(n_x):
                    acc = 0.0
                    for k in range(m):
                        acc += om[i, r_, k] * w_m[k]
                    lam[r_] = xi_v[r_] - acc
        # --- line search (Algorithm 1): largest 2^-ns keeping every iterate strictly inside
        s = 1.0
        if constrained:
            s = 0.0
            t = 1.0
            for _ns in range(n_s_max + 1):
                feas = True
                for i in range(n):
                    for c_ in range(n_x):
                        v = dx[i, c_] + t * d[i, c_]
                        if not (v > dxl[i, c_] and v < dxu[i, c_]):
                            feas = False
                    if i < n - 1:
                        for c_ in range(n_u):
                            v = du[i, c_] + t * e[i, c_]
                            if not (v > dul[i, c_] and v < duu[i, c_]):
                                feas = False
                if feas:
                    s = t
                    break
                t *= 0.5
        steps[j] = s
        for i in range(n):
            for c_ in range(n_x):
                dx[i, c_] += s * d[i, c_]
            if i < n - 1:
                for c_ in range(n_u):
                    du[i, c_] += s * e[i, c_]
        # n_kappa values of kappa, n_QP iterations each (mhe module docstring)
        if (j + 1) % n_qp == 0:
            kappa *= kappa_factor
    return ok


@jit
def rti_solve(
    n,
    p_diag,
    q_diag,
    r_diag,
    a,
    b,
    cm,
    f,
    ry,
    x_lin,
    u_lin,
    x_lb,
    x_ub,
    u_lb,
    u_ub,
    constrained,
    n_kappa,
    n_qp,
    kappa_init,
    kappa_factor,
    n_s_max,
    x_new,
    u_new,
    steps,
):
    """The QP of eq. 42 around (x_lin, u_lin) and the new horizon solution.

    Writes ``x_new = x_lin + dx`` (N, n_x), ``u_new = u_lin + du`` (N-1, n_u) and the step
    sizes. Returns ``(numerics_ok, n_active)``: False if a factorisation failed or a result is
    not finite; the number of entries within 1 % of their box width of a bound.
    """
    big_n, n_x = x_lin.shape
    n_um, n_u = u_lin.shape
    ru = np.empty((n_um, n_u))
    dul = np.empty((n_um, n_u))
    duu = np.empty((n_um, n_u))
    dxl = np.empty((big_n, n_x))
    dxu = np.empty((big_n, n_x))
    for i in range(n_um):
        for c in range(n_u):
            ru[i, c] = -u_lin[i, c]
            if constrained:
                dul[i, c] = u_lb[c] - u_lin[i, c]
                duu[i, c] = u_ub[c] - u_lin[i, c]
            else:
                dul[i, c] = -np.inf
                duu[i, c] = np.inf
    for i in range(big_n):
        for c in range(n_x):
            if constrained:
                dxl[i, c] = x_lb[c] - x_lin[i, c]
                dxu[i, c] = x_ub[c] - x_lin[i, c]
            else:
                dxl[i, c] = -np.inf
                dxu[i, c] = np.inf
    dx = np.empty((big_n, n_x))
    du = np.empty((n_um, n_u))
    ok = ip_solve(
        n, p_diag, q_diag, r_diag, a, b, cm, f, ry, ru, dxl, dxu, dul, duu,
        constrained, n_kappa, n_qp, kappa_init, kappa_factor, n_s_max, dx, du, steps,
    )  # fmt: skip
    n_active = 0
    for i in range(big_n):
        for c in range(n_x):
            v = x_lin[i, c] + dx[i, c]
            x_new[i, c] = v
            if i < n:
                if not math.isfinite(v):
                    ok = False
                if constrained:
                    w = x_ub[c] - x_lb[c]
                    tol = w * 1.0e-2 if math.isfinite(w) else 0.0
                    if v - x_lb[c] < tol or x_ub[c] - v < tol:
                        n_active += 1
    for i in range(n_um):
        for c in range(n_u):
            v = u_lin[i, c] + du[i, c]
            u_new[i, c] = v
            if i < n - 1:
                if not math.isfinite(v):
                    ok = False
                if constrained:
                    w = u_ub[c] - u_lb[c]
                    tol = w * 1.0e-2 if math.isfinite(w) else 0.0
                    if v - u_lb[c] < tol or u_ub[c] - v < tol:
                        n_active += 1
    return ok, n_active
