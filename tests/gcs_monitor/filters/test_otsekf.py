"""OTSEKF (Atmaca2025 eqs. 20-42): equivalence with the augmented-state KF on linear models."""

from __future__ import annotations

import numpy as np
import pytest

from gcs_monitor.filters.covariance import is_psd
from gcs_monitor.filters.otsekf import OtsekfPrediction, otsekf_init, otsekf_step
from tests.reference.otsekf import otsekf_step_reference

# the kernel (filters/_otsekf_jit.py) and its numpy reference (tests/reference/otsekf.py)
STEPS = {"kernel": otsekf_step, "reference": otsekf_step_reference}


def _spd(rng: np.random.Generator, n: int, scale: float) -> np.ndarray:
    A = rng.normal(size=(n, n))
    return scale * (A @ A.T + n * np.eye(n))


def _run_pair(
    seed: int, n: int = 3, b: int = 2, m: int = 3, steps: int = 60, step: str = "reference"
) -> None:
    rng = np.random.default_rng(seed)
    Phi = np.eye(n) + 0.05 * rng.normal(size=(n, n))
    B = 0.1 * rng.normal(size=(n, b))
    H = rng.normal(size=(m, n))
    R = _spd(rng, m, 0.05)
    Qaug = _spd(rng, n + b, 0.01)  # correlated state / bias noise
    Qx, Qxmu, Qmu = Qaug[:n, :n], Qaug[:n, n:], Qaug[n:, n:]
    x0, P0 = rng.normal(size=n), _spd(rng, n, 0.1)
    mu0, Pmu0 = rng.normal(size=b), _spd(rng, b, 0.1)
    s = otsekf_init(x0, P0, mu0, Pmu0)
    # augmented KF
    A = np.block([[Phi, B], [np.zeros((b, n)), np.eye(b)]])
    Ha = np.hstack([H, np.zeros((m, b))])
    xa = np.concatenate([x0, mu0])
    Pa = np.block([[P0, np.zeros((n, b))], [np.zeros((b, n)), Pmu0]])
    truth = np.concatenate([x0, mu0])
    for _ in range(steps):
        truth = A @ truth + rng.multivariate_normal(np.zeros(n + b), Qaug)
        y = Ha @ truth + rng.multivariate_normal(np.zeros(m), R)
        pred = OtsekfPrediction(
            x_bar_prop=Phi @ s.x_bar, Phi=Phi, B=B, Qx=Qx, Qxmu=Qxmu, Qmu=Qmu
        )
        s, innov = STEPS[step](s, pred, lambda x: (H @ x, H), y, R, gate_sigma=3.0)
        assert innov.numerics_ok
        xa = A @ xa
        Pa = A @ Pa @ A.T + Qaug
        Sa = Ha @ Pa @ Ha.T + R
        Ka = Pa @ Ha.T @ np.linalg.inv(Sa)
        nu_a = y - Ha @ xa
        xa = xa + Ka @ nu_a
        Pa = (np.eye(n + b) - Ka @ Ha) @ Pa
        # tolerances: the two-stage form is an exact algebraic rearrangement of the augmented
        # filter (Hsieh & Chen 1999), so only round-off of ~60 well-conditioned steps remains
        np.testing.assert_allclose(innov.nu, nu_a, atol=1e-9)
        np.testing.assert_allclose(innov.S, Sa, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(s.x_hat, xa[:n], atol=1e-9)
        np.testing.assert_allclose(s.mu, xa[n:], atol=1e-9)
        np.testing.assert_allclose(s.P, Pa[:n, :n], rtol=1e-8, atol=1e-12)
        np.testing.assert_allclose(s.P_mu, Pa[n:, n:], rtol=1e-8, atol=1e-12)
        assert is_psd(s.P_bar) and is_psd(s.P_mu)


@pytest.mark.parametrize("step", sorted(STEPS))
def test_two_stage_equals_augmented_kf_correlated_noise(step: str) -> None:
    for seed in range(5):
        _run_pair(seed, step=step)


def test_two_stage_equals_augmented_kf_drift_parametrisation() -> None:
    """The IMU estimator's choice B = 0, Q^{x mu} = -Q^mu, Qx = Q + Q^mu is also exact."""
    rng = np.random.default_rng(11)
    n = 2
    Phi = np.array([[1.0, 0.01], [0.0, 1.0]])
    H = np.eye(n)
    R = np.diag([0.03**2, 1e-4**2])
    Q = np.diag([1e-10, 1e-12])
    Qmu = np.diag([1e-4, 1e-8])
    Qaug = np.block([[Q + Qmu, -Qmu], [-Qmu, Qmu]])
    s = otsekf_init(np.zeros(n), R.copy(), np.zeros(n), np.zeros((n, n)))
    Z = np.zeros((n, n))
    xa, Pa = np.zeros(2 * n), np.block([[R, Z], [Z, Z]])
    A = np.block([[Phi, np.zeros((n, n))], [np.zeros((n, n)), np.eye(n)]])
    Ha = np.hstack([H, np.zeros((n, n))])
    for k in range(40):
        y = np.array([0.02 * k, 1e-3 * k]) + rng.normal(size=n) * np.sqrt(np.diag(R))
        pred = OtsekfPrediction(
            x_bar_prop=Phi @ s.x_bar, Phi=Phi, B=np.zeros((n, n)), Qx=Q + Qmu, Qxmu=-Qmu, Qmu=Qmu
        )
        s, innov = otsekf_step(s, pred, lambda x: (H @ x, H), y, R, gate_sigma=3.0)
        xa, Pa = A @ xa, A @ Pa @ A.T + Qaug
        Ka = Pa @ Ha.T @ np.linalg.inv(Ha @ Pa @ Ha.T + R)
        xa, Pa = xa + Ka @ (y - Ha @ xa), (np.eye(2 * n) - Ka @ Ha) @ Pa
        np.testing.assert_allclose(s.x_hat, xa[:n], rtol=1e-7, atol=1e-10)
        np.testing.assert_allclose(s.mu, xa[n:], rtol=1e-7, atol=1e-10)


@pytest.mark.parametrize("step", sorted(STEPS))
def test_test_ratio_and_numerics_flag(step: str) -> None:
    n = 2
    H = np.eye(n)
    R = np.eye(n)
    s = otsekf_init(np.zeros(n), np.eye(n), np.zeros(n), np.eye(n))
    pred = OtsekfPrediction(
        x_bar_prop=s.x_bar, Phi=np.eye(n), B=np.eye(n), Qx=np.zeros((n, n)),
        Qxmu=np.zeros((n, n)), Qmu=np.zeros((n, n)),
    )
    s1, innov = STEPS[step](s, pred, lambda x: (H @ x, H), np.array([6.0, 0.0]), R, gate_sigma=2.0)
    # innovation covariance: P + R + B Pmu B^T = 3 I; ratio = 36 / (4 * 3) = 3
    np.testing.assert_allclose(innov.test_ratio, [3.0, 0.0], rtol=1e-12)
    assert innov.rejected.tolist() == [True, False]
    s2, bad = STEPS[step](
        s1, pred, lambda x: (H @ x, H), np.array([np.nan, 0.0]), R, gate_sigma=2.0
    )
    assert not bad.numerics_ok
    assert s2 is s1  # the state is returned unchanged on a failure
    assert np.all(np.isnan(bad.nu))


def test_kernel_matches_numpy_reference_nonlinear() -> None:
    """The numba kernels implement the reference (tests/reference/otsekf.py) equation by
    equation: on a nonlinear measurement with a wrapped angle and correlated noise blocks, 50
    steps agree to round-off."""
    rng = np.random.default_rng(5)
    n, b, m = 4, 3, 3
    Phi = np.eye(n) + 0.05 * rng.normal(size=(n, n))
    B = 0.1 * rng.normal(size=(n, b))
    Qaug = _spd(rng, n + b, 0.01)
    R = _spd(rng, m, 0.05)

    def meas(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        h = np.array([x[0] * x[1], np.sin(x[2]), np.arctan2(x[3], 1.0 + x[0] ** 2)])
        H = np.zeros((m, n))
        H[0, 0], H[0, 1] = x[1], x[0]
        H[1, 2] = np.cos(x[2])
        den = (1.0 + x[0] ** 2) ** 2 + x[3] ** 2
        H[2, 0] = -2.0 * x[0] * x[3] / den
        H[2, 3] = (1.0 + x[0] ** 2) / den
        return h, H

    s_py = s_nb = otsekf_init(rng.normal(size=n), _spd(rng, n, 0.1), np.zeros(b), np.eye(b))
    for _ in range(50):
        y = rng.normal(size=m) + np.array([0.0, 0.0, 3.0])  # third channel near the +-pi wrap
        out = []
        for s, step in ((s_py, otsekf_step_reference), (s_nb, otsekf_step)):
            pred = OtsekfPrediction(
                x_bar_prop=np.tanh(Phi @ s.x_bar), Phi=Phi, B=B,
                Qx=Qaug[:n, :n], Qxmu=Qaug[:n, n:], Qmu=Qaug[n:, n:],
            )  # fmt: skip
            out.append(step(s, pred, meas, y, R, gate_sigma=3.0, wrap_idx=(2,)))
        (s_py, i_py), (s_nb, i_nb) = out
        assert i_py.numerics_ok and i_nb.numerics_ok
        # same operations in a different summation order (loops vs BLAS): round-off only
        for field in ("x_bar", "P_bar", "mu", "P_mu", "V", "x_hat", "P"):
            np.testing.assert_allclose(
                getattr(s_nb, field), getattr(s_py, field), rtol=1e-10, atol=1e-12
            )
        for field in ("nu", "S", "test_ratio"):
            np.testing.assert_allclose(
                getattr(i_nb, field), getattr(i_py, field), rtol=1e-10, atol=1e-12
            )
        assert np.all(np.abs(i_nb.nu[2]) <= np.pi)
