"""RLS with forgetting: hand-derived values, exactness on a known linear system, tracking of a
parameter jump, and the covariance bound."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_monitor.filters.rls import (
    RlsFilter,
    RlsState,
    forgetting_factor,
    huber_weight,
    rls_predict,
    rls_step,
)


def test_first_step_by_hand() -> None:
    # n = 1, P = 10, theta = 0, phi = 2, y = 4, lambda = 1:
    # s = 1 + 2 * 10 * 2 = 41, K = 20 / 41, theta = 80 / 41, P = 10 - 20 * 20 / 41 = 10 / 41
    st, up = rls_step(RlsState.initial(1, 10.0), np.array([2.0]), 4.0, 1.0)
    assert (up.prediction, up.error, up.s) == (0.0, 4.0, 41.0)
    assert math.isclose(st.theta[0], 80.0 / 41.0, rel_tol=1e-15)
    assert math.isclose(st.P[0, 0], 10.0 / 41.0, rel_tol=1e-14)


def test_recovers_a_known_linear_system_exactly() -> None:
    # noise-free y = phi^T theta with persistent excitation: with lambda = 1 and a large P0 the
    # estimate equals batch least squares, i.e. theta itself after n independent samples
    rng = np.random.default_rng(1)
    theta = np.array([0.8, -2.5, 0.3])
    st = RlsState.initial(3, 1e8)
    for _ in range(50):
        phi = rng.normal(size=3)
        st, _ = rls_step(st, phi, float(phi @ theta), 1.0)
    np.testing.assert_allclose(st.theta, theta, atol=1e-6)  # P0 = 1e8: prior weight 1e-8
    assert abs(rls_predict(st, np.array([1.0, 1.0, 1.0])) - theta.sum()) < 1e-6


def test_equals_weighted_batch_least_squares() -> None:
    # RLS with forgetting lambda minimises sum lambda^(N-k) e_k^2 + lambda^N theta^T P0^-1 theta
    rng = np.random.default_rng(2)
    lam, p0, n = 0.95, 100.0, 40
    phis = rng.normal(size=(n, 2))
    ys = phis @ np.array([1.0, -1.0]) + 0.1 * rng.normal(size=n)
    st = RlsState.initial(2, p0)
    for phi, y in zip(phis, ys, strict=True):
        st, _ = rls_step(st, phi, float(y), lam)
    w = lam ** np.arange(n - 1, -1, -1)
    A = phis.T @ (w[:, None] * phis) + lam**n * np.eye(2) / p0
    b = phis.T @ (w * ys)
    np.testing.assert_allclose(st.theta, np.linalg.solve(A, b), rtol=1e-9)  # same quadratic
    np.testing.assert_allclose(st.P, np.linalg.inv(A), rtol=1e-9)


def test_forgetting_tracks_a_parameter_jump() -> None:
    rng = np.random.default_rng(3)
    lam = forgetting_factor(2.0, 0.1)  # 2 s memory at 10 Hz
    st = RlsState.initial(2, 1e3)
    for k in range(400):
        gain = 1.0 if k < 200 else 0.2  # a surface loses 80 % of its effectiveness
        phi = np.array([rng.normal(), 1.0])
        st, _ = rls_step(st, phi, gain * phi[0] + 0.01 * rng.normal(), lam)
        if k == 199:
            assert abs(st.theta[0] - 1.0) < 0.02
    assert abs(st.theta[0] - 0.2) < 0.02  # 20 s (10 memories) after the jump


def test_covariance_bound_without_excitation() -> None:
    st = RlsState.initial(2, 1.0)
    for _ in range(500):  # phi never excites the first parameter
        st, _ = rls_step(st, np.array([0.0, 1.0]), 0.0, 0.9, trace_max=50.0)
    assert np.trace(st.P) <= 50.0 * (1 + 1e-12)
    assert np.allclose(st.P, st.P.T)


def test_non_finite_sample_is_skipped_and_bad_lambda_rejected() -> None:
    st0 = RlsState.initial(2, 1.0)
    st, up = rls_step(st0, np.array([1.0, 0.0]), math.nan, 0.99)
    assert st is st0 and math.isnan(up.error)
    with pytest.raises(ValueError):
        rls_step(st0, np.array([1.0, 0.0]), 1.0, 1.5)
    assert math.isclose(forgetting_factor(10.0, 0.1), math.exp(-0.01))


def test_weighted_step_equals_weighted_batch_least_squares() -> None:
    # weights w_k: RLS minimises sum lambda^(N-k) w_k e_k^2 + lambda^N theta^T P0^-1 theta
    rng = np.random.default_rng(5)
    lam, p0, n = 0.97, 50.0, 30
    phis = rng.normal(size=(n, 2))
    ys = phis @ np.array([0.5, 2.0]) + 0.1 * rng.normal(size=n)
    ws = rng.uniform(0.1, 1.0, size=n)
    st = RlsState.initial(2, p0)
    for phi, y, w in zip(phis, ys, ws, strict=True):
        st, _ = rls_step(st, phi, float(y), lam, weight=float(w))
    lw = ws * lam ** np.arange(n - 1, -1, -1)
    A = phis.T @ (lw[:, None] * phis) + lam**n * np.eye(2) / p0
    np.testing.assert_allclose(st.theta, np.linalg.solve(A, phis.T @ (lw * ys)), rtol=1e-9)
    assert huber_weight(0.5, 3.0) == 1.0 and huber_weight(-6.0, 3.0) == 0.5


def test_kernel_matches_the_numpy_reference_and_the_in_place_filter() -> None:
    from tests.reference.rls import rls_update

    rng = np.random.default_rng(7)
    st = RlsState.initial(4, 10.0)
    filt = RlsFilter(4, 10.0)
    th, P = st.theta.copy(), st.P.copy()
    for _ in range(200):
        phi = rng.normal(size=4)
        y, lam, w = float(rng.normal()), 0.97, float(rng.uniform(0.2, 1.0))
        st, up = rls_step(st, phi, y, lam, trace_max=30.0, weight=w)
        filt.update(phi, y, lam, trace_max=30.0, weight=w)
        th, P, e, s = rls_update(th, P, phi, y, lam, 30.0, w)
        assert math.isclose(up.error, e, rel_tol=1e-12, abs_tol=1e-12)
    # loops and numpy sum in different orders: a few ulps per step over 200 steps
    np.testing.assert_allclose(st.theta, th, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(st.P, P, rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(filt.theta, st.theta)  # the same kernel, the same bits
    np.testing.assert_array_equal(filt.P, st.P)
