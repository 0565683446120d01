"""Numpy reference of the RLS kernel (``gcs_monitor/filters/_rls_jit.py``) for the equivalence
test: the equations of ``filters/rls.py``'s docstring, vectorised."""

from __future__ import annotations

import math

import numpy as np


def rls_update(theta: np.ndarray, P: np.ndarray, phi: np.ndarray, y: float, lam: float,
               trace_max: float, weight: float) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(theta', P', a priori error, s)."""
    e = y - float(phi @ theta)
    Pphi = P @ phi
    s = lam / weight + float(phi @ Pphi)
    if not (math.isfinite(e) and math.isfinite(s)) or s <= 0.0:
        return theta, P, e, s
    K = Pphi / s
    P_new = (P - np.outer(K, Pphi)) / lam
    P_new = 0.5 * (P_new + P_new.T)
    tr = float(np.trace(P_new))
    if tr > trace_max:
        P_new = P_new * (trace_max / tr)
    return theta + K * e, P_new, e, s
