"""Numpy reference of the Atmaca2025 estimator's model quantities (the numba model kernel,
``gcs_monitor.models._kinematics_body_jit``, runs in the estimator).

Patched into an :class:`~gcs_monitor.families.imu.imu_hosm.ImuHosmEstimator` by :func:`use_numpy`;
``tests/gcs_monitor/families/imu/test_imu_hosm.py`` compares the two estimators step by step.
"""

from __future__ import annotations

import types

import numpy as np

from gcs_monitor.core.types import Mat, Vec
from gcs_monitor.families.imu.imu_hosm import ImuHosmEstimator, _Step
from gcs_monitor.filters.otsekf import OtsekfPrediction, OtsekfState
from gcs_monitor.models.kinematics_body import (
    body_gs_derivative,
    body_gs_jac_x,
    body_gs_meas_jac,
    body_gs_measurement,
    body_gs_noise_matrix,
    fault_from_drift_rate,
)


def rk2(x: Vec, u_m: Vec, f_hat: Vec, g: float, dt: float) -> Vec:
    """Midpoint integration of eqs. 9-14 over one step, inputs held (eq. 20's integral)."""
    k1 = body_gs_derivative(x, u_m, f_hat, g)
    k2 = body_gs_derivative(x + 0.5 * dt * k1, u_m, f_hat, g)
    return x + dt * k2


def prediction(est: ImuHosmEstimator, s: OtsekfState, st: _Step) -> OtsekfPrediction:
    """Model quantities for k-1 -> k (Atmaca2025 eqs. 20, 25-27) in numpy."""
    dt, g, u_m, fh = st.dt_s, st.g_mps2, st.u_m, est._f_model()
    eye = np.eye(s.x_hat.size)
    x_lin = s.x_hat  # eq. 26: linearise at x_hat_{k-1|k-1}
    F = body_gs_jac_x(x_lin, u_m, fh, g)
    Fdt = F * dt
    # eq. 25, series truncated after the second-order term (|F dt| ~ 1e-3 at 100 Hz)
    Phi = eye + Fdt + 0.5 * (Fdt @ Fdt)
    # eq. 27 over one step with G held: int_0^dt e^{F s} ds G = (I + F dt / 2) G dt
    Gam = (eye + 0.5 * Fdt) @ body_gs_noise_matrix(x_lin) * dt
    Qmu = np.diag(est._drift_var_rate * dt)
    Qx = Gam @ est._Q_imu @ Gam.T + Qmu
    Qxmu = -Qmu
    if est.cfg.propagate == "corrected":
        # eq. 20 evaluated along the drift-corrected trajectory: f_d(x_hat) - Phi V mu
        x_bar_prop = rk2(s.x_hat, u_m, fh, g, dt) - Phi @ (s.V @ s.mu)
        B = np.zeros_like(eye)
    else:
        x_bar_prop = rk2(s.x_bar, u_m, fh, g, dt)
        B = Phi - eye
    return OtsekfPrediction(x_bar_prop=x_bar_prop, Phi=Phi, B=B, Qx=Qx, Qxmu=Qxmu, Qmu=Qmu)


def measurement(x: Vec) -> tuple[Vec, Mat]:
    """h(x) and its Jacobian (eq. 15) in numpy."""
    return body_gs_measurement(x), body_gs_meas_jac(x)


def use_numpy(est: ImuHosmEstimator) -> ImuHosmEstimator:
    """``est`` with its model quantities, measurement and fault increment in numpy."""

    def fault_increment(self: ImuHosmEstimator, x_prev: Vec, mu: Vec, mu_prev: Vec) -> None:
        self._f_int = self._f_int + fault_from_drift_rate(mu - mu_prev, x_prev)

    est._prediction = types.MethodType(prediction, est)  # type: ignore[method-assign]
    est._measurement = measurement  # type: ignore[method-assign]
    est._fault_increment = types.MethodType(fault_increment, est)  # type: ignore[method-assign]
    return est
