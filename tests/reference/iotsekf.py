"""Numpy transcription of the IOTSEKF as printed (Lu2017 eqs. 14-36), with explicit inverses and
the iteration of eqs. 21-23; ``filters/_iotsekf_jit.py`` is compared with it.

``Q^{xf} = 0``; the caller gives the discretisation (``Phi``, ``Gamma``, ``Q_d``) and the
propagated bias-free state, as for the kernel.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class State:
    x_bar: np.ndarray
    P_bar: np.ndarray
    f: np.ndarray
    Pf: np.ndarray
    V: np.ndarray


def step(s: State, x_bar_prop: np.ndarray, Phi: np.ndarray, Gam: np.ndarray, Qd: np.ndarray,
         Qf: np.ndarray, H: np.ndarray, y: np.ndarray, R: np.ndarray, *, eps0: float = 1e-12,
         max_iterations: int = 20) -> tuple[State, np.ndarray, np.ndarray, np.ndarray, int]:
    """One step; returns the new state, ``x_hat``, ``P_x``, the eq. 27 innovation and the number
    of iterations of eqs. 21-23."""
    n = Phi.shape[0]
    Ubar = Phi @ s.V + Gam  # eq. 33
    Pf_pred = s.Pf + Qf  # eq. 28
    U = Ubar + (0.0 - Ubar @ Qf) @ np.linalg.inv(Pf_pred)  # eq. 35
    ubar = (Ubar - U) @ s.f  # eq. 31 (u_bar_{k-1} with the blending matrices of step k)
    Qbar = Qd - 0.0 - U @ (0.0 - Ubar @ Qf).T  # eq. 32
    x_pred = x_bar_prop + ubar  # eq. 17
    P_pred = Phi @ s.P_bar @ Phi.T + Qbar  # eq. 18
    eta1 = x_pred.copy()
    it = 0
    while True:
        it += 1
        Hk = H  # eq. 21: the Jacobian of a linear output at eta1
        K = P_pred @ Hk.T @ np.linalg.inv(Hk @ P_pred @ Hk.T + R)  # eq. 22
        eta2 = x_pred + K @ (y - Hk @ eta1 - Hk @ (x_pred - eta1))  # eq. 23
        eps = np.linalg.norm(eta2 - eta1) / np.linalg.norm(eta2)
        eta1 = eta2
        if eps <= eps0 or it >= max_iterations:
            break
    x_bar = eta2  # eq. 24
    A = np.eye(n) - K @ H
    P_bar = A @ P_pred @ A.T + K @ R @ K.T  # eq. 25
    S = H @ U  # eq. 34
    Kf = Pf_pred @ S.T @ np.linalg.inv(H @ P_pred @ H.T + R + S @ Pf_pred @ S.T)  # eq. 29
    gamma = y - H @ x_pred - S @ s.f  # eq. 27 innovation
    f = s.f + Kf @ gamma  # eq. 27
    Pf = (np.eye(len(s.f)) - Kf @ S) @ Pf_pred  # eq. 30
    V = U - K @ S  # eq. 36
    x_hat = x_bar + V @ f  # eq. 15
    Px = P_bar + V @ Pf @ V.T  # eq. 16
    return State(x_bar, P_bar, f, Pf, V), x_hat, Px, gamma, it
