"""IOTSEKF on a caller's discretisation (Lu2017 eqs. 14-36): the printed equations (with the
iteration), the augmented-state KF on the linearised servo, a scalar closed form, PSD."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from gcs_monitor.filters.covariance import is_psd
from gcs_monitor.filters.ekf import EkfState, ekf_predict, ekf_update
from gcs_monitor.filters.iotsekf import iotsekf_init, iotsekf_step
from gcs_monitor.models.servo import ServoLoopParams, ServoParams, pack_params, propagate
from tests.reference import iotsekf as ref


def _spd(rng: np.random.Generator, n: int, scale: float = 1.0) -> np.ndarray:
    a = rng.normal(size=(n, n))
    return (a @ a.T + n * np.eye(n)) * scale


def _linearised_servo(dt: float = 0.02) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Phi, Gamma (6, 1), Q_d of the closed servo loop (plant and reference states) at rest
    over one 50 Hz sample."""
    prm = pack_params(ServoParams(), ServoLoopParams(), 0.35)
    pr = propagate(np.zeros(6), 0.0, 0.0, 0.0, dt, 4, prm, q_valve=1e-6)
    return pr.Phi, pr.Gamma.reshape(6, 1), pr.Qd


def test_kernel_equals_printed_equations_with_iteration() -> None:
    """The kernel (one pass) against the printed equations with the iteration of eqs. 21-23,
    which for a linear output stops after the second pass (epsilon = 0): round-off only."""
    rng = np.random.default_rng(1)
    n, b, m = 3, 1, 2
    s = iotsekf_init(rng.normal(size=n), _spd(rng, n), rng.normal(size=b), _spd(rng, b),
                     np.eye(b) * 0.01, m=m)
    r = ref.State(s.x_bar.copy(), s.P_bar.copy(), s.f.copy(), s.Pf.copy(), s.V.copy())
    for _ in range(30):
        Phi = np.eye(n) + 0.1 * rng.normal(size=(n, n))
        Gam, Qd = rng.normal(size=(n, b)), _spd(rng, n, 0.01)
        H, R = rng.normal(size=(m, n)), _spd(rng, m, 0.1)
        d = 0.1 * rng.normal(size=n)
        y = rng.normal(size=m)
        s, innov = iotsekf_step(s, s.x_bar + d, Phi, Gam, Qd, H, y, R)
        r, x_hat, Px, gamma, iterations = ref.step(r, r.x_bar + d, Phi, Gam, Qd, s.Qf, H, y, R)
        assert innov.numerics_ok and iterations == 2
        for a, e in ((s.x, x_hat), (s.Px, Px), (s.f, r.f), (s.Pf, r.Pf), (s.V, r.V),
                     (s.x_bar, r.x_bar), (innov.nu, gamma)):
            np.testing.assert_allclose(a, e, rtol=1e-9, atol=1e-12 * max(1.0, np.abs(e).max()))


