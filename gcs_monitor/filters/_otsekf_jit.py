"""Numba kernels of the optimal two-stage EKF (Atmaca2025 eqs. 20-42).

Same equations, same order as ``otsekf._step_reference``; imported lazily by ``otsekf._kernels``
and cached on disk by numba. The step is split in two because the measurement model is evaluated
between them at the predicted augmented estimate (a model function, not part of the filter):

* :func:`predict` -- eqs. 30-31, 35-39, 20, 22 and ``x_hat_{k|k-1}``;
* :func:`update` -- eqs. 21, 23-24, 32-34, 38, 40-42 and the test ratio.

Products are written as loops (6x6 matrices: a BLAS call per product costs more than the
arithmetic) and Cholesky solves return an ok flag instead of raising. All outputs are written
into arrays the caller passes in. No function here calls a function of another module, so
numba's per-file cache invalidation is sufficient.
"""
# ruff: noqa: N803, N806, E741
# mypy: disable-error-code="no-untyped-def"

from __future__ import annotations

import math

import numba
import numpy as np

jit = numba.njit(cache=True, fastmath=False, nogil=True)


@jit
def _mm(A, B, out):
    """out = A @ B."""
    n, k = A.shape
    m = B.shape[1]
    for i in range(n):
        for j in range(m):
            acc = 0.0
            for t in range(k):
                acc += A[i, t] * B[t, j]
            out[i, j] = acc


@jit
def _mmt(A, B, out):
    """out = A @ B.T."""
    n, k = A.shape
    m = B.shape[0]
    for i in range(n):
        for j in range(m):
            acc = 0.0
            for t in range(k):
                acc += A[i, t] * B[j, t]
            out[i, j] = acc


@jit
def _mv(A, x, out):
    """out = A @ x."""
    n, k = A.shape
    for i in range(n):
        acc = 0.0
        for t in range(k):
            acc += A[i, t] * x[t]
        out[i] = acc


@jit
def _symmetrise(P):
    n = P.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            v = (P[i, j] + P[j, i]) * 0.5
            P[i, j] = v
            P[j, i] = v


