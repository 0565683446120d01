"""Numba kernel of the IOTSEKF step on a caller's discretisation (Lu2017 eqs. 14-36).

The same filter as Lu2016's (``filters/two_stage.py``): this kernel chains the equation segments
of ``filters/_two_stage_jit.py`` (``coupling``, ``prediction``, ``innovation_covariance``,
``joseph``, ``bias_terms``, ``blend``) between Cholesky factorisations of ``filters/_linalg.py``;
only the inputs differ -- the caller supplies the transition ``Phi``, the fault input matrix
``Gamma``, the discrete *state* process noise ``Q_d`` and the propagated bias-free state, and
the output is linear (``y = H x``, Lu2017 eq. 5). ``filters/iotsekf.py`` wraps it; the numpy
transcription of the printed equations is ``tests/reference/iotsekf.py``. Loaded through
``gcs_monitor.core.kernels``.
"""
# ruff: noqa: N803, N806, E741
# mypy: disable-error-code="no-untyped-def"

from __future__ import annotations

import numba
import numpy as np

from gcs_monitor.filters._linalg import cholesky
from gcs_monitor.filters._two_stage_jit import (
    _solve,
    bias_terms,
    blend,
    coupling,
    innovation_covariance,
    joseph,
    prediction,
)

# this file calls the jitted functions of these files: see gcs_monitor.core.kernels
KERNEL_DEPENDENCIES = {
    "gcs_monitor.filters._linalg": "67db0d1c07e50a4e",
    "gcs_monitor.filters._two_stage_jit": "793751f1759a3961",
}

jit = numba.njit(cache=True, fastmath=False, nogil=True)

OK = 0
FAIL_PREDICTION = 1  # P^f_{k|k-1} not positive definite
FAIL_UPDATE = 2  # an innovation covariance not positive definite or a result not finite


@jit
def step(x_bar_prop, Phi, Gam, Qd, Qf, x_bar, P_bar, f, Pf, V, H, y, R, gate, out_state,
         out_innov):
    """One IOTSEKF step from k-1 to k (Lu2017 eqs. 14-36, ``Q^{xf} = 0``).

    Parameters
    ----------
    x_bar_prop : (n,) ``x_bar_{k-1|k-1} + int f(x_bar, u, 0) dt`` (eq. 17 without ``u_bar``)
    Phi, Gam : (n, n), (n, b) transition and fault input matrix over the interval (eqs. 19-20)
    Qd : (n, n) discrete state process noise ``Q_{k-1}`` (eqs. 18, 32)
    Qf : (b, b) fault random-walk covariance ``Q^{f^i}`` (eqs. 14, 28)
    x_bar, P_bar, f, Pf, V : the filter at k-1 (bias-free state and covariance, fault estimate
        and covariance, blending matrix)
    H, y, R : (m, n), (m,), (m, m) linear output ``y = H x + v`` (eqs. 5, 21)
    gate : gate of the test ratio (reporting)
    out_state : the filter at k, packed ``[x_bar (n), P_bar (n n), f (b), Pf (b b), V (n b),
        x_hat (n), P_x (n n)]``
    out_innov : ``[gamma (m), S_diag (m), test_ratio (m)]``, the bias-filter innovation of
        eq. 27 and the diagonal of its covariance ``H P_bar H^T + R + S P^f S^T`` (eq. 29)

    Returns :data:`OK`, :data:`FAIL_PREDICTION` or :data:`FAIL_UPDATE`.

    The iteration of eqs. 21-23 is one pass: with a linear output ``H`` does not depend on
    ``eta_1`` and ``eta_2 = x_bar_{k|k-1} + K (y - H x_bar_{k|k-1})`` whatever ``eta_1`` is, so
    the second pass reproduces the first (``epsilon = 0``).
    """
    n = Phi.shape[0]
    b = Gam.shape[1]
    m = y.shape[0]
    Ubar, Pf_pred, W = coupling(Phi, Gam, V, Pf, Qf)  # eqs. 33, 28; W = -Ubar Q^f
    Lf = np.zeros((b, b))
    if not cholesky(Pf_pred, Lf):
        return FAIL_PREDICTION
    U = Ubar + _solve(Lf, W.T).T  # eq. 35
    # eq. 32 (Q_bar = Q + U Q^f Ubar^T) through _two_stage_jit.prediction with Gamma = I
    ubar, P_pred = prediction(Phi, np.eye(n), Qd, P_bar, Ubar, U, W, f)  # eqs. 31, 18
    x_pred = x_bar_prop + ubar  # eq. 17
    hx = H @ x_pred
    PHt, Sx = innovation_covariance(P_pred, H, R)
    L = np.zeros((m, m))
    for i in range(m):
        out_innov[i] = y[i] - hx[i]
        out_innov[m + i] = Sx[i, i]
        out_innov[2 * m + i] = np.nan
    if not cholesky(Sx, L):
        return FAIL_UPDATE
    K = np.ascontiguousarray(_solve(L, PHt.T).T)  # eq. 22
    xb = x_pred + K @ (y - hx)  # eqs. 23-24 (one pass, see above)
    Pb = joseph(P_pred, K, H, R)  # eq. 25
    S, PfSt, Sig, gamma = bias_terms(H, np.ascontiguousarray(U), Pf_pred, Sx, y, hx,
                                     f)  # eqs. 34, 29, 27
    for i in range(m):
        out_innov[i] = gamma[i]
        out_innov[m + i] = Sig[i, i]
    Lg = np.zeros((m, m))
    if not cholesky(Sig, Lg) or not np.all(np.isfinite(gamma)):
        return FAIL_UPDATE
    for i in range(m):
        out_innov[2 * m + i] = gamma[i] * gamma[i] / (gate * gate * Sig[i, i])
    Kf = np.ascontiguousarray(_solve(Lg, PfSt.T).T)  # eq. 29
    # eqs. 27, 30 (Joseph form with R_eff = S_x), 36, 15, 16
    f_new, Pf_new, V_new, x_hat, Px = blend(np.ascontiguousarray(U), K, S, xb, Pb, f, Kf,
                                            gamma, Pf_pred, Sx)
    if not (np.all(np.isfinite(x_hat)) and np.all(np.isfinite(Px))
            and np.all(np.isfinite(f_new))):
        return FAIL_UPDATE
    o = 0
    for i in range(n):
        out_state[o + i] = xb[i]
    o += n
    for i in range(n):
        for j in range(n):
            out_state[o + i * n + j] = Pb[i, j]
    o += n * n
    for i in range(b):
        out_state[o + i] = f_new[i]
    o += b
    for i in range(b):
        for j in range(b):
            out_state[o + i * b + j] = Pf_new[i, j]
    o += b * b
    for i in range(n):
        for j in range(b):
            out_state[o + i * b + j] = V_new[i, j]
    o += n * b
    for i in range(n):
        out_state[o + i] = x_hat[i]
    o += n
    for i in range(n):
        for j in range(n):
            out_state[o + i * n + j] = Px[i, j]
    return OK
