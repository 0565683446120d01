"""Numba kernel of the robust three-step EKF (Lu2017 eqs. 37-48): its one implementation.

``filters/three_step.py`` wraps it; the numpy transcription of the printed equations that the
equivalence test compares it with is ``tests/reference/three_step.py``. Products and solves by
loops (``filters/_linalg.py``): the matrices are 1x1 to 3x3. Loaded through
``gcs_monitor.core.kernels``.
"""
# ruff: noqa: N803, N806, E741
# mypy: disable-error-code="no-untyped-def"

from __future__ import annotations

import numba
import numpy as np

from gcs_monitor.filters._linalg import (
    cho_solve,
    cho_solve_right,
    cholesky,
    matmul,
    matmul_t,
    symmetrise,
)

# this file calls _linalg's jitted functions: see gcs_monitor.core.kernels
KERNEL_DEPENDENCIES = {"gcs_monitor.filters._linalg": "67db0d1c07e50a4e"}

jit = numba.njit(cache=True, fastmath=False, nogil=True)


@jit
def predict_covariance(P, Phi, Qd, out):
    """``out = Phi P Phi^T + Q_d`` (eq. 39), symmetrised."""
    n = P.shape[0]
    T = np.empty((n, n))
    matmul(Phi, P, T)
    matmul_t(T, Phi, out)
    for i in range(n):
        for j in range(n):
            out[i, j] += Qd[i, j]
    symmetrise(out)


@jit
def update(x_pred, P_pred, hx, H, F, y, R, gate, x_out, P_out, f_out, Pf_out, nu, s_diag,
           ratio):
    """Steps 2 and 3 of the RTS-EKF (eqs. 40-48) after the time update (eqs. 38-39).

    Parameters
    ----------
    x_pred, P_pred : (n,), (n, n) predicted state and covariance
    hx, H : (m,), (m, n) predicted output ``h(x_pred)`` and its Jacobian (eq. 44)
    F : (m, p) output-fault distribution, rank p <= m (existence condition, eq. 37)
    y, R : (m,), (m, m) measurement and its noise covariance
    gate : gate of the test ratio (reporting)
    x_out, P_out, f_out, Pf_out : (n,), (n, n), (p,), (p, p) the step's results
    nu, s_diag, ratio : (m,) innovation ``gamma' = y - h(x_pred)`` (eq. 41), diagonal of
        ``R~`` (eq. 40) and ``gamma'^2 / (gate^2 R~_ii)``

    Returns False (outputs undefined) when ``R~`` or ``F^T R~^{-1} F`` is not positive
    definite or a result is not finite.
    """
    n = x_pred.shape[0]
    m = y.shape[0]
    p = F.shape[1]
    PHt = np.empty((n, m))
    matmul_t(P_pred, H, PHt)
    Rt = np.empty((m, m))
    matmul(H, PHt, Rt)
    for i in range(m):
        for j in range(m):
            Rt[i, j] += R[i, j]
    symmetrise(Rt)  # eq. 40
    for i in range(m):
        nu[i] = y[i] - hx[i]  # eq. 41
        s_diag[i] = Rt[i, i]
        ratio[i] = nu[i] * nu[i] / (gate * gate * Rt[i, i])
    L = np.empty((m, m))
    if not cholesky(Rt, L):
        return False
    RiF = np.empty((m, p))
    RiF[:, :] = F
    cho_solve(L, RiF)  # R~^{-1} F
    M = np.empty((p, p))
    for i in range(p):
        for j in range(p):
            acc = 0.0
            for k in range(m):
                acc += F[k, i] * RiF[k, j]
            M[i, j] = acc
    symmetrise(M)
    Lm = np.empty((p, p))
    if not cholesky(M, Lm):
        return False
    for i in range(p):  # eq. 43: P^f = (F^T R~^{-1} F)^{-1}
        for j in range(p):
            Pf_out[i, j] = 1.0 if i == j else 0.0
    cho_solve(Lm, Pf_out)
    symmetrise(Pf_out)
    # eqs. 48, 42: f = N gamma', N = P^f F^T R~^{-1} = P^f (R~^{-1} F)^T
    g = np.empty(p)
    for i in range(p):
        acc = 0.0
        for k in range(m):
            acc += RiF[k, i] * nu[k]
        g[i] = acc
    for i in range(p):
        acc = 0.0
        for j in range(p):
            acc += Pf_out[i, j] * g[j]
        f_out[i] = acc
    K = np.empty((n, m))
    cho_solve_right(L, PHt, K)  # eq. 45: K = P H^T R~^{-1}
    r = np.empty(m)
    for i in range(m):  # eq. 46: gamma' - F f
        acc = nu[i]
        for j in range(p):
            acc -= F[i, j] * f_out[j]
        r[i] = acc
    for i in range(n):
        acc = x_pred[i]
        for k in range(m):
            acc += K[i, k] * r[k]
        x_out[i] = acc
    # eq. 47 with F P^f F^T (printed "F P^f F"): P = P - K (R~ - F P^f F^T) K^T
    FPf = np.empty((m, p))
    matmul(F, Pf_out, FPf)
    D = np.empty((m, m))
    matmul_t(FPf, F, D)
    for i in range(m):
        for j in range(m):
            D[i, j] = Rt[i, j] - D[i, j]
    KD = np.empty((n, m))
    matmul(K, D, KD)
    KDK = np.empty((n, n))
    matmul_t(KD, K, KDK)
    for i in range(n):
        for j in range(n):
            P_out[i, j] = P_pred[i, j] - KDK[i, j]
    symmetrise(P_out)
    return (np.all(np.isfinite(x_out)) and np.all(np.isfinite(P_out))
            and np.all(np.isfinite(f_out)))
