"""EKF on the same discrete model, Q and R as the MHE (Wan2018 sec. VI-A comparison).

Wan2018 uses "the weighting matrices Q and R in (21) ... as the covariance matrices in the
EKF". The unknown input enters as ``x_{k+1} = F(x_k, Theta_k) + B u_k`` with ``B = t_s I``
(eq. 20), so the process noise covariance is ``B Q B^T``. ``P`` of eq. 22 is the initial
covariance. Rows of lost outputs are removed by the same mask as in the MHE (sec. V-C).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from gcs_monitor.core.types import Mat, Vec
from gcs_monitor.filters.mhe import MheModel


@dataclass(frozen=True, slots=True)
class EkfState:
    """EKF estimate and covariance."""

    x: Vec  # (n_x,)
    P: Mat  # (n_x, n_x)


@dataclass(frozen=True, slots=True)
class EkfUpdate:
    """Result of one measurement update."""

    state: EkfState
    nu: Vec  # (n_y,) innovation (0 where masked)
    numerics_ok: bool


def ekf_predict(s: EkfState, model: MheModel, theta_p: Vec, dt_s: float, q_diag: Vec) -> EkfState:
    """x_{k+1|k} = F(x_k|k, 0, Theta_k), P = A P A^T + B Q B^T (Wan2018 eq. 20)."""
    u0 = np.zeros(model.n_u)
    a = model.f_jac_x(s.x, u0, theta_p, dt_s)
    b = model.f_jac_u(s.x, u0, theta_p, dt_s)
    p = a @ s.P @ a.T + (b * q_diag) @ b.T
    return EkfState(x=model.f(s.x, u0, theta_p, dt_s), P=0.5 * (p + p.T))


def ekf_update(
    s: EkfState, model: MheModel, y: Vec, y_mask: Vec, theta_p: Vec, r_diag: Vec
) -> EkfUpdate:
    """Measurement update, Joseph form, only the rows with ``y_mask == 1``."""
    rows = np.flatnonzero(y_mask > 0)
    if rows.size == 0:
        return EkfUpdate(state=s, nu=np.zeros(model.n_y), numerics_ok=True)
    c = model.h_jac_x(s.x, theta_p)[rows]
    r = np.diag(r_diag[rows])
    nu_full = np.zeros(model.n_y)
    nu = y[rows] - model.h(s.x, theta_p)[rows]
    nu_full[rows] = nu
    s_mat = c @ s.P @ c.T + r
    try:
        cf = cho_factor(s_mat)
    except np.linalg.LinAlgError:
        return EkfUpdate(state=s, nu=nu_full, numerics_ok=False)
    k = cho_solve(cf, c @ s.P).T
    i_kc = np.eye(s.x.size) - k @ c
    p = i_kc @ s.P @ i_kc.T + k @ r @ k.T  # Joseph form
    x = s.x + k @ nu
    ok = bool(np.all(np.isfinite(x)) and np.all(np.isfinite(p)))
    return EkfUpdate(state=EkfState(x=x, P=0.5 * (p + p.T)), nu=nu_full, numerics_ok=ok)
