"""Numpy reference of the OTSEKF kernels (Atmaca2025 eqs. 20-42; ``filters/_otsekf_jit.py``).

The notation choices are those of ``gcs_monitor.filters.otsekf`` (module docstring there).
"""

from __future__ import annotations

import math

import numpy as np

from gcs_monitor.core.types import Mat, Vec
from gcs_monitor.filters.covariance import cho_factor_lower, cho_solve_lower, symmetrise
from gcs_monitor.filters.otsekf import (
    MeasFn,
    OtsekfInnovation,
    OtsekfPrediction,
    OtsekfState,
    _bad_innovation,
)


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def otsekf_step_reference(
    s: OtsekfState,
    pred: OtsekfPrediction,
    meas_fn: MeasFn,
    y: Vec,
    R: Mat,
    *,
    gate_sigma: float,
    wrap_idx: tuple[int, ...] = (),
) -> tuple[OtsekfState, OtsekfInnovation]:
    """:func:`gcs_monitor.filters.otsekf.otsekf_step` in numpy, equation by equation.

    Same arguments and results; LAPACK Cholesky solves and BLAS products instead of the
    kernel's loops, so the two agree to round-off.
    """
    Phi, B, Qx, Qxmu, Qmu = pred.Phi, pred.B, pred.Qx, pred.Qxmu, pred.Qmu
    # eqs. 30-31: bias random walk
    mu_pred = s.mu
    P_mu_pred = s.P_mu + Qmu
    L_mu, ok_mu = cho_factor_lower(P_mu_pred)
    m = y.shape[0]
    bad = _bad_innovation(m)
    if not ok_mu:
        return s, bad
    # eq. 37
    U_bar = Phi @ s.V + B
    # eq. 39: U = U_bar + (Q^{x mu} - U_bar Q^{mu}) (P^{mu}_{k|k-1})^{-1}; P^{mu} symmetric
    W = Qxmu - U_bar @ Qmu
    U = U_bar + cho_solve_lower(L_mu, W.T).T
    # eqs. 35-36 (shifted one index, see module docstring)
    u_bar = (U_bar - U) @ s.mu
    Q_bar = Qx - Qxmu @ U_bar.T - U @ W.T
    # eqs. 20, 22
    x_bar_pred = pred.x_bar_prop + u_bar
    P_bar_pred = symmetrise(Phi @ s.P_bar @ Phi.T + Q_bar)
    # predicted augmented estimate, where h is linearised (module docstring)
    x_hat_pred = x_bar_pred + U @ mu_pred
    y_pred, H = meas_fn(x_hat_pred)
    nu = y - y_pred
    for i in wrap_idx:
        nu[i] = _wrap(float(nu[i]))
    S_k = H @ U  # eq. 38
    nu_bar = nu + S_k @ mu_pred  # y - H x_bar_{k|k-1}
    # eq. 23
    PHt = P_bar_pred @ H.T
    C_bar = symmetrise(H @ PHt + R)
    L_bar, ok_bar = cho_factor_lower(C_bar)
    if not ok_bar:
        return s, bad
    K_bar = cho_solve_lower(L_bar, PHt.T).T
    # eqs. 21, 24 (Joseph form)
    x_bar = x_bar_pred + K_bar @ nu_bar
    A = np.eye(P_bar_pred.shape[0]) - K_bar @ H
    P_bar = symmetrise(A @ P_bar_pred @ A.T + K_bar @ R @ K_bar.T)
    # eq. 32 (with H P_bar H^T, module docstring)
    PSt = P_mu_pred @ S_k.T
    C = symmetrise(C_bar + S_k @ PSt)
    L_c, ok_c = cho_factor_lower(C)
    if not ok_c:
        return s, bad
    K_mu = cho_solve_lower(L_c, PSt.T).T
    # eqs. 33, 34 (Joseph form with C_bar as the bias filter's measurement noise)
    mu = mu_pred + K_mu @ nu
    A_mu = np.eye(P_mu_pred.shape[0]) - K_mu @ S_k
    P_mu = symmetrise(A_mu @ P_mu_pred @ A_mu.T + K_mu @ C_bar @ K_mu.T)
    # eqs. 40-42
    V = U - K_bar @ S_k
    x_hat = x_bar + V @ mu
    P = symmetrise(P_bar + V @ P_mu @ V.T)
    diag_c = np.diag(C)
    with np.errstate(over="ignore", invalid="ignore"):
        test_ratio = nu * nu / (gate_sigma * gate_sigma * diag_c)
    # an overflowing innovation is a numerical failure too, not a huge but valid test ratio
    ok = bool(
        np.all(np.isfinite(x_hat))
        and np.all(np.isfinite(P))
        and np.all(np.isfinite(mu))
        and np.all(np.isfinite(test_ratio))
    )
    if not ok:
        return s, bad
    new = OtsekfState(x_bar=x_bar, P_bar=P_bar, mu=mu, P_mu=P_mu, V=V, x_hat=x_hat, P=P)
    innov = OtsekfInnovation(
        nu=nu, S=C, test_ratio=test_ratio, rejected=test_ratio > 1.0, numerics_ok=True
    )
    return new, innov
