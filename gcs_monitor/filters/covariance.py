"""Covariance hygiene shared by every filter: Joseph update, symmetrisation, Cholesky solves.

All linear solves go through a Cholesky factorisation (LAPACK ``potrf``/``potrs``, what
``scipy.linalg.cho_factor``/``cho_solve`` call, without their per-call argument checks, which
cost more than the 6x6 factorisation itself). A failed factorisation is reported, not raised.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from scipy.linalg.lapack import dgesv, dpotrf, dpotrs

from gcs_monitor.core.types import Mat, Vec


@lru_cache(maxsize=16)
def eye(n: int) -> Mat:
    """Read-only identity, cached (np.eye costs more than a 6x6 product)."""
    a = np.eye(n)
    a.setflags(write=False)
    return a


def all_finite(a: Vec | Mat) -> bool:
    """True if every element is finite (a sum is NaN/inf iff some element is)."""
    return math.isfinite(float(a.sum()))


def symmetrise(P: Mat) -> Mat:
    """``(P + P^T) / 2``."""
    return (P + P.T) * 0.5


def cho_factor_lower(S: Mat) -> tuple[Mat, bool]:
    """Lower Cholesky factor of a symmetric matrix; ``ok`` is False if S is not PD or not finite."""
    L, info = dpotrf(S, lower=1, clean=0, overwrite_a=0)
    return L, bool(info == 0)


def cho_solve_lower(L: Mat, B: Mat) -> Mat:
    """Solve ``S X = B`` given the factor from :func:`cho_factor_lower`."""
    X, _info = dpotrs(L, B, lower=1, overwrite_b=0)
    return np.asarray(X, dtype=np.float64)


def gain(PHt: Mat, S: Mat) -> tuple[Mat, bool]:
    """Kalman-type gain ``K = P H^T S^{-1}`` by a Cholesky solve (S symmetric PD).

    Parameters
    ----------
    PHt : (n, m) cross covariance ``P H^T``
    S : (m, m) innovation covariance
    """
    L, ok = cho_factor_lower(S)
    if not ok:
        return np.zeros_like(PHt), False
    # K^T = S^{-1} (P H^T)^T, S symmetric
    return cho_solve_lower(L, PHt.T).T, True


def solve_general(A: Mat, B: Mat) -> tuple[Mat, bool]:
    """Solve ``A X = B`` for a general square A by LU (LAPACK ``gesv``); ok False if singular."""
    _lu, _piv, X, info = dgesv(A, B, overwrite_a=0, overwrite_b=0)
    return X, bool(info == 0)


def joseph_update(P: Mat, K: Mat, H: Mat, R: Mat) -> Mat:
    """Joseph-form covariance update, symmetrised.

    ``P+ = (I - K H) P (I - K H)^T + K R K^T`` (Lu2016 eq. 39). Stays PSD for any gain.
    """
    A = eye(P.shape[0]) - K @ H
    return symmetrise(A @ P @ A.T + K @ R @ K.T)


def is_psd(P: Mat, *, tol: float = 0.0) -> bool:
    """True if ``P`` is symmetric (to round-off) with eigenvalues >= -tol."""
    if not np.all(np.isfinite(P)):
        return False
    scale = max(1.0, float(np.max(np.abs(P))))
    if not np.allclose(P, P.T, rtol=0.0, atol=1e-12 * scale):
        return False
    return bool(np.min(np.linalg.eigvalsh(symmetrise(P))) >= -tol)