@jit
def _chol(A, L):
    """Lower Cholesky factor of A into L; False if A is not PD or not finite."""
    n = A.shape[0]
    for i in range(n):
        for j in range(n):
            L[i, j] = 0.0
    for j in range(n):
        d = A[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        if not d > 0.0:  # also catches NaN
            return False
        ljj = math.sqrt(d)
        L[j, j] = ljj
        for i in range(j + 1, n):
            v = A[i, j]
            for k in range(j):
                v -= L[i, k] * L[j, k]
            L[i, j] = v / ljj
    return True


@jit
def _gain_t(L, M, out):
    """out = (L L^T)^{-1} M^T transposed, i.e. ``M S^{-1}`` for M (r, n) and S = L L^T (n, n).

    This is the Kalman-gain form ``K = P H^T S^{-1}`` with ``M = P H^T``.
    """
    r, n = M.shape
    for c in range(r):
        for i in range(n):
            v = M[c, i]
            for k in range(i):
                v -= L[i, k] * out[c, k]
            out[c, i] = v / L[i, i]
        for i in range(n - 1, -1, -1):
            v = out[c, i]
            for k in range(i + 1, n):
                v -= L[k, i] * out[c, k]
            out[c, i] = v / L[i, i]


@jit
def _joseph(P, K, H, R, out, A, T1, T2, KR):
    """out = (I - K H) P (I - K H)^T + K R K^T, symmetrised (Joseph form)."""
    n = P.shape[0]
    _mm(K, H, A)
    for i in range(n):
        for j in range(n):
            A[i, j] = -A[i, j]
        A[i, i] += 1.0
    _mm(A, P, T1)
    _mmt(T1, A, T2)
    _mm(K, R, KR)
    _mmt(KR, K, out)
    for i in range(n):
        for j in range(n):
            out[i, j] += T2[i, j]
    _symmetrise(out)


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
    if not _chol(P_mu_pred, L_mu):
        return False
    U_bar = np.empty((n, b))
    _mm(Phi, V, U_bar)  # eq. 37
    for i in range(n):
        for j in range(b):
            U_bar[i, j] += B[i, j]
    W = np.empty((n, b))
    _mm(U_bar, Qmu, W)  # eq. 39: W = Q^{x mu} - U_bar Q^{mu}
    for i in range(n):
        for j in range(b):
            W[i, j] = Qxmu[i, j] - W[i, j]
    _gain_t(L_mu, W, U)  # W (P^{mu}_{k|k-1})^{-1}
    for i in range(n):
        for j in range(b):
            U[i, j] += U_bar[i, j]
    # eq. 36 (shifted one index): Q_bar = Qx - Qxmu U_bar^T - U W^T
    Q_bar = np.empty((n, n))
    T = np.empty((n, n))
    _mmt(Qxmu, U_bar, Q_bar)
    _mmt(U, W, T)
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
    _mm(Phi, P_bar, T)
    _mmt(T, Phi, P_bar_pred)
    for i in range(n):
        for j in range(n):
            P_bar_pred[i, j] += Q_bar[i, j]
    _symmetrise(P_bar_pred)
    _mv(U, mu, x_hat_pred)
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
    _mm(H, U, S_k)  # eq. 38
    nu_bar = np.empty(m)  # y - H x_bar_{k|k-1} = nu + S mu
    _mv(S_k, mu_pred, nu_bar)
    for i in range(m):
        nu_bar[i] += nu[i]
    # eq. 23
    PHt = np.empty((n, m))
    _mmt(P_bar_pred, H, PHt)
    C_bar = np.empty((m, m))
    _mm(H, PHt, C_bar)
    for i in range(m):
        for j in range(m):
            C_bar[i, j] += R[i, j]
    _symmetrise(C_bar)
    L = np.empty((m, m))
    if not _chol(C_bar, L):
        return False
    K_bar = np.empty((n, m))
    _gain_t(L, PHt, K_bar)
    # eqs. 21, 24
    _mv(K_bar, nu_bar, x_bar)
    for i in range(n):
        x_bar[i] += x_bar_pred[i]
    A = np.empty((n, n))
    T1 = np.empty((n, n))
    T2 = np.empty((n, n))
    KR = np.empty((n, m))
    _joseph(P_bar_pred, K_bar, H, R, P_bar, A, T1, T2, KR)
    # eq. 32 (with H P_bar H^T, see otsekf module docstring)
    PSt = np.empty((b, m))
    _mmt(P_mu_pred, S_k, PSt)
    _mm(S_k, PSt, C)
    for i in range(m):
        for j in range(m):
            C[i, j] += C_bar[i, j]
    _symmetrise(C)
    if not _chol(C, L):
        return False
    K_mu = np.empty((b, m))
    _gain_t(L, PSt, K_mu)
    # eqs. 33, 34 (Joseph form with C_bar as the bias filter's measurement noise)
    _mv(K_mu, nu, mu)
    for i in range(b):
        mu[i] += mu_pred[i]
    Ab = np.empty((b, b))
    T1b = np.empty((b, b))
    T2b = np.empty((b, b))
    KRb = np.empty((b, m))
    _joseph(P_mu_pred, K_mu, S_k, C_bar, P_mu, Ab, T1b, T2b, KRb)
    # eqs. 40-42
    _mm(K_bar, S_k, V)
    for i in range(n):
        for j in range(b):
            V[i, j] = U[i, j] - V[i, j]
    _mv(V, mu, x_hat)
    for i in range(n):
        x_hat[i] += x_bar[i]
    VP = np.empty((n, b))
    _mm(V, P_mu, VP)
    _mmt(VP, V, P)
    for i in range(n):
        for j in range(n):
            P[i, j] += P_bar[i, j]
    _symmetrise(P)
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
