"""GS-KM / AS-KM (Lu2016 eqs. 11-20): Jacobians vs central differences, kinematics vs DCM."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_monitor.core import constants as c
from gcs_monitor.core.atmosphere import gravity_mps2
from gcs_monitor.core.frames import dcm_ned_frd
from gcs_monitor.filters.two_stage import discretise_series
from gcs_monitor.models import kinematics as km

SEEDS = [0, 1, 2, 3, 4]


def _rand_gs(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, float, float]:
    x = np.concatenate([rng.uniform(-80, 80, 3), rng.uniform(-1.2, 1.2, 2), rng.uniform(-3, 3, 1)])
    u = np.concatenate([rng.uniform(-15, 15, 3), rng.uniform(-1, 1, 3)])
    return x, u, rng.uniform(-1.2, 1.2), rng.uniform(0, 5000)


def _rand_as(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, float, float]:
    x = np.concatenate(
        [
            rng.uniform(30, 80, 1),
            rng.uniform(-10, 10, 2),
            rng.uniform(-1.2, 1.2, 2),
            rng.uniform(-3, 3, 1),
        ]
    )
    u = np.concatenate([rng.uniform(-15, 15, 3), rng.uniform(-1, 1, 3)])
    return x, u, rng.uniform(-1.2, 1.2), rng.uniform(0, 5000)


def _num_jac(fun, x: np.ndarray, eps: float) -> np.ndarray:
    cols = []
    for i in range(x.size):
        d = np.zeros_like(x)
        d[i] = eps
        cols.append((fun(x + d) - fun(x - d)) / (2 * eps))
    return np.stack(cols, axis=1)


@pytest.mark.parametrize("seed", SEEDS)
def test_gs_km_jacobians_match_central_differences(seed: int) -> None:
    rng = np.random.default_rng(seed)
    x, u, lat, alt = _rand_gs(rng)
    Fn = _num_jac(lambda xx: km.gs_km_f(xx, u, lat, alt), x, 1e-6)
    Bn = _num_jac(lambda uu: km.gs_km_f(x, uu, lat, alt), u, 1e-6)
    # atol: central-difference truncation + round-off on O(100) values with eps 1e-6 is ~1e-7
    np.testing.assert_allclose(km.gs_km_jac_x(x, u, lat, alt), Fn, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(km.gs_km_jac_u(x), Bn, rtol=1e-6, atol=1e-6)
    # fault jacobian: f(x, u_m - f) -> df/df = -df/du = G (Lu2016 eq. 13)
    Gn = _num_jac(lambda ff: km.gs_km_f(x, u - ff, lat, alt), np.zeros(6), 1e-6)
    np.testing.assert_allclose(km.gs_km_G(x), Gn, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(km.gs_km_jac_h(x), _num_jac(km.gs_km_h, x, 1e-6), atol=1e-8)
    F, G = km.GsKm(lat, alt).jacobians(x, u)
    np.testing.assert_array_equal(F, km.gs_km_jac_x(x, u, lat, alt))
    np.testing.assert_array_equal(G, km.gs_km_G(x))


@pytest.mark.parametrize("seed", SEEDS)
def test_as_km_jacobians_match_central_differences(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    x, u, lat, alt = _rand_as(rng)
    np.testing.assert_allclose(
        km.as_km_jac_x(x, u, lat, alt),
        _num_jac(lambda xx: km.as_km_f(xx, u, lat, alt), x, 1e-6),
        rtol=1e-6,
        atol=1e-6,
    )
    np.testing.assert_allclose(
        km.as_km_jac_u(x),
        _num_jac(lambda uu: km.as_km_f(x, uu, lat, alt), u, 1e-6),
        rtol=1e-6,
        atol=1e-6,
    )
    np.testing.assert_allclose(
        km.as_km_jac_h(x), _num_jac(km.as_km_h, x, 1e-6), rtol=1e-6, atol=1e-8
    )


def test_as_km_G_matches_printed_eq19() -> None:
    x = np.array([50.0, 2.0, 4.0, 0.1, 0.05, 1.0])
    ua, va, wa = x[:3]
    G = km.as_km_G(x)
    np.testing.assert_array_equal(G[0, :], [-1, 0, 0, 0, wa, -va])
    np.testing.assert_array_equal(G[1, :], [0, -1, 0, -wa, 0, ua])
    np.testing.assert_array_equal(G[2, :], [0, 0, -1, va, -ua, 0])
    h = km.as_km_h(x)
    assert h[0] == pytest.approx(math.sqrt(ua**2 + va**2 + wa**2))
    assert h[1] == pytest.approx(math.atan(wa / ua))


def test_gs_km_static_level_hover_is_gravity_balanced() -> None:
    # at rest over the earth, level, the accelerometer reads -g on z: U_dot = 0 exactly
    lat, alt = 0.9, 120.0
    g = gravity_mps2(lat, alt)
    xd = km.gs_km_f(np.zeros(6), np.array([0, 0, -g, 0, 0, 0]), lat, alt)
    np.testing.assert_allclose(xd[:3], 0.0, atol=1e-15)
    # body rates zero but the earth turns: the Euler angles of a body fixed to NED stay put only
    # if the gyro reads earth rate; with zero gyro the heading drifts at -Omega sin(lat) ... here
    # psi_dot = +Omega sin(delta) (eq. 11 row 6 last term, the body lags the turning NED frame).
    assert xd[5] == pytest.approx(c.EARTH_RATE_RADPS * math.sin(lat), rel=1e-12)


@pytest.mark.parametrize("seed", SEEDS)
def test_gs_km_euler_rates_agree_with_dcm_kinematics(seed: int) -> None:
    """dC_ned_frd/dt = C [w_ib x] - [w_in x] C with w_in = earth rate + transport rate (NED).

    This independent check fixes the sign of the psi_dot frame-rate term (see module doc).
    """
    rng = np.random.default_rng(200 + seed)
    x, u, lat, alt = _rand_gs(rng)
    rr = c.EARTH_RADIUS_M + alt
    om = c.EARTH_RATE_RADPS
    un, ue = x[0], x[1]
    w_in = np.array(
        [om * math.cos(lat) + ue / rr, -un / rr, -om * math.sin(lat) - ue * math.tan(lat) / rr]
    )

    def skew(v: np.ndarray) -> np.ndarray:
        return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])

    C = dcm_ned_frd(*x[3:])
    Cdot_ref = C @ skew(u[3:]) - skew(w_in) @ C
    eul_dot = km.gs_km_f(x, u, lat, alt)[3:]
    eps = 1e-7
    Cdot = (dcm_ned_frd(*(x[3:] + eps * eul_dot)) - dcm_ned_frd(*(x[3:] - eps * eul_dot))) / (
        2 * eps
    )
    np.testing.assert_allclose(Cdot, Cdot_ref, atol=1e-7)  # central-difference error ~eps^2


def test_discretise_matches_expm() -> None:
    from scipy.linalg import expm

    rng = np.random.default_rng(7)
    x, u, lat, alt = _rand_gs(rng)
    F, G = km.GsKm(lat, alt).jacobians(x, u)
    dt = 0.01
    Phi, Gam = discretise_series(F, G, dt)
    # Van Loan: exp([[F, G], [0, 0]] dt) = [[Phi, Gamma], [0, I]]
    M = np.zeros((12, 12))
    M[:6, :6] = F
    M[:6, 6:] = G
    E = expm(M * dt)
    # truncation after 3 terms of |F dt| ~ 1e-2: error ~ |F dt|^4/24 ~ 1e-9
    np.testing.assert_allclose(Phi, E[:6, :6], atol=1e-8)
    np.testing.assert_allclose(Gam, E[:6, 6:], atol=1e-10)


def test_propagate_is_second_order() -> None:
    rng = np.random.default_rng(3)
    x, u, lat, alt = _rand_gs(rng)
    m = km.GsKm(lat, alt)

    def err(dt: float) -> float:
        ref = x.copy()
        n = 64
        for _ in range(n):
            ref = m.propagate(ref, u, u, dt / n)
        return float(np.max(np.abs(m.propagate(x, u, u, dt) - ref)))

    ratio = err(0.02) / err(0.01)
    assert 6.0 < ratio < 10.0  # local error of Heun is O(dt^3): halving dt divides it by ~8


def test_kernel_gs_km_equals_reference_bitwise() -> None:
    """The GS-KM kernel (models/_kinematics_jit.py, which GsKm and gs_km_* wrap) evaluates the
    same expressions in the same order as the plain-float reference (tests/reference/
    kinematics.py): identical rates, propagation and Jacobians (signed zeros included)."""
    from gcs_monitor.core.atmosphere import gravity_mps2
    from gcs_monitor.core.kernels import load_kernels
    from gcs_monitor.models.kinematics import GsKm
    from tests.reference import kinematics as ref

    kin = load_kernels("gcs_monitor.models._kinematics_jit")
    rng = np.random.default_rng(11)
    for _ in range(100):
        x = rng.normal(size=6) * [50.0, 50.0, 5.0, 0.5, 0.3, 3.0]
        u0 = rng.normal(size=6) * [3.0, 3.0, 10.0, 0.3, 0.3, 0.3]
        u1 = u0 + rng.normal(size=6) * 0.01
        lat, alt = rng.uniform(-1.2, 1.2), rng.uniform(0.0, 5000.0)
        F, G = ref.jacobians(x, u0, lat, alt)
        F2, G2, xp2, r2 = np.zeros((6, 6)), np.zeros((6, 6)), np.zeros(6), np.zeros(6)
        kin.jacobians(x, u0, lat, alt, F2, G2)
        kin.propagate(x, u0, u1, lat, alt, gravity_mps2(lat, alt), 0.01, xp2)
        kin.rates(x, u0, lat, alt, gravity_mps2(lat, alt), r2)
        np.testing.assert_array_equal(F, F2)
        np.testing.assert_array_equal(G, G2)
        np.testing.assert_array_equal(np.signbit(G), np.signbit(G2))
        np.testing.assert_array_equal(ref.propagate(x, u0, u1, lat, alt, 0.01), xp2)
        np.testing.assert_array_equal(ref.gs_km_rates(list(x), list(u0), lat, alt,
                                                      gravity_mps2(lat, alt)), r2)
        # and the wrappers return the kernel's numbers
        mdl = GsKm(lat, alt)
        F3, G3 = mdl.jacobians(x, u0)
        np.testing.assert_array_equal(np.signbit(G3), np.signbit(G2))
        np.testing.assert_array_equal(F3, F2)
        np.testing.assert_array_equal(mdl.propagate(x, u0, u1, 0.01), xp2)
        np.testing.assert_array_equal(km.gs_km_f(x, u0, lat, alt), r2)
