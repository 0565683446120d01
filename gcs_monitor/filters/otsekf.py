"""Optimal two-stage extended Kalman filter (OTSEKF), Atmaca2025 eqs. 20-42.

The structure is Hsieh & Chen (1999) as used by Lu2015 and Atmaca2025: a bias-free ("modified
fault-neglecting") filter for ``x_bar`` (eqs. 20-24), a bias ("fault-inclusive drift") filter for
``mu`` (eqs. 30-34), coupled by the blending matrices ``U_bar, U, V`` (eqs. 35-40), and the
recombination ``x_hat = x_bar + V mu`` (eqs. 41-42). It is the optimal decomposition of the
augmented-state filter for

    x_k = Phi_{k-1} x_{k-1} + B_{k-1} mu_{k-1} + w^x,   mu_k = mu_{k-1} + w^mu,   y_k = H_k x_k + v,

with ``E[w^x w^x'] = Qx``, ``E[w^x w^mu'] = Qxmu`` (the paper's ``Q^{x mu}`` of eqs. 36/39),
``E[w^mu w^mu'] = Qmu``. Atmaca2025 eq. 37 writes ``Gamma_{k-1}`` for ``B``; what ``B`` and the
noise blocks are for the IMU drift model is decided by the estimator (see ``imu_hosm.py``).

Notation problems in Atmaca2025 and what this module does (also in docs/papers-notes.md):

* eq. 32 prints ``H P^{mu}_{k|k-1} H^T`` in the gain denominator; the dimensionally and
  Hsieh-Chen-correct term is ``H P^{x_bar}_{k|k-1} H^T`` (the bias-free innovation covariance).
* eq. 39 prints ``Q^{x mu}_{k+1}`` next to ``Q^{mu}_{k-1}``; Hsieh-Chen has both at ``k-1`` (the
  noise of the step that produced the prediction). We use ``k-1`` for both. With the constant noise
  blocks used here the index makes no numerical difference.
* eqs. 35-36 are written at index ``k`` with ``U_{k+1}``; we apply them once per step as
  ``u_bar_{k-1} = (U_bar_k - U_k) mu_{k-1|k-1}`` and ``Q_bar_{k-1}`` from ``U_bar_k, U_k``, which is
  the same recursion shifted by one index.
* eq. 26 linearises ``H_k`` at ``x_hat_{k-1|k-1}``; we linearise ``h`` at the predicted augmented
  estimate ``x_hat_{k|k-1} = x_bar_{k|k-1} + U_k mu_{k|k-1}`` (the standard EKF choice; the two
  differ by one sample of motion). For a nonlinear ``h`` the innovations of eqs. 21 and 33 are
  formed from ``nu = y - h(x_hat_{k|k-1})``: ``y - H x_bar = nu + S mu`` (eq. 21) and
  ``y - H x_bar - S mu = nu`` (eq. 33), which are the printed linear forms exactly when ``h`` is
  linear.
* eq. 42 writes ``P^{r}`` and ``P^{r_bar}``; these are ``P^{x}`` and ``P^{x_bar}``.
* eq. 28 writes ``E{w' w}`` (a scalar); the covariance ``E{w w'}`` is meant.
* eq. 24 is the short-form update; we use the Joseph form (equal for the optimal gain, stays PSD
  under round-off), likewise for eq. 34 with the bias-free innovation covariance as its "R".

The step runs in the numba kernels of ``filters/_otsekf_jit.py``; the numpy reference that the
equivalence test compares them with is ``tests/reference/otsekf.py``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from gcs_monitor.core.kernels import load_kernels
from gcs_monitor.core.types import Mat, Vec

MeasFn = Callable[[Vec], tuple[Vec, Mat]]


@dataclass(frozen=True, slots=True)
class OtsekfState:
    """Two-stage filter state after the update of step k.

    Attributes
    ----------
    x_bar : (n,) bias-free state estimate x_bar_{k|k} (eq. 21)
    P_bar : (n, n) its covariance (eq. 24)
    mu : (b,) bias / drift estimate mu_{k|k} (eq. 33)
    P_mu : (b, b) its covariance (eq. 34)
    V : (n, b) blending matrix V_k (eq. 40)
    x_hat : (n,) recombined estimate x_bar + V mu (eq. 41)
    P : (n, n) its covariance (eq. 42)
    """

    x_bar: Vec
    P_bar: Mat
    mu: Vec
    P_mu: Mat
    V: Mat
    x_hat: Vec
    P: Mat


@dataclass(frozen=True, slots=True)
class OtsekfPrediction:
    """What the model supplies for the prediction from k-1 to k.

    Attributes
    ----------
    x_bar_prop : (n,) ``x_bar_{k-1|k-1} + int f dt`` (eq. 20 without the coupling term u_bar)
    Phi : (n, n) transition matrix Phi_{k-1} (eq. 25)
    B : (n, b) bias-to-state matrix (Gamma_{k-1} of eq. 37)
    Qx : (n, n) state process-noise covariance (Gamma Q Gamma^T of eq. 36)
    Qxmu : (n, b) state/bias noise cross covariance (Q^{x mu} of eqs. 36, 39)
    Qmu : (b, b) bias noise covariance (Q^{mu} of eq. 31)
    """

    x_bar_prop: Vec
    Phi: Mat
    B: Mat
    Qx: Mat
    Qxmu: Mat
    Qmu: Mat


@dataclass(frozen=True, slots=True)
class OtsekfInnovation:
    """Innovation record of one update.

    Attributes
    ----------
    nu : (m,) innovation y - h(x_hat_{k|k-1})
    S : (m, m) its covariance H P_bar H^T + R + S_k P_mu S_k^T (denominator of eq. 32)
    test_ratio : (m,) nu_i^2 / (gate_sigma^2 S_ii); > 1 means outside the gate
    rejected : (m,) test_ratio > 1 (reported only; the filter does not drop measurements)
    numerics_ok : False if a covariance was not PD or a value was not finite
    """

    nu: Vec
    S: Mat
    test_ratio: Vec
    rejected: NDArray[np.bool_]
    numerics_ok: bool


def otsekf_init(x0: Vec, P0: Mat, mu0: Vec, P_mu0: Mat) -> OtsekfState:
    """Initial two-stage state with ``V_0 = 0`` (x_bar_0 = x_hat_0, Hsieh-Chen initialisation)."""
    n, b = x0.shape[0], mu0.shape[0]
    V0 = np.zeros((n, b))
    return OtsekfState(
        x_bar=x0.copy(),
        P_bar=P0.copy(),
        mu=mu0.copy(),
        P_mu=P_mu0.copy(),
        V=V0,
        x_hat=x0.copy(),
        P=P0.copy(),
    )


def otsekf_step(
    s: OtsekfState,
    pred: OtsekfPrediction,
    meas_fn: MeasFn,
    y: Vec,
    R: Mat,
    *,
    gate_sigma: float,
    wrap_idx: tuple[int, ...] = (),
) -> tuple[OtsekfState, OtsekfInnovation]:
    """One predict/update of the optimal two-stage EKF (Atmaca2025 eqs. 20-42).

    Parameters
    ----------
    s : state after step k-1
    pred : model quantities for k-1 -> k (see :class:`OtsekfPrediction`)
    meas_fn : ``x -> (h(x), H(x))``, measurement model and Jacobian (eqs. 16-19, 26)
    y : (m,) measurement y_{m,k}
    R : (m, m) measurement noise covariance (eq. 28)
    gate_sigma : innovation gate in standard deviations (for the test ratio only)
    wrap_idx : innovation components that are angles and are wrapped to (-pi, pi]

    Returns
    -------
    new state and the innovation record. On a numerical failure the returned state is the input
    state (unchanged) and ``numerics_ok`` is False; the caller decides to reset.
    """
    kern = load_kernels("gcs_monitor.filters._otsekf_jit")
    n, b, m = s.x_bar.shape[0], s.mu.shape[0], y.shape[0]
    U = np.empty((n, b))
    x_bar_pred = np.empty(n)
    P_bar_pred = np.empty((n, n))
    P_mu_pred = np.empty((b, b))
    x_hat_pred = np.empty(n)
    if not kern.predict(
        pred.x_bar_prop, pred.Phi, pred.B, pred.Qx, pred.Qxmu, pred.Qmu,
        s.V, s.P_bar, s.mu, s.P_mu,
        U, x_bar_pred, P_bar_pred, P_mu_pred, x_hat_pred,
    ):  # fmt: skip
        return s, _bad_innovation(m)
    y_pred, H = meas_fn(x_hat_pred)
    wrap = _wrap_mask(m, wrap_idx)
    x_bar, x_hat, mu = np.empty(n), np.empty(n), np.empty(b)
    P_bar, P = np.empty((n, n)), np.empty((n, n))
    P_mu, V = np.empty((b, b)), np.empty((n, b))
    nu, C, ratio = np.empty(m), np.empty((m, m)), np.empty(m)
    if not kern.update(
        y, y_pred, H, R, wrap, gate_sigma,
        x_bar_pred, P_bar_pred, U, s.mu, P_mu_pred,
        x_bar, P_bar, mu, P_mu, V, x_hat, P, nu, C, ratio,
    ):  # fmt: skip
        return s, _bad_innovation(m)
    new = OtsekfState(x_bar=x_bar, P_bar=P_bar, mu=mu, P_mu=P_mu, V=V, x_hat=x_hat, P=P)
    innov = OtsekfInnovation(nu=nu, S=C, test_ratio=ratio, rejected=ratio > 1.0, numerics_ok=True)
    return new, innov


def _bad_innovation(m: int) -> OtsekfInnovation:
    return OtsekfInnovation(
        nu=np.full(m, np.nan),
        S=np.full((m, m), np.nan),
        test_ratio=np.full(m, np.nan),
        rejected=np.zeros(m, dtype=bool),
        numerics_ok=False,
    )


_WRAP_MASKS: dict[tuple[int, tuple[int, ...]], NDArray[np.bool_]] = {}


def _wrap_mask(m: int, wrap_idx: tuple[int, ...]) -> NDArray[np.bool_]:
    """(m,) True at the wrapped components; built once per (m, wrap_idx), never written to."""
    key = (m, wrap_idx)
    mask = _WRAP_MASKS.get(key)
    if mask is None:
        mask = np.zeros(m, dtype=np.bool_)
        for i in wrap_idx:
            mask[i] = True
        _WRAP_MASKS[key] = mask
    return mask
