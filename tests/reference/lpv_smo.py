"""Numpy reference of the LPV sliding-mode observer kernel (Chen2020 eqs. 3, 6, 7, 21;
``filters/_lpv_smo_jit.py``)."""

from __future__ import annotations

import math

import numpy as np

from gcs_monitor.core.types import Vec
from gcs_monitor.filters.lpv_smo import SmoMatrices, SmoOutput, SmoState


def smo_step_reference(s: SmoState, mats: SmoMatrices, y_p: Vec, u: Vec, rho: tuple[float, float],
             dt_s: float) -> tuple[SmoState, SmoOutput]:
    """``lpv_smo.smo_step`` in numpy: one explicit-Euler step of eqs. 3, 6, 7 and 21.

    Parameters
    ----------
    s : state at t_k
    y_p : (n,) measured outputs at t_k, original order
    u : (m,) inputs at t_k
    rho : scheduling parameter at t_k
    dt_s : step to t_{k+1}

    Returns
    -------
    the state at t_{k+1} and the outputs at t_k
    """
    n, q = mats.n, mats.q
    y = np.asarray(y_p, dtype=np.float64)[list(mats.perm)]
    yo = np.concatenate([y[q:], s.z_f])  # y = [y_p1; z_f]
    e_y = s.z[q:] - yo
    ne = math.sqrt(float(e_y @ e_y))
    nu = (-mats.k / (ne + mats.delta)) * e_y  # eq. 7, sigmoid smoothing (sec. V)
    f_hat = mats.A_f_inv @ nu[n - q:]  # eq. 21, W = [0 A_f^-1]
    W = mats.W[0] + rho[0] * mats.W[1] + rho[1] * mats.W[2]
    drift = W @ np.concatenate([s.z, np.asarray(u, dtype=np.float64), yo, [1.0]])
    z_next = s.z + dt_s * (drift + mats.Gn @ nu)
    zf_next = s.z_f + dt_s * (mats.A_f @ (y[:q] - s.z_f))  # eq. 3
    x_hat = np.empty(n)
    x_hat[list(mats.perm)] = s.z[:n]
    return SmoState(z_next, zf_next), SmoOutput(f_hat, x_hat, e_y, nu)
