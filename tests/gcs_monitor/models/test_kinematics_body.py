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
    drift_rate_to_fault,
    fault_estimate_matrix,
    fault_from_drift_rate,
    fault_input_matrix,
    own_drift_gain,
)
from tests.helpers.imu_synth_body import truth_at, turn_truth_at
from tests.reference import kinematics_body as ref

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
        drift_rate_to_fault(own_drift_gain(x[3:]) * f, x, mapping="flat"), f, rtol=1e-12
    )
    np.testing.assert_allclose(drift_rate_to_fault(f, x, mapping="paper"), f, rtol=0)


def test_fault_matrices_are_model_jacobians_wrt_fault_and_estimate() -> None:
    """A = d f / d(fault) (the fault adds to u_m, eq. 4) and M = d f / d f_hat, by central
    differences; M = D - A; M f_hat is exactly what f_hat changes (eqs. 9-14 are linear in it)."""
    rng = np.random.default_rng(9)
    for _ in range(20):
        x, u, fh = _random_case(rng)
        A_fd = _fd(lambda ff, x=x, u=u, fh=fh: body_gs_derivative(x, u + ff, fh, G), np.zeros(6))
        M_fd = _fd(lambda ee, x=x, u=u: body_gs_derivative(x, u, ee, G), fh)
        # atol: central differences of an expression linear in the perturbed vector, round-off
        np.testing.assert_allclose(fault_input_matrix(x), A_fd, atol=1e-6)
        np.testing.assert_allclose(fault_estimate_matrix(x), M_fd, atol=1e-6)
        np.testing.assert_allclose(
            fault_estimate_matrix(x), np.diag(own_drift_gain(x[3:])) - fault_input_matrix(x),
            atol=1e-15,
        )
        d_fh = body_gs_derivative(x, u, fh, G) - body_gs_derivative(x, u, np.zeros(6), G)
        np.testing.assert_allclose(fault_estimate_matrix(x) @ fh, d_fh, atol=1e-10)


def test_fault_from_drift_rate_inverts_the_fault_input_matrix() -> None:
    """Closed-form A^{-1}: A(x) A^{-1}(x) r = r; the drift rate of the model with f_hat = 0
    (eq. 20) maps back to f exactly, and with f_hat in eqs. 9-14 it is A f + M f_hat."""
    rng = np.random.default_rng(10)
    for _ in range(20):
        x, u, fh = _random_case(rng)
        r = np.concatenate([rng.uniform(-3, 3, 3), rng.uniform(-0.1, 0.1, 3)])
        # tol: 6x6 products of entries up to ~60, round-off
        np.testing.assert_allclose(fault_input_matrix(x) @ fault_from_drift_rate(r, x), r,
                                   atol=1e-12)
        f = np.concatenate([rng.uniform(-3, 3, 3), rng.uniform(-0.05, 0.05, 3)])
        clean = body_gs_derivative(x, u, np.zeros(6), G)
        mu_dot = body_gs_derivative(x, u + f, np.zeros(6), G) - clean
        np.testing.assert_allclose(drift_rate_to_fault(mu_dot, x), f, atol=1e-11)
        mu_dot_fh = body_gs_derivative(x, u + f, fh, G) - clean
        np.testing.assert_allclose(
            mu_dot_fh, fault_input_matrix(x) @ f + fault_estimate_matrix(x) @ fh, atol=1e-11
        )
    # the inverse is polynomial in sin/cos: finite even at theta = 90 deg
    x90 = np.array([50.0, 1.0, 2.0, 0.3, 0.5 * math.pi, 0.0])
    assert np.all(np.isfinite(fault_from_drift_rate(np.ones(6), x90)))


