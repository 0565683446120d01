"""Robust three-step EKF (Lu2017 eqs. 37-48): the printed equations, hand values, the m = p
degeneracy, unbiasedness for m > p, covariance PSD."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gcs_monitor.filters.covariance import is_psd
from gcs_monitor.filters.three_step import (
    three_step_init,
    three_step_predict,
    three_step_update,
)
from gcs_monitor.models.servo import ServoLoopParams, ServoParams, pack_params, propagate
from tests.reference import three_step as ref


def _spd(rng: np.random.Generator, n: int, scale: float = 1.0) -> np.ndarray:
    a = rng.normal(size=(n, n))
    return (a @ a.T + n * np.eye(n)) * scale


@pytest.mark.parametrize(("m", "p"), [(1, 1), (2, 2), (2, 1), (3, 1), (3, 2)])
def test_kernel_equals_printed_equations(m: int, p: int) -> None:
    """Cholesky solves against the printed inverses: round-off only (1e-12 relative)."""
    rng = np.random.default_rng(m * 10 + p)
    n = 3
    x, P = rng.normal(size=n), _spd(rng, n)
    H, F, R = rng.normal(size=(m, n)), rng.normal(size=(m, p)), _spd(rng, m, 0.1)
    y = rng.normal(size=m)
    s, innov = three_step_update(x, P, y, H @ x, H, F, R)
    assert s is not None and innov.numerics_ok
    xr, Pr, fr, Pfr, g, Rt = ref.update(x, P, y, H @ x, H, F, R)
    for a, b in ((s.x, xr), (s.P, Pr), (s.f, fr), (s.Pf, Pfr), (innov.nu, g),
                 (innov.S_diag, Rt.diagonal())):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * max(1.0, np.abs(b).max()))


def test_scalar_hand_values() -> None:
    """n = m = p = 1, H = F = 1: R~ = P + R, f = y - x, P^f = P + R, and the update leaves x and
    P as predicted (eqs. 40-47 by hand)."""
    s, innov = three_step_update(np.array([0.2]), np.array([[0.5]]), np.array([1.0]),
                                 np.array([0.2]), np.eye(1), np.eye(1), np.array([[0.25]]))
    assert s is not None
    np.testing.assert_allclose(s.f, [0.8], rtol=1e-15)
    np.testing.assert_allclose(s.Pf, [[0.75]], rtol=1e-15)
    np.testing.assert_allclose(s.x, [0.2], rtol=1e-15)
    np.testing.assert_allclose(s.P, [[0.5]], rtol=1e-15)
    np.testing.assert_allclose(innov.S_diag, [0.75], rtol=1e-15)


def test_m_equals_p_is_an_open_loop_prediction_on_the_servo() -> None:
    """Lu2017's case m = p (here the servo tier's m = p = 2: rod and surface sensors, F = I):
    N = F^{-1}, so the state is never corrected (x_{k|k} = x_{k|k-1}, P_{k|k} = P_{k|k-1}) and
    the fault estimate is the whole innovation y - H x_{k|k-1} (papers-notes, Lu2017)."""
    prm = pack_params(ServoParams(), ServoLoopParams(), 0.35)
    rng = np.random.default_rng(4)
    s6 = np.zeros(6)
    st_ = three_step_init(np.zeros(3), np.diag([1e-8, 1e-4, 1e-4]), 2)
    H = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    R = np.diag([1e-8, 4e-7])
    for k in range(50):
        q = 0.01 if k > 5 else 0.0
        pr = propagate(np.concatenate([st_.x, s6[3:]]), q, q, 0.0, 0.02, 4, prm,
                       q_valve=1e-4)
        s6 = pr.s
        P_pred = three_step_predict(st_.P, pr.Phi[:3, :3], pr.Qd[:3, :3])
        y = np.array([s6[0] + 1e-3, s6[0] - 2e-3]) + rng.normal(size=2) * 1e-4
        new, innov = three_step_update(s6[:3], P_pred, y, H @ s6[:3], H, np.eye(2), R)
        assert new is not None
        np.testing.assert_allclose(new.x, s6[:3], rtol=0, atol=1e-15)
        np.testing.assert_allclose(new.P, P_pred, rtol=1e-9, atol=1e-20)
        np.testing.assert_allclose(new.f, y - H @ s6[:3], rtol=1e-9, atol=1e-15)
        st_ = new
    assert is_psd(st_.P)


def test_unbiased_state_and_fault_for_m_greater_than_p() -> None:
    """Gillijns & De Moor (2007): with m > p the state and an arbitrary (unmodelled) output fault
    are estimated without bias. A scalar random walk measured by two sensors, the second with a
    fault ramp the filter knows nothing about: over 400 Monte Carlo runs the mean errors at the
    end are zero within 4 standard errors."""
    rng = np.random.default_rng(8)
    H = np.array([[1.0], [1.0]])
    F = np.array([[0.0], [1.0]])
    R = np.diag([0.04, 0.09])
    q = 0.01
    ex, ef = [], []
    for _ in range(400):
        x_true, s = 0.0, three_step_init(np.zeros(1), np.eye(1), 1)
        for k in range(40):
            x_true += rng.normal() * np.sqrt(q)
            f_true = 0.05 * k + (1.0 if k > 20 else 0.0)
            y = H[:, 0] * x_true + F[:, 0] * f_true + rng.normal(size=2) * np.sqrt(R.diagonal())
            P_pred = three_step_predict(s.P, np.eye(1), np.array([[q]]))
            new, _ = three_step_update(s.x, P_pred, y, H @ s.x, H, F, R)
            assert new is not None
            s = new
        ex.append(s.x[0] - x_true)
        ef.append(s.f[0] - f_true)
    for e in (np.array(ex), np.array(ef)):
        assert abs(e.mean()) < 4.0 * e.std() / np.sqrt(e.size)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), scale=st.floats(1e-6, 1e3), p=st.integers(1, 3))
def test_covariances_stay_symmetric_psd(seed: int, scale: float, p: int) -> None:
    rng = np.random.default_rng(seed)
    n, m = 3, 3
    s = three_step_init(np.zeros(n), _spd(rng, n, scale), p)
    H, F = rng.normal(size=(m, n)), rng.normal(size=(m, p))
    for _ in range(20):
        Phi = np.eye(n) + 0.3 * rng.normal(size=(n, n))
        P_pred = three_step_predict(s.P, Phi, _spd(rng, n, 0.01 * scale))
        x_pred = rng.normal(size=n)
        new, innov = three_step_update(x_pred, P_pred, rng.normal(size=m) * np.sqrt(scale),
                                       H @ x_pred, H, F, _spd(rng, m, 0.1 * scale))
        assert new is not None and innov.numerics_ok
        for P in (new.P, new.Pf):
            assert is_psd(P, tol=1e-9 * np.max(np.abs(P)))
        s = new
