"""Numba kernels of the optimal two-stage EKF (Atmaca2025 eqs. 20-42): the implementation.

``otsekf.otsekf_step`` runs them (loaded through ``gcs_monitor.core.kernels.load_kernels``);
the numpy reference of the equivalence test is ``tests/reference/otsekf.py``. The step is split
in two because the measurement model is evaluated between them at the predicted augmented
estimate (a model function, not part of the filter):

* :func:`predict` -- eqs. 30-31, 35-39, 20, 22 and ``x_hat_{k|k-1}``;
* :func:`update` -- eqs. 21, 23-24, 32-34, 38, 40-42 and the test ratio.

Products are loops and Cholesky solves return an ok flag instead of raising (both from
``filters/_linalg.py``). All outputs are written into arrays the caller passes in.
"""
# ruff: noqa: N803, N806, E741
# mypy: disable-error-code="no-untyped-def"

from __future__ import annotations

import math

import numba
import numpy as np

from gcs_monitor.filters._linalg import (
    cho_solve_right,
    cholesky,
    joseph,
    matmul,
    matmul_t,
    matvec,
    symmetrise,
)

# this file calls _linalg's jitted functions: see gcs_monitor.core.kernels
KERNEL_DEPENDENCIES = {"gcs_monitor.filters._linalg": "67db0d1c07e50a4e"}

jit = numba.njit(cache=True, fastmath=False, nogil=True)


@jit
def predict(
    x_bar_prop,
    Phi,
    B,
    Qx,
    Qxmu,
    Qmu,
    V,
    P_bar,
    mu,
    P_mu,
    U,
    x_bar_pred,
    P_bar_pred,
    P_mu_pred,
    x_hat_pred,
):
    """Prediction from k-1 to k (Atmaca2025 eqs. 30-31, 35-39, 20, 22).

    Inputs as in ``otsekf.OtsekfPrediction`` and ``OtsekfState``; writes ``U`` (n, b),
    ``x_bar_pred`` (n,), ``P_bar_pred`` (n, n), ``P_mu_pred`` (b, b) and the predicted augmented
    estimate ``x_hat_pred = x_bar_pred + U mu`` (n,). Returns False if ``P_mu_pred`` is not PD.
    """
    n, b = B.shape
    for i in range(b):  # eq. 31
        for j in range(b):
            P_mu_pred[i, j] = P_mu[i, j] + Qmu[i, j]
    L_mu = np.empty((b, b))
    if not cholesky(P_mu_pred, L_mu):
        return False
    U_bar = np.empty((n, b))
    matmul(Phi, V, U_bar)  # eq. 37
    for i in range(n):
        for j in range(b):
            U_bar[i, j] += B[i, j]
    W = np.empty((n, b))
    matmul(U_bar, Qmu, W)  # eq. 39: W = Q^{x mu} - U_bar Q^{mu}
    for i in range(n):
        for j in range(b):
            W[i, j] = Qxmu[i, j] - W[i, j]
    cho_solve_right(L_mu, W, U)  # W (P^{mu}_{k|k-1})^{-1}
    for i in range(n):
        for j in range(b):
            U[i, j] += U_bar[i, j]
    # eq. 36 (shifted one index): Q_bar = Qx - Qxmu U_bar^T - U W^T
    Q_bar = np.empty((n, n))
    T = np.empty((n, n))
    matmul_t(Qxmu, U_bar, Q_bar)
    matmul_t(U, W, T)
    for i in range(n):
        for j in range(n):
            Q_bar[i, j] = Qx[i, j] - Q_bar[i, j] - T[i, j]
    # eqs. 35, 20: u_bar = (U_bar - U) mu, x_bar_pred = x_bar_prop + u_bar
    for i in range(n):
        acc = 0.0
        for j in range(b):
            acc += (U_bar[i, j] - U[i, j]) * mu[j]
        x_bar_pred[i] = x_bar_prop[i] + acc
    # eq. 22
    matmul(Phi, P_bar, T)
    matmul_t(T, Phi, P_bar_pred)
    for i in range(n):
        for j in range(n):
            P_bar_pred[i, j] += Q_bar[i, j]
    symmetrise(P_bar_pred)
    matvec(U, mu, x_hat_pred)
    for i in range(n):
        x_hat_pred[i] += x_bar_pred[i]
    return True


