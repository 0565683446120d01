"""Chen2020 LPV sliding-mode observer: LMI design, error dynamics, fault reconstruction on the
linear model, equivalent output injection by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_monitor.families.yaw_rate.design import load_design
from gcs_monitor.filters.lpv_smo import (
    SmoDesign,
    error_dynamics,
    partition,
    smo_init,
    smo_matrices,
    smo_step,
)
from gcs_monitor.filters.lpv_smo_design import a11_margin, design_l1

DESIGN = load_design("transport")
MODEL = DESIGN.model
A_F = np.array([[0.01]])  # Chen2020 sec. V
M_P = np.array([[0.0, 0.0], [0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])  # Chen2020 eq. 60
# with uncertainty in the beta channel as well (a roll-angle fault's e~_1 sees no xi of eq. 60:
# its bound is degenerate, gamma -> 0)
M_P3 = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])


def _vertices() -> list[np.ndarray]:
    return [MODEL.at_rho(*r)[0] for r in MODEL.vertices()]


@pytest.mark.parametrize("faulty", [(3,), (2,), (1,)])
def test_lmi_feasible_and_error_dynamics_stable(faulty: tuple[int, ...]) -> None:
    """Assumption 3.1 + the bounded real lemma at the vertices: feasible for every lateral
    sensor; the error dynamics (eq. 14) are then stable at the vertices and across the speeds."""
    res = design_l1(_vertices(), faulty, A_F, M_P if faulty[0] >= 2 else M_P3, l1_max=1.0)
    assert res.status == "optimal"
    assert np.isfinite(res.gamma) and res.gamma > 0.0
    assert np.linalg.norm(res.L1, 2) <= 1.0 + 1e-6
    d = SmoDesign(faulty, A_F, 0.1, res.L1, 0.8, 0.01, res.gamma)
    lo, hi = MODEL.eas_range_mps
    mats = [MODEL.at_rho(*r)[0] for r in MODEL.vertices()]
    mats += [MODEL.matrices(v)[0] for v in np.linspace(lo, hi, 7)]
    for Ap in mats:
        assert a11_margin(Ap, faulty, A_F, res.L1) < 0.0
        eig = np.linalg.eigvals(error_dynamics(Ap, d))
        assert np.max(eig.real) < 0.0
        # block triangular (eq. 14): -k2 (n times) and the eigenvalues of A11 + L1 A211
        assert np.sum(np.isclose(eig, -0.1, atol=1e-9)) >= 4


def test_roll_angle_fault_is_barely_detectable() -> None:
    """A roll-angle fault: A_11 = 0 and A_211 carries only g cos(theta) / V of the sideslip row,
    which the affine fit with rho_1, rho_2 independent nearly cancels at a vertex: the bound is
    three orders of magnitude above the rate sensors' (docs/papers-notes.md, Chen2020)."""
    res = design_l1(_vertices(), (0,), A_F, M_P3, l1_max=1.0)
    assert res.status.startswith("optimal")
    assert res.gamma > 100.0


def test_error_dynamics_is_block_triangular_by_hand() -> None:
    """T_L (A + G_l C) T_L^-1 = [[A11 + L1 A211, 0], [A21, -k2 I]] (derived from eq. 10)."""
    d = DESIGN.sensors["r"]
    Ap = MODEL.matrices(120.0)[0]
    Ae = error_dynamics(Ap, d)
    blk = partition(Ap, d.faulty, d.A_f)
    np.testing.assert_allclose(Ae[:1, :1], blk["A11"] + d.L1 @ blk["A211"], atol=1e-12)
    np.testing.assert_allclose(Ae[:1, 1:], 0.0, atol=1e-12)
    np.testing.assert_allclose(Ae[1:, :1], blk["A21"], atol=1e-12)
    np.testing.assert_allclose(Ae[1:, 1:], -d.k2 * np.eye(4), atol=1e-12)
    np.testing.assert_allclose(blk["A212"], d.A_f)  # the filter row: e_f = -e~_1 (eq. 22)


def test_injection_and_fault_estimate_by_hand() -> None:
    """nu = -k e_y / (||e_y|| + delta) (eq. 7 smoothed) and f_hat = A_f^-1 nu_f (eq. 21)."""
    d = DESIGN.sensors["r"]
    mats = smo_matrices(MODEL.A, MODEL.B, MODEL.c, d)
    y = np.array([0.1, 0.02, 0.01, 0.05])
    s = smo_init(mats, y)
    # move the estimate of z_f by 0.003 and of phi by -0.004: e_y = [-0.004, 0, 0, 0.003]
    z = s.z.copy()
    z[1] -= 0.004  # order [r; phi, beta, p; z_f]
    z[4] += 0.003
    s = type(s)(z, s.z_f)
    _, out = smo_step(s, mats, y, np.zeros(2), (120.0, 120.0 ** 2), 0.02)
    e_y = np.array([-0.004, 0.0, 0.0, 0.003])
    np.testing.assert_allclose(out.e_y, e_y, atol=1e-15)
    nu = -d.k * e_y / (0.005 + d.delta)  # ||e_y|| = 0.005
    np.testing.assert_allclose(out.nu, nu, rtol=1e-12)
    assert out.f_hat[0] == pytest.approx(nu[3] / 0.01, rel=1e-12)


