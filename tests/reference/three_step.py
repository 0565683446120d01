"""Numpy transcription of the RTS-EKF measurement steps as printed (Lu2017 eqs. 40-48), with
explicit inverses; ``filters/_three_step_jit.py`` is compared with it."""

from __future__ import annotations

import numpy as np


def update(x_pred: np.ndarray, P_pred: np.ndarray, y: np.ndarray, hx: np.ndarray,
           H: np.ndarray, F: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, ...]:
    """``(x, P, f, Pf, gamma', R~)`` of one step (eqs. 40-48, ``F P^f F^T`` in eq. 47)."""
    Rt = H @ P_pred @ H.T + R  # eq. 40
    gam = y - hx  # eq. 41 (h linear: y - H x_pred)
    Ri = np.linalg.inv(Rt)
    Pf = np.linalg.inv(F.T @ Ri @ F)  # eq. 43
    N = Pf @ F.T @ Ri  # eq. 48
    f = N @ gam  # eq. 42
    K = P_pred @ H.T @ Ri  # eq. 45
    x = x_pred + K @ (gam - F @ f)  # eq. 46
    P = P_pred - K @ (Rt - F @ Pf @ F.T) @ K.T  # eq. 47
    return x, P, f, Pf, gam, Rt
