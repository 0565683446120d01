"""Plain (extended) Kalman filter steps and the innovation record shared by all filters.

Model-agnostic: the caller passes the propagated state, the transition matrix and the
discrete process noise (prediction) and the predicted output and its Jacobian (update).
Used for comparison with the two-stage filter (an EKF on the 6-state GS-KM that ignores the
faults, or the augmented-state EKF with the faults as extra states).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gcs_monitor.core.types import Mat, Vec
from gcs_monitor.filters.covariance import all_finite, gain, joseph_update, symmetrise


@dataclass(frozen=True, slots=True)
class Innovation:
    """What one measurement update saw.

    Attributes
    ----------
    nu : (m,) innovation y - h(x_pred), measurement units
    S_diag : (m,) diagonal of the innovation covariance
    test_ratio : (m,) nu_i^2 / (gate^2 S_ii); > 1 means outside the gate
    numerics_ok : False if S was not positive definite or anything became non-finite
    """

    nu: Vec
    S_diag: Vec
    test_ratio: Vec
    numerics_ok: bool


def make_innovation(nu: Vec, S: Mat, gate_sigma: float, ok: bool) -> Innovation:
    """Build an :class:`Innovation`; ``ok`` is combined with finiteness and S_ii > 0 checks."""
    s_diag = S.diagonal().copy()
    good = bool(ok and all_finite(nu) and all_finite(s_diag) and s_diag.min() > 0.0)
    if good:
        ratio = nu * nu / (gate_sigma * gate_sigma * s_diag)
    else:
        ratio = np.full(nu.shape, np.nan)
    return Innovation(nu=nu, S_diag=s_diag, test_ratio=ratio, numerics_ok=good)


@dataclass(frozen=True, slots=True)
class EkfState:
    """EKF estimate and covariance.

    Attributes
    ----------
    x : (n,) state estimate
    P : (n, n) its covariance
    """

    x: Vec
    P: Mat


def ekf_predict(s: EkfState, x_pred: Vec, Phi: Mat, Qd: Mat) -> EkfState:
    """Time update ``P = Phi P Phi^T + Qd`` with the state already propagated by the model.

    Parameters
    ----------
    x_pred : (n,) model-propagated state
    Phi : (n, n) transition matrix
    Qd : (n, n) discrete process noise covariance
    """
    return EkfState(x=x_pred, P=symmetrise(Phi @ s.P @ Phi.T + Qd))


def ekf_update(
    s: EkfState, y: Vec, y_pred: Vec, H: Mat, R: Mat, *, gate_sigma: float
) -> tuple[EkfState, Innovation]:
    """Measurement update with a Cholesky gain and the Joseph form.

    Parameters
    ----------
    y : (m,) measurement
    y_pred : (m,) h(x_pred)
    H : (m, n) output Jacobian at x_pred
    R : (m, m) measurement noise covariance
    gate_sigma : gate for the normalised test ratio
    """
    nu = y - y_pred
    PHt = s.P @ H.T
    S = H @ PHt + R
    K, ok = gain(PHt, S)
    innov = make_innovation(nu, S, gate_sigma, ok)
    if not innov.numerics_ok:
        return s, innov
    return EkfState(x=s.x + K @ nu, P=joseph_update(s.P, K, H, R)), innov
