"""Robust three-step EKF (RTS-EKF) for output faults, Lu2017 sec. V.B (eqs. 37-48).

The filter estimates a state x and an output fault ``f^o`` entering the measurement through
``y = h(x) + F f^o + v`` with no model of the fault's dynamics (Gillijns & De Moor 2007, Lu2017
ref. 19): a time update (eqs. 38-39), the fault as the unbiased minimum-variance estimate from
the innovation (eqs. 40-43, 48), and the measurement update of the state with the fault removed
(eqs. 44-47). It exists when ``m >= p`` and ``rank F = p`` (eq. 37). Model-agnostic: the caller
propagates the state (eq. 38) and supplies the transition and discrete process noise.

Choices where the printed text is ambiguous (docs/papers-notes.md, Lu2017):

1. Eq. 38 integrates ``f(x, u, f^i)``: the RTS-EKF models no input fault, so ``f^i = 0``.
2. Eq. 47 prints ``F P^f F``; the dimensions need ``F P^f F^T``.
3. With ``m = p`` (Lu2017's case, ``m = p = 1``, ``F = I``) ``N = F^{-1}``, the gain multiplies
   ``gamma' - F N gamma' = 0`` and ``R~ - F P^f F^T = 0``: the measurement update does nothing.
   The state estimate is the model's open-loop prediction and the fault estimate the whole
   innovation; the state is "unbiased" only because the model is exact and stable (for the
   servo: the NDI loop is). A state correction needs ``m > p``.

The step runs in the numba kernel ``filters/_three_step_jit.py``; the numpy transcription of
the printed equations is ``tests/reference/three_step.py``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gcs_monitor.core.kernels import load_kernels
from gcs_monitor.core.types import Mat, Vec
from gcs_monitor.filters.ekf import Innovation

_KERNEL = "gcs_monitor.filters._three_step_jit"


@dataclass(frozen=True, slots=True)
class ThreeStepState:
    """RTS-EKF state after step k.

    Attributes
    ----------
    x, P : (n,), (n, n) state estimate and its error covariance (eqs. 46-47)
    f, Pf : (p,), (p, p) output-fault estimate and its error covariance (eqs. 42-43)
    """

    x: Vec
    P: Mat
    f: Vec
    Pf: Mat


def three_step_init(x0: Vec, P0: Mat, p: int) -> ThreeStepState:
    """Initial state, no fault estimate yet (zero fault, zero covariance)."""
    return ThreeStepState(np.array(x0, dtype=np.float64), np.array(P0, dtype=np.float64),
                          np.zeros(p), np.zeros((p, p)))


def three_step_predict(P: Mat, Phi: Mat, Qd: Mat) -> Mat:
    """``P_{k|k-1} = Phi P Phi^T + Q_d`` (eq. 39); the state itself is the model's (eq. 38)."""
    out = np.empty(P.shape)
    load_kernels(_KERNEL).predict_covariance(P, Phi, Qd, out)
    return out


def three_step_update(x_pred: Vec, P_pred: Mat, y: Vec, hx: Vec, H: Mat, F: Mat, R: Mat, *,
                      gate_sigma: float = 3.0) -> tuple[ThreeStepState | None, Innovation]:
    """Fault estimation and measurement update (eqs. 40-48).

    Parameters
    ----------
    x_pred, P_pred : (n,), (n, n) the time update (eqs. 38-39)
    y : (m,) measurement
    hx, H : (m,), (m, n) ``h(x_pred)`` and its Jacobian (eq. 44)
    F : (m, p) output-fault distribution (eq. 37: ``m >= p``, ``rank F = p``)
    R : (m, m) measurement noise covariance

    Returns
    -------
    The state at k (None on a numerical failure) and the innovation ``gamma' = y - h(x_pred)``
    (eq. 41) with ``R~`` (eq. 40) as its covariance.
    """
    n, m, p = x_pred.size, y.size, F.shape[1]
    if F.shape[0] != m or p > m:
        raise ValueError(f"F must be (m, p) with p <= m = {m}, got {F.shape} (Lu2017 eq. 37)")
    x = np.empty(n)
    P = np.empty((n, n))
    f = np.empty(p)
    Pf = np.empty((p, p))
    nu = np.empty(m)
    sd = np.empty(m)
    ratio = np.empty(m)
    ok = load_kernels(_KERNEL).update(
        np.asarray(x_pred, dtype=np.float64), np.asarray(P_pred, dtype=np.float64),
        np.asarray(hx, dtype=np.float64), np.asarray(H, dtype=np.float64),
        np.asarray(F, dtype=np.float64), np.asarray(y, dtype=np.float64),
        np.asarray(R, dtype=np.float64), float(gate_sigma), x, P, f, Pf, nu, sd, ratio)
    innov = Innovation(nu=nu, S_diag=sd, test_ratio=ratio, numerics_ok=bool(ok))
    return (ThreeStepState(x, P, f, Pf) if ok else None), innov