@jit
def update(
    y,
    y_pred,
    H,
    R,
    wrap,
    gate_sigma,
    x_bar_pred,
    P_bar_pred,
    U,
    mu_pred,
    P_mu_pred,
    x_bar,
    P_bar,
    mu,
    P_mu,
    V,
    x_hat,
    P,
    nu,
    C,
    test_ratio,
):
    """Update at k (Atmaca2025 eqs. 21, 23-24, 32-34, 38, 40-42), Joseph form.

    ``wrap`` (m,) is 1 for angle components of the innovation (wrapped to (-pi, pi]). Writes the
    new state (``x_bar .. P``), the innovation ``nu``, its covariance ``C`` and the test ratio.
    Returns False on a non-PD covariance or a non-finite result (outputs then undefined, except
    ``nu`` which is the innovation).
    """
    n = x_bar_pred.shape[0]
    b = mu_pred.shape[0]
    m = y.shape[0]
    two_pi = 2.0 * math.pi
    for i in range(m):
        v = y[i] - y_pred[i]
        if wrap[i]:
            v = (v + math.pi) % two_pi - math.pi
        nu[i] = v
    S_k = np.empty((m, b))
    matmul(H, U, S_k)  # eq. 38
    nu_bar = np.empty(m)  # y - H x_bar_{k|k-1} = nu + S mu
    matvec(S_k, mu_pred, nu_bar)
    for i in range(m):
        nu_bar[i] += nu[i]
    # eq. 23
    PHt = np.empty((n, m))
    matmul_t(P_bar_pred, H, PHt)
    C_bar = np.empty((m, m))
    matmul(H, PHt, C_bar)
    for i in range(m):
        for j in range(m):
            C_bar[i, j] += R[i, j]
    symmetrise(C_bar)
    L = np.empty((m, m))
    if not cholesky(C_bar, L):
        return False
    K_bar = np.empty((n, m))
    cho_solve_right(L, PHt, K_bar)
    # eqs. 21, 24
    matvec(K_bar, nu_bar, x_bar)
    for i in range(n):
        x_bar[i] += x_bar_pred[i]
    A = np.empty((n, n))
    T1 = np.empty((n, n))
    T2 = np.empty((n, n))
    KR = np.empty((n, m))
    joseph(P_bar_pred, K_bar, H, R, P_bar, A, T1, T2, KR)
    # eq. 32 (with H P_bar H^T, see otsekf module docstring)
    PSt = np.empty((b, m))
    matmul_t(P_mu_pred, S_k, PSt)
    matmul(S_k, PSt, C)
    for i in range(m):
        for j in range(m):
            C[i, j] += C_bar[i, j]
    symmetrise(C)
    if not cholesky(C, L):
        return False
    K_mu = np.empty((b, m))
    cho_solve_right(L, PSt, K_mu)
    # eqs. 33, 34 (Joseph form with C_bar as the bias filter's measurement noise)
    matvec(K_mu, nu, mu)
    for i in range(b):
        mu[i] += mu_pred[i]
    Ab = np.empty((b, b))
    T1b = np.empty((b, b))
    T2b = np.empty((b, b))
    KRb = np.empty((b, m))
    joseph(P_mu_pred, K_mu, S_k, C_bar, P_mu, Ab, T1b, T2b, KRb)
    # eqs. 40-42
    matmul(K_bar, S_k, V)
    for i in range(n):
        for j in range(b):
            V[i, j] = U[i, j] - V[i, j]
    matvec(V, mu, x_hat)
    for i in range(n):
        x_hat[i] += x_bar[i]
    VP = np.empty((n, b))
    matmul(V, P_mu, VP)
    matmul_t(VP, V, P)
    for i in range(n):
        for j in range(n):
            P[i, j] += P_bar[i, j]
    symmetrise(P)
    g2 = gate_sigma * gate_sigma
    ok = True
    for i in range(m):
        r = nu[i] * nu[i] / (g2 * C[i, i])
        test_ratio[i] = r
        if not math.isfinite(r):
            ok = False
    for i in range(n):
        if not math.isfinite(x_hat[i]):
            ok = False
        for j in range(n):
            if not math.isfinite(P[i, j]):
                ok = False
    for i in range(b):
        if not math.isfinite(mu[i]):
            ok = False
    return ok
