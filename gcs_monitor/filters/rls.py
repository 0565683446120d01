"""Recursive least squares with exponential forgetting and a bounded covariance.

Identifies ``theta`` in the linear regression ``y_k = phi_k^T theta + e_k`` online (Ljung and
Soderstrom, "Theory and Practice of Recursive Identification", 1983, sec. 2.6; used for aircraft
anomaly detection by Keipour, Mousaei and Scherer, ICRA 2019). Per sample, with forgetting
factor ``lambda`` (memory ``1 / (1 - lambda)`` samples)::

    e      = y - phi^T theta                 a priori prediction error
    s      = lambda + phi^T P phi
    K      = P phi / s
    theta' = theta + K e
    P'     = (P - K phi^T P) / lambda

Without excitation the division by ``lambda`` makes ``P`` grow without bound (estimator
wind-up: the next excitation then throws ``theta`` about); ``P'`` is scaled down whenever its
trace exceeds ``trace_max`` (a constant-trace bound, Ljung sec. 5.6). The update is skipped for
a non-finite sample; the state is immutable, a step returns a new one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gcs_monitor.core.types import Mat, Vec


@dataclass(frozen=True, slots=True)
class RlsState:
    """Parameter estimate ``theta`` (n,) and its (scaled) covariance ``P`` (n, n)."""

    theta: Vec
    P: Mat

    @staticmethod
    def initial(n: int, p0: float, theta0: Vec | None = None) -> RlsState:
        """``theta = theta0`` (zeros by default) with ``P = p0 I``."""
        th = np.zeros(n) if theta0 is None else np.asarray(theta0, dtype=np.float64).copy()
        if th.shape != (n,):
            raise ValueError(f"theta0 must have shape ({n},), got {th.shape}")
        return RlsState(th, np.eye(n) * p0)


@dataclass(frozen=True, slots=True)
class RlsUpdate:
    """What one sample did: the a priori prediction and its error, and the gain denominator
    ``s`` (``e^2 / (sigma^2 s)`` is the normalised innovation when the noise variance is
    ``sigma^2``)."""

    prediction: float
    error: float
    s: float


def rls_predict(state: RlsState, phi: Vec) -> float:
    """``phi^T theta``: the model's prediction of ``y`` for regressor ``phi`` (n,)."""
    return float(phi @ state.theta)


def rls_step(state: RlsState, phi: Vec, y: float, lam: float, *,
             trace_max: float = math.inf, weight: float = 1.0) -> tuple[RlsState, RlsUpdate]:
    """One RLS update with forgetting factor ``lam`` in (0, 1] (module docstring).

    Parameters
    ----------
    state : current estimate
    phi : (n,) regressor
    y : measured output
    lam : forgetting factor (1 = ordinary recursive least squares)
    trace_max : upper bound on ``trace(P)`` after the update
    weight : the sample's weight ``w`` in (0, 1] in the weighted cost ``sum lambda^(N-k) w_k
        e_k^2`` (a robust M-estimator's weight, e.g. Huber's ``min(1, c / |e / sigma|)``):
        ``s = lambda / w + phi^T P phi``
    """
    if not 0.0 < lam <= 1.0:
        raise ValueError(f"forgetting factor must be in (0, 1], got {lam}")
    if not 0.0 < weight <= 1.0:
        raise ValueError(f"weight must be in (0, 1], got {weight}")
    theta, P = state.theta, state.P
    pred = float(phi @ theta)
    e = y - pred
    Pphi = P @ phi
    s = lam / weight + float(phi @ Pphi)
    if not (math.isfinite(e) and math.isfinite(s)) or s <= 0.0:
        return state, RlsUpdate(pred, e, s)
    K = Pphi / s
    P_new = (P - np.outer(K, Pphi)) / lam
    P_new = 0.5 * (P_new + P_new.T)  # symmetric despite round-off
    tr = float(np.trace(P_new))
    if tr > trace_max:
        P_new *= trace_max / tr
    return RlsState(theta + K * e, P_new), RlsUpdate(pred, e, s)


def huber_weight(normalised_error: float, c: float) -> float:
    """Huber's weight ``min(1, c / |r|)`` of a residual ``r`` in units of its scale (1 for a
    non-finite one is never asked: callers skip those samples)."""
    a = abs(normalised_error)
    return 1.0 if a <= c else c / a


def forgetting_factor(memory_s: float, period_s: float) -> float:
    """``lambda = exp(-period_s / memory_s)``: a sample ``memory_s`` old weighs ``1/e`` (the
    memory ``1 / (1 - lambda)`` is ``memory_s / period_s`` samples when that is large)."""
    if memory_s <= 0.0 or period_s <= 0.0:
        raise ValueError(f"memory and period must be > 0, got {memory_s}, {period_s}")
    return math.exp(-period_s / memory_s)
