"""Atmaca2025 body-frame GS model: Jacobians vs central differences, truth consistency."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_monitor.core.frames import dcm_ned_frd
from gcs_monitor.models.kinematics_body import (
    body_gs_derivative,
    body_gs_jac_x,
    body_gs_meas_jac,
    body_gs_measurement,
    body_gs_noise_matrix,
    compiled_kernels,
    drift_rate_to_fault,
    own_drift_gain,
)
from tests.helpers.imu_synth_body import truth_at

G = 9.81


def _random_case(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    x = np.concatenate([rng.uniform(-60, 60, 3), rng.uniform(-1.0, 1.0, 2), rng.uniform(-3, 3, 1)])
    u_m = np.concatenate([rng.uniform(-5, 5, 3), rng.uniform(-0.5, 0.5, 3)])
    f_hat = np.concatenate([rng.uniform(-1, 1, 3), rng.uniform(-0.05, 0.05, 3)])
    return x, u_m, f_hat


def _fd(fun, x: np.ndarray, h: float = 1e-6) -> np.ndarray:
    cols = []
    for i in range(x.shape[0]):
        e = np.zeros_like(x)
        e[i] = h
        cols.append((fun(x + e) - fun(x - e)) / (2 * h))
    return np.stack(cols, axis=1)


def test_state_jacobian_matches_central_differences() -> None:
    rng = np.random.default_rng(4)
    for _ in range(20):
        x, u_m, fh = _random_case(rng)
        F = body_gs_jac_x(x, u_m, fh, G)
        F_fd = _fd(lambda xx, u_m=u_m, fh=fh: body_gs_derivative(xx, u_m, fh, G), x)
        # atol: central differences, h = 1e-6 on values up to ~60 -> truncation ~1e-8
        np.testing.assert_allclose(F, F_fd, atol=1e-6)


def test_noise_matrix_is_minus_input_jacobian() -> None:
    """Eq. 15 (with the row-1 typo corrected) must equal -df/du_m."""
    rng = np.random.default_rng(5)
    for _ in range(20):
        x, u_m, fh = _random_case(rng)
        G_fd = -_fd(lambda uu, x=x, fh=fh: body_gs_derivative(x, uu, fh, G), u_m)
        np.testing.assert_allclose(body_gs_noise_matrix(x), G_fd, atol=1e-6)


def test_measurement_jacobian_and_dcm() -> None:
    rng = np.random.default_rng(6)
    for _ in range(20):
        x, _, _ = _random_case(rng)
        h = body_gs_measurement(x)
        np.testing.assert_allclose(h[:3], dcm_ned_frd(*x[3:]) @ x[:3], atol=1e-12)
        np.testing.assert_allclose(h[3:], x[3:], atol=0)
        np.testing.assert_allclose(body_gs_meas_jac(x), _fd(body_gs_measurement, x), atol=1e-6)


def test_hand_values_level_flight() -> None:
    """Level, wings-level, no rates: u' = A_x, w' = A_z + g, attitude rates are the gyro rates."""
    x = np.array([50.0, 0.0, 2.0, 0.0, 0.0, 0.3])
    u_m = np.array([0.5, 0.0, -G, 0.01, 0.0, 0.0])
    d = body_gs_derivative(x, u_m, np.zeros(6), G)
    np.testing.assert_allclose(d, [0.5, 2.0 * 0.01, 0.0, 0.01, 0.0, 0.0], atol=1e-12)


def test_own_terms_keep_fault_and_cross_terms_remove_it() -> None:
    """Eqs. 9-14: with f_hat = f, d(model)/df is D on the diagonal and zero elsewhere."""
    rng = np.random.default_rng(7)
    x, u, _ = _random_case(rng)
    f = np.array([0.3, -0.2, 0.1, 0.01, -0.02, 0.015])
    clean = body_gs_derivative(x, u, np.zeros(6), G)
    faulty = body_gs_derivative(x, u + f, f, G)
    # tol: exact algebra, round-off only
    np.testing.assert_allclose(faulty - clean, own_drift_gain(x[3:]) * f, atol=1e-12)
    np.testing.assert_allclose(
        drift_rate_to_fault(own_drift_gain(x[3:]) * f, x[3:]), f, rtol=1e-12
    )
    np.testing.assert_allclose(drift_rate_to_fault(f, x[3:], mapping="paper"), f, rtol=0)


def test_synthetic_truth_obeys_fault_free_model() -> None:
    """The analytic truth of tests/helpers satisfies eqs. 9-14 with f = f_hat = 0."""
    g = 9.79
    for t in (0.3, 7.1, 23.4, 51.0):
        x, u, vel_ned = truth_at(t, g)
        h = 1e-5
        xd = (truth_at(t + h, g)[0] - truth_at(t - h, g)[0]) / (2 * h)
        # atol: central-difference truncation on ~1 Hz signals
        np.testing.assert_allclose(body_gs_derivative(x, u, np.zeros(6), g), xd, atol=1e-6)
        np.testing.assert_allclose(body_gs_measurement(x)[:3], vel_ned, atol=1e-9)
    assert math.isfinite(float(x[0]))


def test_compiled_model_matches_numpy_reference() -> None:
    """models/_kinematics_body_jit.py writes the same equations: equal to round-off."""
    kb = compiled_kernels()
    if kb is None:
        pytest.skip("numba not installed")
    rng = np.random.default_rng(8)
    for _ in range(20):
        x, u_m, f_hat = _random_case(rng)
        out, h = np.empty(6), np.empty(6)
        F, Gm, H = np.empty((6, 6)), np.empty((6, 6)), np.empty((6, 6))
        kb.derivative(x, u_m, f_hat, G, out)
        kb.jac_x(x, u_m, f_hat, G, F)
        kb.noise_matrix(x, Gm)
        kb.measurement(x, h, H)
        # identical expressions in the same order: a few ulp at most
        tol = {"rtol": 1e-13, "atol": 1e-12}
        np.testing.assert_allclose(out, body_gs_derivative(x, u_m, f_hat, G), **tol)
        np.testing.assert_allclose(F, body_gs_jac_x(x, u_m, f_hat, G), **tol)
        np.testing.assert_allclose(Gm, body_gs_noise_matrix(x), **tol)
        np.testing.assert_allclose(h, body_gs_measurement(x), **tol)
        np.testing.assert_allclose(H, body_gs_meas_jac(x), **tol)
