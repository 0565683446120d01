"""Numba kernels of the two-stage filter (Lu2016 eqs. 31-58): the non-iterated step.

The implementation the monitor runs after the first ``n_iterated_steps`` steps, for
``Q^{xf} = 0`` and the series discretisation of eqs. 33-34 (:func:`discretise`, which the
numpy path of ``two_stage.py`` calls too). Loaded by ``two_stage`` through
``gcs_monitor.core.kernels.load_kernels``. Products use numpy's ``@`` (BLAS, bit-identical to
the numpy path's products); Cholesky solves and the inverse of eq. 57 come from
``filters/_linalg.py`` (an ok flag where numba's LAPACK wrappers would raise).
"""
# ruff: noqa: N803, N806, E741
# mypy: disable-error-code="no-untyped-def"

from __future__ import annotations

import numba
import numpy as np

from gcs_monitor.filters._linalg import cho_solve, cholesky, gauss_jordan_inverse

# this file calls _linalg's jitted functions: see gcs_monitor.core.kernels
KERNEL_DEPENDENCIES = {"gcs_monitor.filters._linalg": "67db0d1c07e50a4e"}

jit = numba.njit(cache=True, fastmath=False, nogil=True)


@jit
def discretise(F, G, dt):
    """``Phi = exp(F dt)`` and ``Gamma = int_0^dt exp(F s) ds G`` (Lu2016 eqs. 33-34).

    Series truncated after ``(F dt)^3 / 3!`` (see ``two_stage.discretise_series``).
    """
    n = F.shape[0]
    I = np.eye(n)
    A = F * dt
    A2 = A @ A
    A3 = A2 @ A
    Phi = I + A + A2 * 0.5 + A3 * (1.0 / 6.0)  # eq. 33
    Gam = ((I + A * 0.5 + A2 * (1.0 / 6.0) + A3 * (1.0 / 24.0)) * dt) @ G  # eq. 34
    return Phi, Gam


@jit
def _solve(L, B):
    """``(L L^T)^{-1} B`` as a new array (``B`` untouched)."""
    X = np.empty(B.shape)
    X[:, :] = B
    cho_solve(L, X)
    return X


# ------------------------------------------------------------------------- equation segments
# The pieces of one step between its factorisations. The kernels below (predict, update)
# chain them with _linalg's Cholesky solves; two_stage._step_numpy chains the same pieces with
# LAPACK's solves (the iterated first steps). See the two_stage module docstring.


@jit
def coupling(Phi, Gam, V, Pf, Qf):
    """``U_bar = Phi V + Gamma`` (eq. 47), ``P^f_{k|k-1} = P^f + Q^f`` (eq. 41) and
    ``W = Q^{xf} - U_bar Q^f`` with ``Q^{xf} = 0`` (eq. 49: ``U = U_bar + W (P^f_{k|k-1})^{-1}``).
    """
    Ubar = Phi @ V + Gam  # eq. 47
    Pf_pred = Pf + Qf  # eq. 41
    W = -(Ubar @ Qf)  # Qxf - Ubar Qf with Qxf = 0
    return Ubar, Pf_pred, W


@jit
def prediction(Phi, Gam, Q, P_bar, Ubar, U, W, f):
    """``u_bar`` (eq. 45) and ``P_bar_{k|k-1}`` (eq. 32 with ``Q_bar`` of eq. 46, symmetrised)."""
    Qbar = Gam @ Q @ Gam.T - U @ W.T  # eq. 46
    ubar = (Ubar - U) @ f  # eq. 45
    Pp = Phi @ P_bar @ Phi.T + Qbar  # eq. 32
    return ubar, 0.5 * (Pp + Pp.T)


@jit
def innovation_covariance(P_pred, H, R):
    """``P H^T`` and ``S_x = H P H^T + R``, the parts of the gain of eq. 36."""
    PHt = P_pred @ H.T
    Sx = H @ PHt + R
    return PHt, Sx


@jit
def joseph(P, K, H, R):
    """Joseph form, symmetrised (eqs. 39, 44), with BLAS products (``_linalg.joseph`` sums
    by loops: other round-off)."""
    A = np.eye(P.shape[0]) - K @ H
    Pn = A @ P @ A.T + K @ R @ K.T
    return 0.5 * (Pn + Pn.T)


@jit
def bias_terms(H, U, Pf_pred, Sx, y, hx, f):
    """``S = H U`` (eq. 48), ``P^f S^T`` and ``S_x + S P^f S^T`` (the gain of eq. 42), and the
    bias-filter innovation ``y - h(x_bar_{k|k-1}) - S f`` (eq. 43)."""
    S = H @ U  # eq. 48
    PfSt = Pf_pred @ S.T
    Sig = Sx + S @ PfSt
    gamma = y - hx - S @ f  # eq. 43 innovation
    return S, PfSt, Sig, gamma


