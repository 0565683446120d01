"""Numba kernel of recursive least squares with forgetting (:mod:`gcs_monitor.filters.rls`):
one weighted update of ``theta`` (n,) and ``P`` (n, n) in place.

The equations are those of :func:`gcs_monitor.filters.rls.rls_step` (Ljung sec. 2.6; the
weighted cost and the trace bound in its docstring), in the same order; the numpy reference of
the equivalence test is ``tests/reference/rls.py``. Loaded through ``gcs_monitor.core.kernels``.
"""
# mypy: disable-error-code="no-untyped-def"

from __future__ import annotations

import math

import numba
import numpy as np

jit = numba.njit(cache=True, fastmath=False, nogil=True)


@jit
def update(theta, P, phi, y, lam, trace_max, weight, Pphi):
    """One RLS update in place; returns (prediction, a priori error, s). A non-finite sample
    or ``s <= 0`` leaves ``theta`` and ``P`` unchanged. ``Pphi`` (n,) is scratch space."""
    n = theta.shape[0]
    pred = 0.0
    for i in range(n):
        pred += phi[i] * theta[i]
    e = y - pred
    s = lam / weight
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += P[i, j] * phi[j]
        Pphi[i] = acc
        s += phi[i] * acc
    if not (math.isfinite(e) and math.isfinite(s)) or s <= 0.0:
        return pred, e, s
    inv_lam = 1.0 / lam
    tr = 0.0
    for i in range(n):
        k_i = Pphi[i] / s
        theta[i] += k_i * e
        for j in range(n):
            P[i, j] = (P[i, j] - k_i * Pphi[j]) * inv_lam
    for i in range(n):  # symmetric despite round-off
        for j in range(i + 1, n):
            m = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = m
            P[j, i] = m
        tr += P[i, i]
    if tr > trace_max:
        f = trace_max / tr
        for i in range(n):
            for j in range(n):
                P[i, j] *= f
    return pred, e, s


@jit
def predict(theta, phi):
    """``phi^T theta``."""
    acc = 0.0
    for i in range(theta.shape[0]):
        acc += phi[i] * theta[i]
    return acc


def warm() -> None:
    """Compile (or load from the disk cache) both signatures the callers use."""
    th = np.zeros(2)
    P = np.eye(2)
    update(th, P, np.ones(2), 1.0, 1.0, math.inf, 1.0, np.empty(2))
    predict(th, np.ones(2))
