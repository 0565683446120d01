"""IOTSEKF / ATSEKF (Lu2016 eqs. 31-58): equivalence with the augmented KF, closed forms, PSD."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gcs_monitor.filters.covariance import is_psd
from gcs_monitor.filters.ekf import EkfState, ekf_predict, ekf_update
from gcs_monitor.filters.two_stage import (
    TwoStageConfig,
    TwoStageNoise,
    _step_numpy,
    adapt_qf,
    discretise_series,
    two_stage_init,
    two_stage_step,
)

NO_ADAPT = TwoStageConfig(adapt=False)


DT = 0.01


def numpy_step(s, model, u_prev, u_now, y, dt_s, noise, cfg):  # type: ignore[no-untyped-def]
    """two_stage_step through the numpy path (LAPACK solves, numpy adaptation) at every step:
    what the filter runs in its iterated first steps (two_stage module docstring)."""
    return _step_numpy(s, model, u_prev, u_now, y, dt_s, noise, cfg, discretise_series)


# the non-iterated step: the kernels (filters/_two_stage_jit.py) and the numpy path
STEPS = {"kernel": two_stage_step, "numpy": numpy_step}


@dataclass(frozen=True)
class LinearModel:
    """x_k = Phi x_{k-1} + B u_{k-1} + Gamma f + w, y = C x + v, with (Phi, Gamma) the eq. 33-34
    discretisation of continuous (Fc, Gc) (so the filter's built-in series reproduces them);
    `disc` instead hands Phi = Fc, Gamma = Gc straight through (for hand-made discrete cases)."""

    Fc: np.ndarray
    B: np.ndarray
    Gc: np.ndarray
    C: np.ndarray
    discrete: bool = False  # True: Fc, Gc already are Phi, Gamma (use with discretise=disc)

    @property
    def Phi(self):
        return self.Fc if self.discrete else discretise_series(self.Fc, self.Gc, DT)[0]

    @property
    def Gam(self):
        return self.Gc if self.discrete else discretise_series(self.Fc, self.Gc, DT)[1]

    def propagate(self, x, u0, u1, dt_s):
        return self.Phi @ x + self.B @ u0

    def jacobians(self, x, u):
        return self.Fc, self.Gc

    def h(self, x):
        return self.C @ x

    def h_jac(self, x):
        return self.C

    def disc(self, F, G, dt_s):
        return F, G


def _random_lti(rng: np.random.Generator, n: int, b: int, m: int) -> LinearModel:
    A = rng.normal(size=(n, n)) * 3.0
    Fc = A - (np.max(np.real(np.linalg.eigvals(A))) + 1.0) * np.eye(n)  # stable, fast modes
    return LinearModel(
        Fc, rng.normal(size=(n, b)), rng.normal(size=(n, b)) * 50.0, rng.normal(size=(m, n))
    )


@pytest.mark.parametrize("path", sorted(STEPS))
def test_two_stage_equals_augmented_kf_on_lti_with_constant_bias(path: str) -> None:
    """Hsieh & Chen (1999): with Q^{xf} = 0, V_0 = 0 and P^f invertible, the two-stage filter is
    an exact algebraic reorganisation of the augmented-state KF. Both run the same recursion in
    float64, so they differ only by round-off: rtol 1e-9 is tight on purpose (any missing
    coupling term, e.g. ubar of eq. 45 or the U Q^f Ubar^T of eq. 46, shows up at 1e-2)."""
    rng = np.random.default_rng(11)
    n, b, m = 4, 2, 3
    mod = _random_lti(rng, n, b, m)
    Q = np.diag([0.02, 0.05])
    R = np.diag([0.1, 0.2, 0.05])
    Qf = np.diag([1e-4, 3e-4])
    noise = TwoStageNoise(Q=Q, R=R)
    f_true = np.array([1.5, -0.7])
    x_true = np.zeros(n)
    P0 = np.eye(n) * 2.0
    Pf0 = np.eye(b) * 5.0
    s = two_stage_init(np.zeros(n), P0, np.zeros(b), Pf0, Qf, m=m, window_n=10)
    Phi, Gam = mod.Phi, mod.Gam
    # augmented: z = [x; f]
    Aa = np.block([[Phi, Gam], [np.zeros((b, n)), np.eye(b)]])
    Qa = np.block([[Gam @ Q @ Gam.T, np.zeros((n, b))], [np.zeros((b, n)), Qf]])
    Ca = np.hstack([mod.C, np.zeros((m, b))])
    a = EkfState(x=np.zeros(n + b), P=np.block([[P0, np.zeros((n, b))], [np.zeros((b, n)), Pf0]]))
    u_prev = np.zeros(b)
    cfg = TwoStageConfig(adapt=False, n_iterated_steps=0)
    for _k in range(200):
        u = rng.normal(size=b)
        x_true = (
            Phi @ x_true
            + mod.B @ u_prev
            + Gam @ (f_true + rng.normal(size=b) * np.sqrt(np.diag(Q)))
        )
        y = mod.C @ x_true + rng.normal(size=m) * np.sqrt(np.diag(R))
        s, innov = STEPS[path](s, mod, u_prev, u, y, DT, noise, cfg)
        za = Aa @ a.x + np.concatenate([mod.B @ u_prev, np.zeros(b)])
        a = ekf_predict(a, za, Aa, Qa)
        a, innov_a = ekf_update(a, y, Ca @ a.x, Ca, R, gate_sigma=3.0)
        u_prev = u
        np.testing.assert_allclose(s.x, a.x[:n], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(s.f, a.x[n:], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(s.Pf, a.P[n:, n:], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(s.Px, a.P[:n, :n], rtol=1e-9, atol=1e-12)
        # same innovation and innovation covariance
        np.testing.assert_allclose(innov.nu, innov_a.nu, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(innov.S_diag, innov_a.S_diag, rtol=1e-9)
    assert np.max(np.abs(s.f - f_true)) < 0.2  # and it actually found the bias


def test_scalar_constant_bias_closed_form() -> None:
    """Phi = 0, Gamma = H = 1, Q^f = 0: y_k = f + w_k + v_k, so f_hat_k is the precision-weighted
    mean, P^f_k = 1 / (1/P0 + k/(q + r)) exactly (least squares of a constant)."""
    mod = LinearModel(
        np.zeros((1, 1)), np.zeros((1, 1)), np.ones((1, 1)), np.ones((1, 1)), discrete=True
    )
    q, r, p0, f0 = 0.3, 0.2, 4.0, 0.5
    noise = TwoStageNoise(Q=np.array([[q]]), R=np.array([[r]]))
    s = two_stage_init(
        np.zeros(1),
        np.array([[1.0]]),
        np.array([f0]),
        np.array([[p0]]),
        np.zeros((1, 1)),
        m=1,
        window_n=10,
    )
    rng = np.random.default_rng(5)
    ys = 2.0 + rng.normal(size=50)
    for k, y in enumerate(ys, start=1):
        s, _ = two_stage_step(
            s,
            mod,
            np.zeros(1),
            np.zeros(1),
            np.array([y]),
            DT,
            noise,
            NO_ADAPT,
            discretise=mod.disc,
        )
        info = 1.0 / p0 + k / (q + r)
        f_expected = (f0 / p0 + np.sum(ys[:k]) / (q + r)) / info
        np.testing.assert_allclose(s.Pf[0, 0], 1.0 / info, rtol=1e-12)  # float64 round-off
        np.testing.assert_allclose(s.f[0], f_expected, rtol=1e-12)


def test_iteration_leaves_linear_update_unchanged() -> None:
    """For a linear h the iterated update (eq. 37) is a fixed point after one pass."""
    rng = np.random.default_rng(2)
    mod = _random_lti(rng, 3, 1, 2)
    noise = TwoStageNoise(Q=np.eye(1) * 0.1, R=np.eye(2) * 0.1)
    s0 = two_stage_init(
        np.zeros(3), np.eye(3), np.zeros(1), np.eye(1), np.eye(1) * 1e-3, m=2, window_n=10
    )
    y = np.array([1.0, -2.0])
    a, _ = two_stage_step(
        s0, mod, np.ones(1), np.ones(1), y, DT, noise, TwoStageConfig(adapt=False)
    )
    b, _ = numpy_step(
        s0, mod, np.ones(1), np.ones(1), y, DT, noise,
        TwoStageConfig(adapt=False, n_iterated_steps=0),
    )  # fmt: skip
    np.testing.assert_allclose(a.x, b.x, rtol=1e-12, atol=1e-14)


def test_adapt_qf_scalar_hand_value() -> None:
    # eq. 53/57/58 with m = b = 1: Q^f = max(0, mean(g^2) - (hG)^2 q / dt - r) / (hG)^2 * dt^2
    g2 = np.array([[0.5], [0.3], [0.4], [0.6]])
    H, Gam, Q, R, dt = (
        np.array([[2.0]]),
        np.array([[0.05]]),
        np.array([[0.1]]),
        np.array([[0.1]]),
        0.01,
    )
    hg = 0.1
    expected = (0.45 - hg**2 * 0.1 / dt - 0.1) / hg**2 * dt**2
    assert expected > 0.0
    np.testing.assert_allclose(adapt_qf(g2, H, Gam, Q, R, dt), [[expected]], rtol=1e-12)
    # negative Q_hat is clipped to zero (eq. 58)
    np.testing.assert_array_equal(adapt_qf(g2 * 0.01, H, Gam, Q, R, dt), [[0.0]])


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), adapt=st.booleans(), scale=st.floats(1e-3, 1e3))
def test_covariances_stay_symmetric_psd(seed: int, adapt: bool, scale: float) -> None:
    rng = np.random.default_rng(seed)
    n = m = b = 3
    mod = _random_lti(rng, n, b, m)
    if abs(np.linalg.det(mod.C @ mod.Gam)) < 1e-3:  # eq. 57 inverts H Gamma
        mod = LinearModel(mod.Fc, mod.B, np.eye(3), np.eye(3))
    noise = TwoStageNoise(Q=np.eye(b) * 0.01 * scale, R=np.eye(m) * 0.1 * scale)
    s = two_stage_init(
        np.zeros(n),
        np.eye(n) * scale,
        np.zeros(b),
        np.eye(b) * scale,
        np.eye(b) * 1e-4,
        m=m,
        window_n=4,
    )
    for _ in range(30):
        y = rng.normal(size=m) * np.sqrt(scale) * 3.0
        s, innov = two_stage_step(
            s,
            mod,
            rng.normal(size=b),
            rng.normal(size=b),
            y,
            DT,
            noise,
            TwoStageConfig(adapt=adapt, window_n=4, n_iterated_steps=2),
        )
        assert innov.numerics_ok
        for P in (s.P_bar, s.Pf, s.Px):
            assert is_psd(P, tol=1e-9 * np.max(np.abs(P)))


def test_kernel_and_numpy_paths_agree_on_gs_km() -> None:
    """The kernels and the numpy path chain the same equation segments around different
    Cholesky solves and adaptation sums (two_stage module docstring): ATSEKF on the nonlinear
    GS-KM over 300 steps (adaptation active) must agree to round-off (1e-9 relative)."""
    from gcs_monitor.models.kinematics import GsKm

    rng = np.random.default_rng(4)
    mdl = GsKm(0.9, 500.0)
    Q = np.diag([1e-4] * 3 + [3e-8] * 3)
    R = np.diag([1e-4] * 3 + [3e-8] * 3)
    noise = TwoStageNoise(Q=Q, R=R)
    x = np.array([50.0, 10.0, -1.0, 0.2, 0.05, 2.0])
    u = np.array([0.3, 9.81 * np.sin(0.2), -9.81 * np.cos(0.2), 0.0, 0.02, 0.1])
    f_true = np.array([1.0, -0.5, 0.3, 0.01, 0.0, -0.02])
    s0 = two_stage_init(x, R, np.zeros(6), np.eye(6), np.eye(6) * 1e-6, m=6, window_n=10)
    sa, sb = s0, s0
    for _ in range(300):
        x = mdl.propagate(x, u, u, DT)
        um = u + f_true + rng.normal(size=6) * np.sqrt(np.diag(Q))
        y = x + rng.normal(size=6) * np.sqrt(np.diag(R))
        sa, ia = two_stage_step(sa, mdl, um, um, y, DT, noise, TwoStageConfig())
        sb, ib = numpy_step(sb, mdl, um, um, y, DT, noise, TwoStageConfig())
        assert ia.numerics_ok and ib.numerics_ok
    np.testing.assert_allclose(sa.x, sb.x, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(sa.f, sb.f, rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(sa.Qf, sb.Qf, rtol=1e-7, atol=1e-16)
    np.testing.assert_allclose(ia.nu, ib.nu, rtol=1e-7, atol=1e-12)


@pytest.mark.parametrize("adapt", [True, False])
def test_packed_step_equals_compiled_step_bitwise(adapt: bool) -> None:
    """PackedTwoStage (one kernel on a packed state, the estimator hot path) makes exactly the
    calls of the compiled two_stage_step for h(x) = x: identical numbers, not just close."""
    from gcs_monitor.core.atmosphere import gravity_mps2
    from gcs_monitor.core.kernels import load_kernels
    from gcs_monitor.filters.two_stage import PackedTwoStage
    from gcs_monitor.models.kinematics import GsKm

    kin = load_kernels("gcs_monitor.models._kinematics_jit")
    rng = np.random.default_rng(5)
    lat, alt = 0.9, 500.0
    mdl = GsKm(lat, alt)
    Q = np.diag([1e-4] * 3 + [3e-8] * 3)
    R = np.diag([1e-4] * 3 + [3e-8] * 3)
    noise = TwoStageNoise(Q=Q, R=R)
    cfg = TwoStageConfig(adapt=adapt)
    x = np.array([50.0, 10.0, -1.0, 0.2, 0.05, 2.0])
    u = np.array([0.3, 9.81 * np.sin(0.2), -9.81 * np.cos(0.2), 0.0, 0.02, 0.1])
    f_true = np.array([1.0, -0.5, 0.3, 0.01, 0.0, -0.02])
    sa = sb = two_stage_init(x, R, np.zeros(6), np.eye(6), np.eye(6) * 1e-6, m=6, window_n=10)
    packed = PackedTwoStage(6, 6, 6, cfg.window_n)
    F, G, xb = np.zeros((6, 6)), np.zeros((6, 6)), np.zeros(6)
    u_prev = u
    for _ in range(200):
        x = mdl.propagate(x, u, u, DT)
        um = u + f_true + rng.normal(size=6) * np.sqrt(np.diag(Q))
        y = x + rng.normal(size=6) * np.sqrt(np.diag(R))
        sa, ia = two_stage_step(sa, mdl, u_prev, um, y, DT, noise, cfg)
        if sb.k < cfg.n_iterated_steps:
            sb, ib = two_stage_step(sb, mdl, u_prev, um, y, DT, noise, cfg)
        else:
            kin.jacobians(sb.x, u_prev - sb.f, lat, alt, F, G)
            kin.propagate(sb.x_bar, u_prev, um, lat, alt, gravity_mps2(lat, alt), DT, xb)
            sb, ib = packed.step(sb, F, G, xb, y, DT, noise, cfg)
        u_prev = um
        for name in ("x_bar", "P_bar", "f", "Pf", "V", "Qf", "x", "Px", "gamma2"):
            np.testing.assert_array_equal(getattr(sa, name), getattr(sb, name))
        assert sa.k == sb.k and ia.numerics_ok and ib.numerics_ok
        for name in ("nu", "S_diag", "test_ratio"):
            np.testing.assert_array_equal(getattr(ia, name), getattr(ib, name))
