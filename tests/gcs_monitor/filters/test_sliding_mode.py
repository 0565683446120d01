"""Levant third-order differentiator (Atmaca2025 eqs. 47-50), explicit Euler."""

from __future__ import annotations

import math

import numpy as np

from gcs_monitor.filters.sliding_mode import LevantGains, hosm_init, hosm_step
from tests.reference.sliding_mode import hosm_step_reference


def _run(sig, dsig, L: float, dt: float, t_end: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    lam = LevantGains().lambdas(np.array([L]))
    s = hosm_init(np.array([sig(0.0)]))
    ts = np.arange(0.0, t_end, dt)
    z0, z1 = np.empty_like(ts), np.empty_like(ts)
    for i, t in enumerate(ts):
        s = hosm_step(s, np.array([sig(t)]), lam, dt)
        z0[i], z1[i] = s.z[0, 0], s.z[1, 0]
    return ts + dt, z0, z1  # z(t_{k+1})


def test_gains_formula() -> None:
    lam = LevantGains().lambdas(np.array([16.0]))
    np.testing.assert_allclose(lam[:, 0], [3 * 2.0, 2 * 16 ** (1 / 3), 1.5 * 4.0, 1.1 * 16.0])


def test_differentiates_sine_noise_free() -> None:
    """sin(t): |f''''| = |sin| <= 1, L = 1. After convergence the Euler error is O(L dt^3)."""
    dt = 0.01
    ts, z0, z1 = _run(math.sin, math.cos, 1.0, dt, 30.0)
    late = ts > 10.0
    # bound: explicit Euler lags by up to one step, dt * max|f''| = 1e-2 (measured 5e-3)
    assert np.max(np.abs(z1[late] - np.cos(ts[late]))) < 1e-2
    assert np.max(np.abs(z0[late] - np.sin(ts[late]))) < 1e-4


def test_ramp_and_step_robustness() -> None:
    """Ramp 0.5 t with a step of 1 at t = 5: the derivative recovers to 0.5 within 3 s."""
    dt = 0.01

    def sig(t: float) -> float:
        return 0.5 * t + (1.0 if t >= 5.0 else 0.0)

    ts, z0, z1 = _run(sig, lambda t: 0.5, 4.0, dt, 12.0)
    before = (ts > 3.0) & (ts < 5.0)
    after = ts > 8.0
    assert np.max(np.abs(z1[before] - 0.5)) < 1e-3
    assert np.max(np.abs(z1[after] - 0.5)) < 1e-2
    assert np.all(np.isfinite(z1))
    # the step does produce a transient (a differentiator cannot ignore it) ...
    assert np.max(np.abs(z1[(ts > 5.0) & (ts < 8.0)] - 0.5)) > 0.1
    # ... and z0 tracks the stepped signal again
    assert abs(z0[-1] - sig(ts[-1])) < 1e-3


def test_vector_channels_independent() -> None:
    lam = LevantGains().lambdas(np.array([1.0, 1.0]))
    s = hosm_init(np.zeros(2))
    for k in range(1000):
        t = k * 0.01
        s = hosm_step(s, np.array([2.0 * t, 0.0]), lam, 0.01)
    np.testing.assert_allclose(s.z[1], [2.0, 0.0], atol=1e-5)  # converged to round-off of Euler


def test_kernel_matches_numpy_reference() -> None:
    """Same recursion in the kernel and in numpy (tests/reference/sliding_mode.py): 500 noisy
    steps on 6 channels agree to round-off."""
    rng = np.random.default_rng(2)
    lam = LevantGains().lambdas(np.array([100.0] * 3 + [0.5] * 3))
    s_py = s_nb = hosm_init(np.zeros(6))
    for k in range(500):
        f = np.sin(0.01 * k * np.arange(1, 7)) + 1e-3 * rng.normal(size=6)
        s_py = hosm_step_reference(s_py, f, lam, 0.01)
        s_nb = hosm_step(s_nb, f, lam, 0.01)
    # pow/sqrt/sign of the same operands; only libm rounding of pow can differ (<= 1 ulp)
    np.testing.assert_allclose(s_nb.z, s_py.z, rtol=1e-9, atol=1e-12)