@jit
def blend(U, K, S, x_bar, P_bar, f, Kf, gamma, Pf_pred, Sx):
    """Bias update (eqs. 43-44, Joseph form with ``R_eff = S_x``) and the blend (eqs. 50-52)."""
    f_new = f + Kf @ gamma  # eq. 43
    Pf_new = joseph(Pf_pred, Kf, S, Sx)  # eq. 44, Joseph form
    V = U - K @ S  # eq. 50
    x_hat = x_bar + V @ f_new  # eq. 51
    Px = P_bar + V @ Pf_new @ V.T  # eq. 52
    return f_new, Pf_new, V, x_hat, Px


# ------------------------------------------------------------------------- the step


@jit
def predict(F, G, dt, V, Pf, Qf, f, P_bar, Q):
    """Prediction of the non-iterated step (eqs. 32-34, 41, 45-49), ``Q^{xf} = 0``.

    ``F``, ``G`` (eq. 34) come from the model at ``(x_hat, u_m - f_hat)`` (Lu2016 note 1).
    Returns ``(ok, Gamma, U, u_bar, P_bar_{k|k-1}, P^f_{k|k-1})``; ``ok`` False if
    ``P^f_{k|k-1}`` is not positive definite.
    """
    n = F.shape[0]
    Phi, Gam = discretise(F, G, dt)  # eqs. 33-34
    Ubar, Pf_pred, W = coupling(Phi, Gam, V, Pf, Qf)  # eqs. 47, 41
    Lf = np.zeros(Pf_pred.shape)
    if not cholesky(Pf_pred, Lf):
        return False, Gam, Ubar, np.zeros(n), P_bar, Pf_pred
    U = Ubar + _solve(Lf, W.T).T  # eq. 49
    ubar, P_pred = prediction(Phi, Gam, Q, P_bar, Ubar, U, W, f)  # eqs. 45-46, 32
    return True, Gam, np.ascontiguousarray(U), ubar, P_pred, Pf_pred


@jit
def update(x_pred, P_pred, hx, H, y, R, U, Pf_pred, f, gamma2, k, adapt, Gam, Q, Qf, dt, gate):
    """Update of the non-iterated step (eqs. 35-44, 48, 50-52) and the adaptation (53-58).

    ``hx``, ``H`` are the model's output and its Jacobian at ``x_pred`` (eq. 35). Returns
    ``(ok, x_bar, P_bar, f, P^f, V, x_hat, P_x, gamma2, Q^f_next, nu, S_diag, test_ratio)``;
    on a non-PD innovation covariance or a non-finite innovation ``ok`` is False and only the
    innovation entries are meaningful.
    """
    m = y.shape[0]
    b = f.shape[0]
    PHt, Sx = innovation_covariance(P_pred, H, R)
    L = np.zeros(Sx.shape)
    nan_m = np.full(m, np.nan)
    if not cholesky(Sx, L):
        return (
            False,
            x_pred,
            P_pred,
            f,
            Pf_pred,
            U,
            x_pred,
            P_pred,
            gamma2,
            Qf,
            y - hx,
            nan_m,
            nan_m,
        )
    K = _solve(L, PHt.T).T  # eq. 36
    K = np.ascontiguousarray(K)
    x_bar = x_pred + K @ (y - hx)  # eqs. 37-38 (eta1 = x_pred: no iteration)
    P_bar = joseph(P_pred, K, H, R)  # eq. 39
    S, PfSt, Sig, gamma = bias_terms(H, U, Pf_pred, Sx, y, hx, f)  # eqs. 48, 42, 43
    s_diag = np.empty(m)
    for i in range(m):
        s_diag[i] = Sig[i, i]
    Lg = np.zeros(Sig.shape)
    if not cholesky(Sig, Lg) or not np.all(np.isfinite(gamma)):
        return (
            False,
            x_pred,
            P_pred,
            f,
            Pf_pred,
            U,
            x_pred,
            P_pred,
            gamma2,
            Qf,
            gamma,
            s_diag,
            nan_m,
        )
    ratio = gamma * gamma / (gate * gate * s_diag)
    Kf = np.ascontiguousarray(_solve(Lg, PfSt.T).T)  # eq. 42
    f_new, Pf_new, V, x_hat, Px = blend(U, K, S, x_bar, P_bar, f, Kf, gamma, Pf_pred, Sx)
    g2 = gamma2.copy()
    nwin = g2.shape[0]
    g2[k % nwin, :] = gamma * gamma
    Qf_next = Qf
    if adapt and k + 1 >= nwin:  # eqs. 53, 57, 58
        HG = H @ Gam
        HGQ = HG @ Q
        A = np.empty(HG.shape)
        Qf_next = np.zeros((b, b))
        if gauss_jordan_inverse(HG, A):  # (H Gamma)^{-1}
            qt = np.empty(m)
            for i in range(m):
                cr = 0.0
                for j in range(nwin):
                    cr += g2[j, i]
                q = 0.0
                for j in range(m):
                    q += HGQ[i, j] * HG[i, j]
                qt[i] = max(cr / nwin - q / dt - R[i, i], 0.0)  # eqs. 53, 58 (diagonal)
            for i in range(b):
                acc = 0.0
                for j in range(m):
                    acc += A[i, j] * A[i, j] * qt[j]
                Qf_next[i, i] = acc * dt * dt  # eq. 57, main diagonal
    ok = np.all(np.isfinite(x_hat)) and np.all(np.isfinite(Px)) and np.all(np.isfinite(f_new))
    return (
        ok,
        x_bar,
        P_bar,
        f_new,
        Pf_new,
        np.ascontiguousarray(V),
        x_hat,
        Px,
        g2,
        Qf_next,
        gamma,
        s_diag,
        ratio,
    )


