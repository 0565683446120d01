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
a non-finite sample. :func:`rls_step` returns a new immutable state; :class:`RlsFilter`
updates its arrays in place (a monitor's per-sample path). Both run the one implementation,
the numba kernel ``filters/_rls_jit.py``; its numpy reference is ``tests/reference/rls.py``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import ModuleType

import numpy as np

from gcs_monitor.core.kernels import load_kernels
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
    """One RLS update with forgetting factor ``lam`` in (0, 1] (module docstring), on a copy
    of ``state``: the kernel ``filters/_rls_jit.update`` (the one implementation).

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
    _check(lam, weight)
    theta, P = state.theta.copy(), state.P.copy()
    pred, e, s = _kernel().update(theta, P, np.asarray(phi, dtype=np.float64), float(y), lam,
                                  trace_max, weight, np.empty(len(theta)))
    if not (math.isfinite(e) and math.isfinite(s)) or s <= 0.0:
        return state, RlsUpdate(pred, e, s)
    return RlsState(theta, P), RlsUpdate(pred, e, s)


class RlsFilter:
    """The same update on a mutable estimate (the per-sample path of a monitor: no copies).

    ``theta`` (n,) and ``P`` (n, n) are updated in place by :meth:`update`; :meth:`state`
    gives a frozen snapshot."""

    __slots__ = ("theta", "P", "_scratch", "_k")

    def __init__(self, n: int, p0: float) -> None:
        self.theta = np.zeros(n)
        self.P = np.eye(n) * p0
        self._scratch = np.empty(n)
        self._k = _kernel()

    def predict(self, phi: Vec) -> float:
        return float(self._k.predict(self.theta, phi))

    def update(self, phi: Vec, y: float, lam: float, *, trace_max: float = math.inf,
               weight: float = 1.0) -> RlsUpdate:
        """:func:`rls_step` in place."""
        _check(lam, weight)
        pred, e, s = self._k.update(self.theta, self.P, phi, y, lam, trace_max, weight,
                                    self._scratch)
        return RlsUpdate(pred, e, s)

    def state(self) -> RlsState:
        return RlsState(self.theta.copy(), self.P.copy())


def _check(lam: float, weight: float) -> None:
    if not 0.0 < lam <= 1.0:
        raise ValueError(f"forgetting factor must be in (0, 1], got {lam}")
    if not 0.0 < weight <= 1.0:
        raise ValueError(f"weight must be in (0, 1], got {weight}")


def _kernel() -> ModuleType:
    return load_kernels("gcs_monitor.filters._rls_jit")


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