def test_steady_coordinated_turn_exact_kinematics_and_fault_map() -> None:
    """Hand-derived steady turn (30 deg bank, 125 m/s, Omega = g tan(phi) / V): body velocity
    and attitude constant except psi' = Omega, body rates W^{-1} [0, 0, Omega], specific force
    C^T (v_ned' - g). Eqs. 9-14 must give exactly that derivative. In the bank A is not
    diagonal: with f_hat != f the diagonal map D^{-1} is wrong, the exact map is not."""
    g = 9.79
    x, u, _ = turn_truth_at(12.3, g)
    om = g * math.tan(math.radians(30.0)) / 125.0
    # tol: round-off on values up to 125
    np.testing.assert_allclose(body_gs_derivative(x, u, np.zeros(6), g),
                               [0, 0, 0, 0, 0, om], atol=1e-12)
    # hand values of the rates: p = -Omega sin(theta), q = Omega sin(phi) cos(theta), ...
    th = math.radians(3.0)
    np.testing.assert_allclose(u[3:], om * np.array([-math.sin(th), 0.5 * math.cos(th),
                                                     math.sqrt(3) / 2 * math.cos(th)]), atol=1e-15)
    A = fault_input_matrix(x)
    assert abs(A[4, 5]) == pytest.approx(0.5)  # -sin(phi): r_m drives theta' in eq. 13
    assert abs(A[5, 4]) == pytest.approx(0.5 / math.cos(th))  # q_m drives psi' in eq. 14
    # a true r-gyro fault: its drift maps back to exactly that fault
    f = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.01])
    mu_dot = body_gs_derivative(x, u + f, np.zeros(6), g) - body_gs_derivative(x, u, np.zeros(6), g)
    np.testing.assert_allclose(drift_rate_to_fault(mu_dot, x), f, atol=1e-14)
    # fault free, a false estimate f_hat_r = 0.01 rad/s in eqs. 9-14 (mappings flat/paper): the
    # model drifts by M f_hat
    fh = f
    mu_dot = body_gs_derivative(x, u, fh, g) - body_gs_derivative(x, u, np.zeros(6), g)
    flat = drift_rate_to_fault(mu_dot, x, mapping="flat")
    # the diagonal map reads the sin(phi) coupling of eq. 13 as an f_q of tan(phi) f_hat_r and
    # the ground-speed cross term of eq. 10 as an f_Ay of u f_hat_r
    assert flat[4] == pytest.approx(math.tan(math.radians(30.0)) * 0.01, rel=1e-12)
    assert flat[1] == pytest.approx(x[0] * 0.01, rel=1e-12)


def test_body_model_is_flat_nonrotating_limit_of_gs_km(monkeypatch: pytest.MonkeyPatch) -> None:
    """Eqs. 9-14 = the verified GS-KM (Lu2016 eq. 11, kinematics.py) with no earth rate and an
    infinite radius, rotated into body axes: d(C^T v)/dt = C^T v_ned' - omega x v_b.

    The GS-KM here is its plain-float reference (tests/reference/kinematics.py, equal to the
    kernel bit for bit), which reads the earth constants at call time; the kernel has them
    compiled in."""
    from gcs_monitor.core import constants
    from gcs_monitor.core.atmosphere import gravity_mps2
    from tests.reference.kinematics import gs_km_rates

    def gs_km_f(x: np.ndarray, u: np.ndarray, lat: float, alt: float) -> np.ndarray:
        return np.array(gs_km_rates(list(x), list(u), lat, alt, gravity_mps2(lat, alt)))

    monkeypatch.setattr(constants, "EARTH_RATE_RADPS", 0.0)
    monkeypatch.setattr(constants, "EARTH_RADIUS_M", 1.0e15)
    rng = np.random.default_rng(11)
    lat, alt = 0.9, 500.0
    g = gravity_mps2(lat, alt)
    for _ in range(20):
        x, u, _ = _random_case(rng)
        C = dcm_ned_frd(*x[3:])
        d_ned = gs_km_f(np.concatenate([C @ x[:3], x[3:]]), u, lat, alt)
        vb_dot = C.T @ d_ned[:3] - np.cross(u[3:], x[:3])
        # atol: transport terms v^2 / 1e15 and round-off
        np.testing.assert_allclose(body_gs_derivative(x, u, np.zeros(6), g),
                                   np.concatenate([vb_dot, d_ned[3:]]), atol=1e-10)


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


def test_kernel_matches_numpy_reference() -> None:
    """models/_kinematics_body_jit.py (which the model functions wrap) writes the same
    equations as the plain-float reference (tests/reference/kinematics_body.py): equal to
    round-off."""
    from gcs_monitor.core.kernels import load_kernels

    kb = load_kernels("gcs_monitor.models._kinematics_body_jit")
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
        np.testing.assert_allclose(out, ref.body_gs_derivative(x, u_m, f_hat, G), **tol)
        np.testing.assert_allclose(F, ref.body_gs_jac_x(x, u_m, f_hat, G), **tol)
        np.testing.assert_allclose(Gm, ref.body_gs_noise_matrix(x), **tol)
        np.testing.assert_allclose(h, ref.body_gs_measurement(x), **tol)
        np.testing.assert_allclose(H, ref.body_gs_meas_jac(x), **tol)
        r = np.concatenate([rng.uniform(-3, 3, 3), rng.uniform(-0.1, 0.1, 3)])
        ff = np.empty(6)
        kb.fault_from_drift_rate(r, x, ff)
        np.testing.assert_allclose(ff, ref.fault_from_drift_rate(r, x), **tol)
        mu, mu_prev, f_int = rng.normal(size=6), rng.normal(size=6), rng.normal(size=6)
        f_int_ref = f_int + ref.fault_from_drift_rate(mu - mu_prev, x)
        kb.fault_integral_step(x, mu, mu_prev, f_int)
        np.testing.assert_allclose(f_int, f_int_ref, **tol)