def test_equals_augmented_kf_on_the_linearised_servo() -> None:
    """Hsieh & Chen (1999): with Q^{xf} = 0 and V_0 = 0 the two-stage filter is an exact
    reorganisation of the augmented-state KF ``z = [x; f^i]``. On the servo loop linearised at
    rest (50 Hz, rod sensor), with a 1 Hz input fault the random walk only approximates, both
    give the same estimates to round-off (1e-9 relative; a missing coupling term shows at 1e-2)
    and the fault estimate follows the sinusoid."""
    Phi, Gam, Qd = _linearised_servo()
    n, b = 6, 1
    H = np.array([[1.0, 0.0, 0.0, 0.0, 0.0, 0.0]])
    R = np.array([[1e-8]])
    Qf = np.array([[(1.0 * 0.02) ** 2]])
    P0 = np.diag([1e-8, 1e-4, 1e-4, 1e-8, 1e-6, 1e-6])
    Pf0 = np.array([[0.01]])
    s = iotsekf_init(np.zeros(n), P0, np.zeros(b), Pf0, Qf, m=1)
    Aa = np.block([[Phi, Gam], [np.zeros((b, n)), np.eye(b)]])
    Qa = np.block([[Qd, np.zeros((n, b))], [np.zeros((b, n)), Qf]])
    Ca = np.hstack([H, np.zeros((1, b))])
    a = EkfState(np.zeros(n + b), np.block([[P0, np.zeros((n, b))], [np.zeros((b, n)), Pf0]]))
    rng = np.random.default_rng(2)
    x = np.zeros(n)
    est, true = [], []
    for k in range(500):
        f_true = 0.05 * np.sin(2 * np.pi * 1.0 * k * 0.02)
        x = Phi @ x + Gam[:, 0] * f_true
        y = H @ x + rng.normal(size=1) * 1e-4
        s, innov = iotsekf_step(s, Phi @ s.x_bar, Phi, Gam, Qd, H, y, R)
        a = ekf_predict(a, Aa @ a.x, Aa, Qa)
        a, innov_a = ekf_update(a, y, Ca @ a.x, Ca, R, gate_sigma=3.0)
        np.testing.assert_allclose(s.x, a.x[:n], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(s.f, a.x[n:], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(s.Px, a.P[:n, :n], rtol=1e-9, atol=1e-18)
        np.testing.assert_allclose(s.Pf, a.P[n:, n:], rtol=1e-9, atol=1e-18)
        np.testing.assert_allclose(innov.S_diag, innov_a.S_diag, rtol=1e-9)
        if k > 100:
            est.append(s.f[0])
            true.append(f_true)
    # the random-walk fault model follows the sinusoid with a lag of a sample or two
    assert np.sqrt(np.mean(np.square(np.subtract(est, true)))) < 0.015


def test_scalar_constant_fault_closed_form() -> None:
    """Phi = 0, Gamma = H = 1, Q^f = 0: y_k = f + w_k + v_k, so f_hat_k is the
    precision-weighted mean and P^f_k = 1 / (1/P0 + k/(q + r)) (least squares of a constant)."""
    q, r, p0, f0 = 0.3, 0.2, 4.0, 0.5
    s = iotsekf_init(np.zeros(1), np.array([[1.0]]), np.array([f0]), np.array([[p0]]),
                     np.zeros((1, 1)), m=1)
    rng = np.random.default_rng(5)
    ys = 2.0 + rng.normal(size=50)
    for k, y in enumerate(ys, start=1):
        s, _ = iotsekf_step(s, np.zeros(1), np.zeros((1, 1)), np.ones((1, 1)),
                            np.array([[q]]), np.eye(1), np.array([y]), np.array([[r]]))
        info = 1.0 / p0 + k / (q + r)
        np.testing.assert_allclose(s.Pf[0, 0], 1.0 / info, rtol=1e-12)  # float64 round-off
        np.testing.assert_allclose(s.f[0], (f0 / p0 + np.sum(ys[:k]) / (q + r)) / info,
                                   rtol=1e-12)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), scale=st.floats(1e-6, 1e3))
def test_covariances_stay_symmetric_psd(seed: int, scale: float) -> None:
    rng = np.random.default_rng(seed)
    n, b, m = 3, 1, 2
    s = iotsekf_init(np.zeros(n), _spd(rng, n, scale), np.zeros(b), _spd(rng, b, scale),
                     np.eye(b) * 1e-3 * scale, m=m)
    for _ in range(30):
        Phi = np.eye(n) + 0.3 * rng.normal(size=(n, n))
        H = rng.normal(size=(m, n))
        s, innov = iotsekf_step(s, rng.normal(size=n), Phi, rng.normal(size=(n, b)),
                                _spd(rng, n, 0.01 * scale), H,
                                rng.normal(size=m) * np.sqrt(scale), _spd(rng, m, 0.1 * scale))
        assert innov.numerics_ok
        for P in (s.P_bar, s.Pf, s.Px):
            assert is_psd(P, tol=1e-9 * np.max(np.abs(P)))