def _simulate(fault: np.ndarray, sensor: str, eas: float, n: int, dt: float,
              rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The linear LPV plant (no uncertainty) under a light stabilising loop and random
    excitation; the observer on its outputs with ``fault`` added to the sensor."""
    d = DESIGN.sensors[sensor]
    j = d.faulty[0]
    mats = smo_matrices(MODEL.A, MODEL.B, MODEL.c, d)
    A, B, _ = MODEL.matrices(eas)
    x = np.zeros(4)
    s = None
    f_hat = np.zeros(n)
    exc = np.zeros(2)
    for k in range(n):
        if k % 200 == 0:
            exc = rng.normal(0.0, 0.01, 2)
        u = exc - np.array([0.5 * x[0] + 0.5 * x[2], -1.0 * x[3]])  # roll hold, yaw damper
        y = x.copy()
        y[j] += fault[k]
        if s is None:
            s = smo_init(mats, y)
        s, out = smo_step(s, mats, y, u, (eas, eas * eas), dt)
        f_hat[k] = out.f_hat[0]
        x = x + dt * (A @ x + B @ u)
    return f_hat, x


@pytest.mark.parametrize("sensor", ["r", "p"])
def test_reconstructs_constant_and_ramp_faults_on_the_linear_model(sensor: str) -> None:
    """No uncertainty (xi = 0): e~_1 -> 0 and f_hat -> f (eq. 22) for a bias and a ramp."""
    dt = 0.02
    n = 6000  # 120 s
    t = np.arange(n) * dt
    rng = np.random.default_rng(5)
    bias = np.where(t >= 30.0, 3.0 * math.pi / 180, 0.0)
    ramp = np.clip((t - 30.0) * 0.1 * math.pi / 180, 0.0, 5.0 * math.pi / 180)  # Chen2020
    for f in (bias, ramp):
        f_hat, _ = _simulate(f, sensor, 120.0, n, dt, rng)
        late = t >= 90.0
        # rad/s: a ramp's equivalent injection lags by the boundary layer's time constant
        np.testing.assert_allclose(f_hat[late], f[late], atol=2e-3 * math.pi / 180 * 10)
        np.testing.assert_allclose(f_hat[(t > 5.0) & (t < 29.0)], 0.0, atol=1e-3)


def test_closed_loop_bound_with_the_simulators_autopilot() -> None:
    """Chen2020 eq. 58 with the simulator's autopilot as controller: the loop is stable, the
    bound LMI feasible, and designing L_1 jointly does not do worse than the shipped one."""
    from gcs_monitor.filters.lpv_smo_design import ClosedLoopBlock
    from sim_vehicle.dynamics.linearise import lateral_closed_loop, lateral_lti

    ltis = [lateral_lti("transport", v, 1500.0) for v in (90.0, 180.0)]
    blocks = []
    for lt in ltis:
        A, H, C = lateral_closed_loop("transport", lt)
        assert np.max(np.linalg.eigvals(A).real) < 0.0
        assert H[3, 0] > 0.0  # r' grows with e_f: the loop reads r - e_f (eq. 24)
        blocks.append(ClosedLoopBlock(A, H, np.vstack([M_P, np.zeros((2, 2))]), C))
    d = DESIGN.sensors["r"]
    Ap = [lt.A for lt in ltis]
    fixed = design_l1(Ap, d.faulty, A_F, M_P, l1_max=1.0, closed_loop=blocks, L1_fixed=d.L1)
    joint = design_l1(Ap, d.faulty, A_F, M_P, l1_max=1.0, closed_loop=blocks)
    assert fixed.status == joint.status == "optimal"
    assert 0.0 < joint.gamma <= fixed.gamma * (1 + 1e-6)


def test_kernel_equals_the_numpy_reference() -> None:
    """The numba step and tests/reference/lpv_smo.py on 500 random steps (same arithmetic up
    to summation order: 1e-12 relative)."""
    from tests.reference.lpv_smo import smo_step_reference

    rng = np.random.default_rng(2)
    for sensor in ("r", "p"):
        mats = smo_matrices(MODEL.A, MODEL.B, MODEL.c, DESIGN.sensors[sensor])
        s = smo_init(mats, rng.normal(0.0, 0.05, 4))
        for _ in range(500):
            y, u = rng.normal(0.0, 0.05, 4), rng.normal(0.0, 0.02, 2)
            rho = (float(rng.uniform(80.0, 170.0)),) * 2
            rho = (rho[0], rho[0] ** 2)
            s1, o1 = smo_step(s, mats, y, u, rho, 0.02)
            s2, o2 = smo_step_reference(s, mats, y, u, rho, 0.02)
            np.testing.assert_allclose(s1.z, s2.z, rtol=1e-12, atol=1e-15)
            np.testing.assert_allclose(s1.z_f, s2.z_f, rtol=1e-12, atol=1e-15)
            for a, b in ((o1.f_hat, o2.f_hat), (o1.x_hat, o2.x_hat), (o1.e_y, o2.e_y),
                         (o1.nu, o2.nu)):
                np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-15)
            s = s1
