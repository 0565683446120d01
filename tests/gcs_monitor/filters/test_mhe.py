"""Tests of the real-time MHE solver (Wan2018 sec. V, Algorithms 1-2)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.optimize import minimize

from gcs_monitor.core.kernels import load_kernels
from gcs_monitor.filters.airdata_ekf import EkfState, ekf_update
from gcs_monitor.filters.mhe import (
    IpSettings,
    MheBounds,
    MheWeights,
    mhe_init,
    mhe_step,
)
from gcs_monitor.models.airdata import AirDataModel
from tests.reference.mhe import barrier_ip_qp, mhe_step_reference, riccati_direction


def _random_lq(rng: np.random.Generator, n: int, n_x: int, n_u: int, n_y: int):  # type: ignore[no-untyped-def]
    a = np.eye(n_x)[None] + 0.3 * rng.standard_normal((n - 1, n_x, n_x))
    b = rng.standard_normal((n - 1, n_x, n_u))
    cbar = rng.standard_normal((n, n_y, n_x))
    rbar = rng.uniform(0.5, 2.0, n_y)
    qbar = rng.uniform(0.2, 3.0, (n - 1, n_u))
    p = rng.uniform(0.5, 2.0, n_x)
    rx = rng.standard_normal(n_x)
    rubar = rng.standard_normal((n - 1, n_u))
    rybar = rng.standard_normal((n, n_y))
    rp = rng.standard_normal((n - 1, n_x))
    return p, a, b, cbar, rbar, qbar, rx, rubar, rybar, rp


def _ip_kernel(n, p, q, r, a, b, cm, f, ry, ru, dxl, dxu, dul, duu, ip):  # type: ignore[no-untyped-def]
    """filters/_mhe_jit.py's Algorithms 1-2 (ip_solve) with barrier_ip_qp's signature."""
    n_x, n_u = a.shape[1], b.shape[2]
    dx, du = np.zeros((cm.shape[0], n_x)), np.zeros((cm.shape[0] - 1, n_u))
    steps = np.zeros(ip.n_kappa * ip.n_qp)
    load_kernels("gcs_monitor.filters._mhe_jit").ip_solve(
        n, p, q, r, a, b, cm, f, ry, ru, dxl, dxu, dul, duu, ip.constrained, ip.n_kappa,
        ip.n_qp, ip.kappa_init, ip.kappa_factor, ip.n_s_max, dx, du, steps)
    return dx, du, steps


# the QP solver of the CMHE step (Wan2018 Algorithms 1-2): the kernel and its numpy reference
IP_SOLVERS = {"kernel": _ip_kernel, "reference": barrier_ip_qp}


def _dense_kkt(p, a, b, cbar, rbar, qbar, rx, rubar, rybar, rp):  # type: ignore[no-untyped-def]
    """Solve the linear MHE (45) through its full KKT system, no structure used."""
    n, n_x, n_u = cbar.shape[0], a.shape[1], b.shape[2]
    nz = n * n_x + (n - 1) * n_u
    h = np.zeros((nz, nz))
    g = np.zeros(nz)
    ri = np.diag(1.0 / rbar)
    for i in range(n):
        sl = slice(i * n_x, (i + 1) * n_x)
        h[sl, sl] += cbar[i].T @ ri @ cbar[i]
        g[sl] += cbar[i].T @ ri @ rybar[i]
    h[:n_x, :n_x] += np.diag(1.0 / p)
    g[:n_x] += rx / p
    for i in range(n - 1):
        sl = slice(n * n_x + i * n_u, n * n_x + (i + 1) * n_u)
        h[sl, sl] += np.diag(1.0 / qbar[i])
        g[sl] += rubar[i] / qbar[i]
    ge = np.zeros(((n - 1) * n_x, nz))
    he = np.zeros((n - 1) * n_x)
    for i in range(n - 1):
        rows = slice(i * n_x, (i + 1) * n_x)
        ge[rows, (i + 1) * n_x : (i + 2) * n_x] = np.eye(n_x)
        ge[rows, i * n_x : (i + 1) * n_x] = -a[i]
        ge[rows, n * n_x + i * n_u : n * n_x + (i + 1) * n_u] = -b[i]
        he[rows] = -rp[i]
    kkt = np.block([[h, ge.T], [ge, np.zeros((ge.shape[0], ge.shape[0]))]])
    sol = np.linalg.solve(kkt, np.concatenate([g, he]))
    z = sol[:nz]
    return z[: n * n_x].reshape(n, n_x), z[n * n_x :].reshape(n - 1, n_u)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
@pytest.mark.parametrize("n", [1, 2, 3, 5])
def test_riccati_direction_equals_dense_kkt(seed: int, n: int) -> None:
    rng = np.random.default_rng(seed)
    args = _random_lq(rng, n, 4, 4, 6)
    d, e = riccati_direction(n, *args)
    d_ref, e_ref = _dense_kkt(*args)
    # Tight: both are exact direct solves of the same well-conditioned linear system
    # (cond ~ 1e2..1e3); the only difference is float64 round-off.
    np.testing.assert_allclose(d, d_ref, rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(e, e_ref, rtol=1e-9, atol=1e-10)


@pytest.mark.parametrize("solver", sorted(IP_SOLVERS))
def test_barrier_ip_converges_to_box_qp_solution(solver: str) -> None:
    """Algorithm 1 with many iterations vs scipy on a small box-constrained QP (42)."""
    barrier_ip_qp = IP_SOLVERS[solver]
    rng = np.random.default_rng(7)
    n, n_x, n_u, n_y = 3, 2, 2, 2
    p = np.array([1.0, 2.0])
    q = np.array([0.5, 0.5])
    r = np.array([0.1, 0.2])
    a = np.eye(n_x)[None] + 0.1 * rng.standard_normal((n - 1, n_x, n_x))
    b = 0.5 * np.eye(n_x)[None].repeat(n - 1, 0)
    cm = rng.standard_normal((n, n_y, n_x))
    f = 0.3 * rng.standard_normal((n - 1, n_x))
    ry = 3.0 * rng.standard_normal((n, n_y))  # large residuals so that bounds bind
    ru = 0.1 * rng.standard_normal((n - 1, n_u))
    dxl, dxu = np.full((n, n_x), -0.4), np.full((n, n_x), 0.4)
    dul, duu = np.full((n - 1, n_u), -0.3), np.full((n - 1, n_u), 0.3)

    def unpack(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return z[: n * n_x].reshape(n, n_x), z[n * n_x :].reshape(n - 1, n_u)

    def cost(z: np.ndarray) -> float:
        dx, du = unpack(z)
        j = 0.5 * np.sum(dx[0] ** 2 / p)
        j += 0.5 * np.sum((ru - du) ** 2 / q)
        for i in range(n):
            j += 0.5 * np.sum((ry[i] - cm[i] @ dx[i]) ** 2 / r)
        return float(j)

    def eq(z: np.ndarray) -> np.ndarray:
        dx, du = unpack(z)
        return np.concatenate(
            [dx[i + 1] - f[i] - a[i] @ dx[i] - b[i] @ du[i] for i in range(n - 1)]
        )

    # The cost is quadratic, so central differences give its exact gradient and Hessian
    # (up to round-off); SLSQP then gets exact derivatives.
    nz = n * n_x + (n - 1) * n_u
    eye = np.eye(nz)
    g0 = np.array([(cost(eye[j]) - cost(-eye[j])) / 2.0 for j in range(nz)])
    hess = np.array(
        [
            [
                (
                    cost(eye[i] + eye[j])
                    - cost(eye[i] - eye[j])
                    - cost(-eye[i] + eye[j])
                    + cost(-eye[i] - eye[j])
                )
                / 4.0
                for j in range(nz)
            ]
            for i in range(nz)
        ]
    )
    z0 = np.zeros(nz)
    jeq = np.array([(eq(eye[j]) - eq(-eye[j])) / 2.0 for j in range(nz)]).T
    bnds = [(-0.4, 0.4)] * (n * n_x) + [(-0.3, 0.3)] * ((n - 1) * n_u)
    ref = minimize(
        cost,
        z0,
        jac=lambda z: g0 + hess @ z,
        method="SLSQP",
        bounds=bnds,
        constraints=[{"type": "eq", "fun": eq, "jac": lambda z: jeq}],
        # ftol 1e-12: at 1e-15 SLSQP (scipy 1.1x) stops with "positive directional derivative"
        # (status 8) at its precision floor instead of reporting success.
        options={"ftol": 1e-12, "maxiter": 1000},
    )
    assert ref.success, ref.message
    dx_ref, du_ref = unpack(ref.x)
    n_active = np.sum(np.isclose(np.abs(ref.x), [0.4] * (n * n_x) + [0.3] * ((n - 1) * n_u)))
    assert n_active >= 2  # the test is only meaningful with active bounds

    ip = IpSettings(n_kappa=8, n_qp=6, kappa_init=1e-1, n_s_max=40)
    dx, du, steps = barrier_ip_qp(n, p, q, r, a, b, cm, f, ry, ru, dxl, dxu, dul, duu, ip)
    # Loose: the barrier solution sits O(kappa_final / distance) ~ 1e-8 / 1e-? inside an active
    # bound, and SLSQP itself stops at ~1e-7; 1e-4 is far below the bound widths (0.3-0.4).
    np.testing.assert_allclose(dx, dx_ref, atol=1e-4)
    np.testing.assert_allclose(du, du_ref, atol=1e-4)
    assert np.all(np.abs(dx) < 0.4) and np.all(np.abs(du) < 0.3)  # strictly feasible
    # The paper's real-time setting (n_kappa = n_QP = 2) gives a suboptimal but feasible point.
    dx2, du2, _ = barrier_ip_qp(n, p, q, r, a, b, cm, f, ry, ru, dxl, dxu, dul, duu, IpSettings())
    assert np.all(np.abs(dx2) < 0.4) and np.all(np.abs(du2) < 0.3)
    assert cost(np.concatenate([dx2.ravel(), du2.ravel()])) < cost(np.zeros_like(ref.x))


@pytest.mark.parametrize("solver", sorted(IP_SOLVERS))
def test_unconstrained_qp_is_solved_exactly_in_one_step(solver: str) -> None:
    """Without bounds, the first full Newton step solves the QP; later directions vanish
    (Algorithm 2's Riccati recursion against the dense KKT solve)."""
    barrier_ip_qp = IP_SOLVERS[solver]
    rng = np.random.default_rng(3)
    n, n_x = 3, 4
    a = np.eye(n_x)[None] + 0.1 * rng.standard_normal((n - 1, n_x, n_x))
    b = 0.05 * np.eye(n_x)[None].repeat(n - 1, 0)
    cm = rng.standard_normal((n, 4, n_x))
    f = rng.standard_normal((n - 1, n_x))
    ry = rng.standard_normal((n, 4))
    ru = rng.standard_normal((n - 1, n_x))
    inf = np.full((n, n_x), np.inf)
    p, q, r = np.ones(n_x), np.ones(n_x), np.ones(4)
    ip = IpSettings(constrained=False)
    dx, du, steps = barrier_ip_qp(
        n, p, q, r, a, b, cm, f, ry, ru, -inf, inf, -inf[:-1], inf[:-1], ip
    )
    d_ref, e_ref = _dense_kkt(p, a, b, cm, r, np.ones((n - 1, n_x)), np.zeros(n_x), ru, ry, -f)
    np.testing.assert_allclose(dx, d_ref, atol=1e-10)  # exact linear solve, round-off only
    np.testing.assert_allclose(du, e_ref, atol=1e-10)
    np.testing.assert_array_equal(steps, 1.0)


def test_umhe_n1_equals_ekf_update_with_prior_covariance_p() -> None:
    """Check documented in the report: UMHE with N = 1 is the EKF measurement update whose
    prior covariance is the (fixed) arrival weight P.

    With N = 1 the horizon holds no inputs, the cost is
    1/2|x - x^-|^2_{P^-1} + 1/2|y - h(x)|^2_{R^-1}, and one Gauss-Newton step from x^- gives
    x^- + K (y - h(x^-)), K = P C^T (C P C^T + R)^-1: the EKF update (and, because the arrival
    prior x^- = F(x_hat_{k-1|k-1}, 0), the EKF prediction) with P_{k|k-1} := P.
    """
    model = AirDataModel()
    theta = np.array([130.0, 0.05, 0.01, 0.5, -9.7, 1500.0])
    x0 = np.array([0.05, 130.0, -8.0, 0.5])
    w = MheWeights(
        p_diag=np.array([1e-4, 1.0, 4.0, 1.0]),
        q_diag=np.ones(4),
        r_diag=np.array([0.04, 0.04, 3e-5, 0.3]),
    )
    y = model.h(x0, theta) + np.array([0.3, -0.2, 0.003, 1.5])
    mask = np.ones(4)
    s = mhe_init(x0, y, mask, theta, horizon_n=1, n_u=4)
    theta1 = theta + np.array([0.5, 0.001, 0.0, 0.1, 0.05, 2.0])
    s1, info = mhe_step(
        s, model, y, mask, theta1, 0.05, w, MheBounds.unbounded(4, 4), IpSettings(constrained=False)
    )
    x_prior = model.f(x0, np.zeros(4), theta, 0.05)
    ekf = ekf_update(EkfState(x=x_prior, P=np.diag(w.p_diag)), model, y, mask, theta1, w.r_diag)
    # Tight: the same linear algebra (one Gauss-Newton step = one EKF update), round-off only.
    np.testing.assert_allclose(s1.x[0], ekf.state.x, rtol=1e-10, atol=1e-12)
    assert info.numerics_ok


def test_cmhe_respects_wind_bounds_on_the_airdata_model() -> None:
    """A CAS measurement far off pulls W_x; the CMHE keeps W_x and u_wx inside their bounds."""
    model = AirDataModel()
    theta = np.array([130.0, 0.05, 0.0, 0.5, -9.79, 1500.0])
    x0 = np.array([0.05, 130.0, 0.0, 0.0])
    w = MheWeights(
        p_diag=np.array([1e-4, 1.0, 1e-2, 1e-2]),
        q_diag=np.array([1e-4, 1e-2, 1.0, 1.0]),
        r_diag=np.array([0.04, 0.04, 3e-5, 0.3]),
    )
    b = MheBounds(
        x_lb=np.array([-np.inf, -np.inf, -5.0, -3.0]),
        x_ub=np.array([np.inf, np.inf, 5.0, 3.0]),
        u_lb=np.array([-np.inf, -np.inf, -1.0, -1.0]),
        u_ub=np.array([np.inf, np.inf, 1.0, 1.0]),
    )
    mask = np.ones(4)
    y_true = model.h(x0, theta)
    s_c = mhe_init(x0, y_true, mask, theta, 3, 4)
    s_u = s_c
    for k in range(60):
        y = y_true + np.array([0, 0, 0, -0.4 * k])  # CAS runaway, 8 m/s^2 at 20 Hz
        s_c, _ = mhe_step(s_c, model, y, mask, theta, 0.05, w, b, IpSettings())
        s_u, _ = mhe_step(s_u, model, y, mask, theta, 0.05, w, b, IpSettings(constrained=False))
        assert np.all(s_c.x[: s_c.n, 2] > -5.0) and np.all(s_c.x[: s_c.n, 2] < 5.0)
        assert np.all(np.abs(s_c.u[: s_c.n - 1, 2]) < 1.0)
    # The UMHE absorbs the fault into the headwind estimate (W_x grows positive = tailwind
    # appears as lower airspeed); the CMHE cannot.
    assert s_u.x[s_u.n - 1, 2] > 10.0
    assert s_c.x[s_c.n - 1, 2] < 5.0


def test_horizon_shift_and_fixed_size() -> None:
    model = AirDataModel()
    theta = np.array([130.0, 0.05, 0.0, 0.5, -9.79, 1500.0])
    x0 = np.array([0.05, 130.0, 0.0, 0.0])
    w = MheWeights(np.ones(4), np.ones(4), np.ones(4))
    s = mhe_init(x0, model.h(x0, theta), np.ones(4), theta, 3, 4)
    shapes = (s.x.shape, s.u.shape)
    for k in range(5):
        s2, _ = mhe_step(
            s,
            model,
            model.h(x0, theta),
            np.ones(4),
            theta,
            0.05,
            w,
            MheBounds.unbounded(4, 4),
            IpSettings(),
        )
        assert (s2.x.shape, s2.u.shape) == shapes
        assert s2.n == min(k + 2, 3)
        assert s2 is not s and s2.x is not s.x  # a new state, the old one untouched
        s = s2
    assert replace(s, n=1).n == 1


class _MethodsOnly:
    """AirDataModel without its compiled ``linearise_horizon``: a generic MheModel."""

    def __init__(self) -> None:
        self._m = AirDataModel()
        self.n_x, self.n_u, self.n_y = 4, 4, 4
        self.f, self.f_jac_x, self.f_jac_u = self._m.f, self._m.f_jac_x, self._m.f_jac_u
        self.h, self.h_jac_x = self._m.h, self._m.h_jac_x


@pytest.mark.parametrize("horizon_n", [1, 3, 5])
@pytest.mark.parametrize("model_kind", ["airdata", "methods_only"])
def test_kernel_matches_numpy_reference(horizon_n: int, model_kind: str) -> None:
    """filters/_mhe_jit.py (+ the model's compiled linearisation, or its methods) against the
    numpy reference (tests/reference/mhe.py): CAS runaway into the wind bounds, a lost CAS
    sample (NaN, masked) and a bounds change that forces the interior clip."""
    model = AirDataModel() if model_kind == "airdata" else _MethodsOnly()
    theta = np.array([130.0, 0.05, 0.0, 0.5, -9.79, 1500.0])
    x0 = np.array([0.05, 130.0, 0.0, 0.0])
    w = MheWeights(
        np.array([1e-4, 1.0, 1e-2, 1e-2]),
        np.array([1e-4, 1e-2, 1.0, 1.0]),
        np.array([0.04, 0.04, 3e-5, 0.3]),
    )
    b_wide = MheBounds(
        np.array([-np.inf, -np.inf, -5.0, -3.0]),
        np.array([np.inf, np.inf, 5.0, 3.0]),
        np.array([-np.inf, -np.inf, -1.0, -1.0]),
        np.array([np.inf, np.inf, 1.0, 1.0]),
    )
    b_tight = replace(b_wide, x_lb=np.array([-np.inf, -np.inf, -2.0, -3.0]),
                      x_ub=np.array([np.inf, np.inf, 2.0, 3.0]))  # fmt: skip
    y0 = model.h(x0, theta)
    for constrained in (True, False):
        s_py = s_nb = mhe_init(x0, y0, np.ones(4), theta, horizon_n, 4)
        for k in range(40):
            y = y0 + np.array([0.0, 0.0, 0.0, -0.4 * k])
            mask = np.ones(4)
            if k % 7 == 3:  # CAS lost: NaN and its row of C zeroed (Wan2018 sec. V-C)
                y[3], mask[3] = np.nan, 0.0
            th = theta + np.array([0.1 * k, 0.0, 0.0, 0.0, 0.0, 1.0 * k])
            bnd = b_wide if k < 25 else b_tight
            out = []
            ip = IpSettings(constrained=constrained)
            for s, step in ((s_py, mhe_step_reference), (s_nb, mhe_step)):
                out.append(step(s, model, y, mask, th, 0.05, w, bnd, ip))
            (s_py, i_py), (s_nb, i_nb) = out
            assert s_nb.n == s_py.n
            n = s_py.n
            # Same algorithm, different summation order (Cholesky vs inv): round-off only.
            np.testing.assert_allclose(s_nb.x[:n], s_py.x[:n], rtol=1e-9, atol=1e-9)
            np.testing.assert_allclose(s_nb.u[: n - 1], s_py.u[: n - 1], rtol=1e-9, atol=1e-9)
            np.testing.assert_array_equal(s_nb.theta[:n], s_py.theta[:n])
            np.testing.assert_array_equal(s_nb.dt_s[: n - 1], s_py.dt_s[: n - 1])
            np.testing.assert_array_equal(s_nb.y[:n], s_py.y[:n])
            np.testing.assert_array_equal(s_nb.y_mask[:n], s_py.y_mask[:n])
            np.testing.assert_array_equal(i_nb.step_sizes, i_py.step_sizes)
            assert i_nb.n_active == i_py.n_active
            assert i_nb.numerics_ok and i_py.numerics_ok
        if constrained and horizon_n > 1:
            assert i_py.n_active > 0  # the runaway drove W_x onto its bound: the test saw it