@jit
def _unpack(s, n, b, m, nwin):
    """Views of a packed state: x_bar, P_bar, f, Pf, V, Qf, x, Px, gamma2 (TwoStageState order)."""
    o = 0
    x_bar = s[o:o + n]
    o += n
    P_bar = s[o:o + n * n].reshape((n, n))
    o += n * n
    f = s[o:o + b]
    o += b
    Pf = s[o:o + b * b].reshape((b, b))
    o += b * b
    V = s[o:o + n * b].reshape((n, b))
    o += n * b
    Qf = s[o:o + b * b].reshape((b, b))
    o += b * b
    x = s[o:o + n]
    o += n
    Px = s[o:o + n * n].reshape((n, n))
    o += n * n
    gamma2 = s[o:o + nwin * m].reshape((nwin, m))
    return x_bar, P_bar, f, Pf, V, Qf, x, Px, gamma2


@jit
def step_identity_output(s_in, k, s_out, F, G, xb_prop, y, Q, R, adapt, dt, gate, nwin, out):
    """One non-iterated step (:func:`predict` + :func:`update`) for an output ``h(x) = x``.

    The same calls as ``two_stage._step_compiled`` with ``hx = x_pred``, ``H = I`` (Lu2016
    eq. 14, GS-KM), on a packed state (``two_stage.pack_state`` layout) so that one call replaces
    two kernel calls and a dozen boxed arrays. ``F``, ``G`` (eq. 34) and ``xb_prop`` (eq. 31
    without ubar) come from the model. Writes the new state into ``s_out`` and
    ``[nu (m), S_diag (m), test_ratio (m)]`` into ``out``. Returns 0 on success, 1 if the
    prediction failed (``out`` unset), 2 if the update failed (``out`` as ``update`` left it).
    """
    n = F.shape[0]
    b = G.shape[1]
    m = y.shape[0]
    x_bar0, P_bar0, f0, Pf0, V0, Qf0, _x0, _Px0, g20 = _unpack(s_in, n, b, m, nwin)
    ok, Gam, U, ubar, P_pred, Pf_pred = predict(F, G, dt, V0, Pf0, Qf0, f0, P_bar0, Q)
    if not ok:
        return 1
    x_pred = xb_prop + ubar  # eq. 31
    hx = x_pred.copy()
    H = np.eye(n)
    res = update(x_pred, P_pred, hx, H, y, R, U, Pf_pred, f0, g20, k, adapt, Gam, Q, Qf0, dt,
                 gate)
    ok, x_bar, P_bar, f_new, Pf_new, V, x_hat, Px, gamma2, Qf_next, nu, s_diag, ratio = res
    for i in range(m):
        out[i] = nu[i]
        out[m + i] = s_diag[i]
        out[2 * m + i] = ratio[i]
    if not ok:
        return 2
    xb1, Pb1, f1, Pf1, V1, Qf1, x1, Px1, g21 = _unpack(s_out, n, b, m, nwin)
    xb1[:] = x_bar
    Pb1[:, :] = P_bar
    f1[:] = f_new
    Pf1[:, :] = Pf_new
    V1[:, :] = V
    Qf1[:, :] = Qf_next
    x1[:] = x_hat
    Px1[:, :] = Px
    g21[:, :] = gamma2
    return 0
