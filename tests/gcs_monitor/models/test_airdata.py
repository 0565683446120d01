"""Wan2018 air-data model: equations vs hand values, Jacobians vs finite differences."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_monitor.core.atmosphere import cas_from_tas
from gcs_monitor.core.constants import GRAVITY_STD_MPS2
from gcs_monitor.models.airdata import (
    AirDataModel,
    AirDataModelParams,
    WindEnvelope,
    airdata_derivative,
    airdata_f,
    airdata_f_jac_u,
    airdata_f_jac_x,
    airdata_h,
    airdata_h_jac_x,
    airdata_initial_state,
    cas_from_tas_with_derivative,
    envelope_bounds,
)
from tests.reference import airdata as ref

P = AirDataModelParams()


def _random_point(rng: np.random.Generator, lateral: bool = False
                  ) -> tuple[np.ndarray, np.ndarray]:
    x = np.array(
        [rng.uniform(-0.05, 0.2), rng.uniform(80, 190), rng.uniform(-30, 30), rng.uniform(-5, 5)]
    )
    th = np.array(
        [
            rng.uniform(80, 190),
            rng.uniform(-0.1, 0.25),
            rng.uniform(-0.1, 0.1),
            rng.uniform(-2, 3),
            rng.uniform(-15, -5),
            rng.uniform(0, 10000),
        ]
    )
    if lateral:  # bank and sideslip (airdata.lateral)
        th = np.concatenate((th, [rng.uniform(-0.6, 0.6), rng.uniform(-0.06, 0.06)]))
    return x, th


def test_level_unaccelerated_flight_is_an_equilibrium() -> None:
    """alpha = theta, A_x = g sin(theta), A_z = -g cos(theta), q = 0: f_alpha = f_v = 0."""
    th_rad = 0.04
    x = np.array([th_rad, 120.0, 0.0, 0.0])
    theta_p = np.array(
        [
            120.0,
            th_rad,
            0.0,
            GRAVITY_STD_MPS2 * math.sin(th_rad),
            -GRAVITY_STD_MPS2 * math.cos(th_rad),
            1000.0,
        ]
    )
    np.testing.assert_allclose(airdata_derivative(x, theta_p, P), 0.0, atol=1e-12)
    y = airdata_h(x, theta_p)
    assert y[1] == pytest.approx(0.0, abs=1e-12)  # no climb
    assert y[3] == pytest.approx(cas_from_tas(120.0, 1000.0), rel=1e-12)


def test_hand_values() -> None:
    """A pull-up: q and normal load raise alpha_dot; headwind W_x < 0 raises V_t (eq. 11)."""
    x = np.array([0.0, 100.0, -10.0, 2.0])
    theta_p = np.array([100.0, 0.0, 0.05, 1.0, -2.0 * GRAVITY_STD_MPS2, 0.0])
    xd = airdata_derivative(x, theta_p, P)
    # f_alpha = A_z + g = -g ; alpha_dot = -g / 100 + 0.05
    assert xd[0] == pytest.approx(-GRAVITY_STD_MPS2 / 100.0 + 0.05, rel=1e-12)
    assert xd[1] == pytest.approx(1.0, rel=1e-12)  # A_x
    y = airdata_h(x, theta_p)
    assert y[1] == pytest.approx(-2.0)  # W_z = 2 m/s down -> V_z = -2 m/s (up positive)
    assert y[3] == pytest.approx(cas_from_tas(110.0, 0.0), rel=1e-12)  # sea level: CAS = TAS
    assert y[3] == pytest.approx(110.0, rel=1e-12)
    eq13 = AirDataModelParams(wind_accel_in_alpha=False)
    xn = airdata_f(x, np.array([0.1, 0.2, 0.3, 0.4]), theta_p, 0.05, eq13)
    np.testing.assert_allclose(xn, x + 0.05 * (xd + [0.1, 0.2, 0.3, 0.4]), rtol=1e-14)
    # eq. 8 term, alpha = theta = 0: + t_s (0.3 sin 0 - 0.4 cos 0) / V_g = -0.05 * 0.4 / 100
    xn8 = airdata_f(x, np.array([0.1, 0.2, 0.3, 0.4]), theta_p, 0.05, P)
    assert xn8[0] - xn[0] == pytest.approx(-0.05 * 0.4 / 100.0, rel=1e-12)
    np.testing.assert_array_equal(xn8[1:], xn[1:])


@pytest.mark.parametrize("alt_m", [0.0, 1524.0, 9000.0])
def test_cas_matches_core_atmosphere(alt_m: float) -> None:
    for tas in (60.0, 120.0, 190.0):
        cas, dcas = cas_from_tas_with_derivative(tas, alt_m)
        assert cas == pytest.approx(cas_from_tas(tas, alt_m), rel=1e-13)
        h = 1e-4
        fd = (cas_from_tas(tas + h, alt_m) - cas_from_tas(tas - h, alt_m)) / (2 * h)
        assert dcas == pytest.approx(fd, rel=1e-8)


@pytest.mark.parametrize("lateral", [False, True])
@pytest.mark.parametrize("seed", range(5))
def test_jacobians_against_central_differences(seed: int, lateral: bool) -> None:
    rng = np.random.default_rng(seed)
    x, th = _random_point(rng, lateral)
    u = rng.standard_normal(4)
    dt = 0.05
    eps = np.array([1e-5, 1e-3, 1e-3, 1e-3])
    a_fd = np.zeros((4, 4))
    c_fd = np.zeros((4, 4))
    for j in range(4):
        e = np.zeros(4)
        e[j] = eps[j]
        a_fd[:, j] = (airdata_f(x + e, u, th, dt, P) - airdata_f(x - e, u, th, dt, P)) / (
            2 * eps[j]
        )
        c_fd[:, j] = (airdata_h(x + e, th) - airdata_h(x - e, th)) / (2 * eps[j])
    # Central differences: O(eps^2) truncation; the CAS power chain loses ~1e-14 relative,
    # divided by eps -> ~1e-7 relative.
    np.testing.assert_allclose(airdata_f_jac_x(x, th, dt, P, u), a_fd, rtol=1e-7, atol=1e-8)
    np.testing.assert_allclose(airdata_h_jac_x(x, th), c_fd, rtol=1e-6, atol=1e-8)
    b_fd = np.zeros((4, 4))
    for j in range(4):
        e = np.zeros(4)
        e[j] = 1e-3
        b_fd[:, j] = (airdata_f(x, u + e, th, dt, P) - airdata_f(x, u - e, th, dt, P)) / 2e-3
    np.testing.assert_allclose(airdata_f_jac_u(dt, x, th, P), b_fd, atol=1e-12)
    # Remark 1: a_12 = c_22 = 0 (V_g enters through the measured Theta)
    assert airdata_f_jac_x(x, th, dt, P, u)[0, 1] == 0.0
    assert airdata_h_jac_x(x, th)[1, 1] == 0.0


def test_initial_state_inverts_the_output() -> None:
    rng = np.random.default_rng(11)
    x, th = _random_point(rng)
    x[1] = th[0]
    y = airdata_h(x, th)
    x0 = airdata_initial_state(y[2], y[3], th, wind_z_mps=x[3])
    np.testing.assert_allclose(x0, x, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("lateral", [False, True])
def test_kernel_horizon_linearisation_matches_reference(lateral: bool) -> None:
    """models/_airdata_jit.py: A, B, masked C and r_y over a horizon (Wan2018 eq. 42) equal the
    plain-float reference (tests/reference/airdata.py) node by node, with one output masked;
    the defects equal the Python transition airdata_f (its own rounding of the eq. 8 term,
    _airdata_jit module docstring)."""
    rng = np.random.default_rng(4)
    model = AirDataModel()
    big_n, n = 4, 3
    pts = [_random_point(rng, lateral) for _ in range(big_n)]
    x_lin = np.array([p[0] for p in pts])
    th = np.array([p[1] for p in pts])
    u_lin = 0.01 * rng.standard_normal((big_n - 1, 4))
    dts = np.full(big_n, 0.05)
    mk = np.ones((big_n, 4))
    mk[1, 3] = 0.0  # CAS lost at node 1 (Wan2018 sec. V-C)
    ym = np.array([model.h(x_lin[i], th[i]) for i in range(big_n)])
    ym += rng.standard_normal((big_n, 4))
    ym *= mk
    out = [np.zeros((big_n - 1, 4, 4)), np.zeros((big_n - 1, 4, 4)), np.zeros((big_n - 1, 4)),
           np.zeros((big_n, 4, 4)), np.zeros((big_n, 4))]  # fmt: skip
    assert model.linearise_horizon(n, x_lin, u_lin, th, dts, ym, mk, *out)
    a, b, f, cm, ry = out
    for i in range(n):
        # same expressions in the same order: a few ulp
        np.testing.assert_allclose(cm[i], ref.airdata_h_jac_x(x_lin[i], th[i]) * mk[i][:, None],
                                   rtol=1e-13, atol=1e-13)  # fmt: skip
        np.testing.assert_allclose(ry[i], (ym[i] - ref.airdata_h(x_lin[i], th[i])) * mk[i],
                                   rtol=1e-12, atol=1e-11)  # fmt: skip
        if i < n - 1:
            np.testing.assert_allclose(a[i], ref.airdata_f_jac_x(x_lin[i], th[i], dts[i], P,
                                                                 u_lin[i]),
                                       rtol=1e-13, atol=1e-15)  # fmt: skip
            np.testing.assert_array_equal(b[i], ref.airdata_f_jac_u(dts[i], x_lin[i], th[i], P))
            f_ref = model.f(x_lin[i], u_lin[i], th[i], dts[i]) - x_lin[i + 1]
            np.testing.assert_allclose(f[i], f_ref, rtol=1e-12, atol=1e-11)
    # rows from n on are left untouched
    assert not np.any(cm[n:]) and not np.any(ry[n:]) and not np.any(a[n - 1 :])


@pytest.mark.parametrize("lateral", [False, True])
def test_model_functions_match_reference(lateral: bool) -> None:
    """The model functions (wrapping the kernels) against the plain-float reference: the same
    expressions in the same order, identical numbers."""
    rng = np.random.default_rng(6)
    for _ in range(50):
        x, th = _random_point(rng, lateral)
        u = rng.standard_normal(4)
        for p in (P, AirDataModelParams(wind_accel_in_alpha=False)):
            np.testing.assert_array_equal(airdata_f_jac_x(x, th, 0.05, p, u),
                                          ref.airdata_f_jac_x(x, th, 0.05, p, u))
            np.testing.assert_array_equal(airdata_f_jac_u(0.05, x, th, p),
                                          ref.airdata_f_jac_u(0.05, x, th, p))
        np.testing.assert_array_equal(airdata_f_jac_u(0.05), ref.airdata_f_jac_u(0.05))
        np.testing.assert_array_equal(airdata_h(x, th), ref.airdata_h(x, th))
        np.testing.assert_array_equal(airdata_h_jac_x(x, th), ref.airdata_h_jac_x(x, th))
        assert (cas_from_tas_with_derivative(x[1], th[5])
                == ref.cas_from_tas_with_derivative(x[1], th[5]))


# ------------------------------------------------------------------------------------------
# Wind bounds from a declared envelope (eq. 21b): hand-derived values of envelope_bounds
# ------------------------------------------------------------------------------------------


def test_envelope_calm_gives_the_model_margins() -> None:
    env = WindEnvelope(wind_mps=0.0, wind_z_mps=0.0, shear_rate_mps2=0.0)
    b = envelope_bounds(env, 150.0, 0.05, 0.0)
    assert b.wind_x_max_mps == pytest.approx(env.model_margin_mps, abs=1e-12)
    assert b.wind_z_max_mps == pytest.approx(env.model_margin_mps, abs=1e-12)
    assert b.rate_x_max_mps2 == pytest.approx(env.model_rate_margin_mps2, abs=1e-12)
    assert b.rate_z_max_mps2 == pytest.approx(env.model_rate_margin_mps2, abs=1e-12)


def test_envelope_turbulence_by_hand() -> None:
    """sigma 2 m/s, L 500 m, V 100 m/s: tau = 5 s; over t_s = 0.05 s a first-order Markov gust
    changes with sd 2 sqrt(2 (1 - e^-0.01)) = 0.282137 m/s; 3 of those / t_s = 16.928 m/s^2."""
    env = WindEnvelope(wind_mps=0.0, wind_z_mps=0.0, shear_rate_mps2=0.0,
                       turbulence_sigma_mps=2.0, turbulence_scale_m=500.0)
    b = envelope_bounds(env, 100.0, 0.05, 0.0)
    step_sd = 2.0 * math.sqrt(2.0 * (1.0 - math.exp(-0.01)))
    assert step_sd == pytest.approx(0.282137, abs=1e-6)
    rate = 3.0 * step_sd / 0.05 + 0.5
    assert b.rate_x_max_mps2 == pytest.approx(rate, rel=1e-12)
    assert b.rate_z_max_mps2 == pytest.approx(rate, rel=1e-12)
    # |W_x| <= 3 sigma + (3 sigma)^2 / (2 V) (eq. 11) + 2;  |W_z| <= 3 sigma (1 + sin 10 deg) + 2
    assert b.wind_x_max_mps == pytest.approx(6.0 + 36.0 / 200.0 + 2.0, rel=1e-12)
    assert b.wind_z_max_mps == pytest.approx(6.0 * (1.0 + math.sin(math.radians(10.0))) + 2.0,
                                             rel=1e-12)


def test_envelope_turn_adds_heading_rate_times_wind() -> None:
    """30 deg bank at 100 m/s: heading rate g tan 30 / 100; W_x,max = 10 + 100/200 = 10.5."""
    env = WindEnvelope(wind_mps=10.0, wind_z_mps=0.0, shear_rate_mps2=0.0,
                       model_margin_mps=0.0, model_rate_margin_mps2=0.0)
    level = envelope_bounds(env, 100.0, 0.05, 0.0)
    turn = envelope_bounds(env, 100.0, 0.05, math.radians(30.0))
    assert level.rate_x_max_mps2 == 0.0
    expected = 10.5 * GRAVITY_STD_MPS2 * math.tan(math.radians(30.0)) / 100.0
    assert turn.rate_x_max_mps2 == pytest.approx(expected, rel=1e-12)
    assert turn.rate_z_max_mps2 == 0.0  # the heading rate does not move the vertical wind
    assert turn.wind_x_max_mps == level.wind_x_max_mps == pytest.approx(10.5, rel=1e-12)


def test_envelope_bounds_grow_with_the_weather() -> None:
    """Invariant: more wind, shear or turbulence never shrinks the box."""
    rng = np.random.default_rng(5)
    for _ in range(50):
        a = WindEnvelope(wind_mps=rng.uniform(0, 30), shear_mps=rng.uniform(0, 10),
                         turbulence_sigma_mps=rng.uniform(0, 3), shear_rate_mps2=rng.uniform(0, 2))
        bigger = WindEnvelope(wind_mps=a.wind_mps + 1, shear_mps=a.shear_mps + 1,
                              turbulence_sigma_mps=a.turbulence_sigma_mps + 0.5,
                              shear_rate_mps2=a.shear_rate_mps2 + 0.1)
        v, roll = rng.uniform(80, 190), rng.uniform(-0.5, 0.5)
        b0, b1 = envelope_bounds(a, v, 0.05, roll), envelope_bounds(bigger, v, 0.05, roll)
        assert b1.wind_x_max_mps > b0.wind_x_max_mps
        assert b1.wind_z_max_mps > b0.wind_z_max_mps
        assert b1.rate_x_max_mps2 > b0.rate_x_max_mps2
        assert b1.rate_z_max_mps2 > b0.rate_z_max_mps2


def test_eq8_wind_acceleration_moves_alpha_with_a_vertical_gust() -> None:
    """Eq. 8 term: a vertical wind input u_wz over t_s changes alpha by -t_s u_wz cos(d) / V_g
    and W_z by t_s u_wz, so V_z (eq. 15) changes only by -t_s u_wz sin(d)^2 (d = alpha - theta):
    a gust changes the angle of attack, not the ground path. Without the term (eq. 13) alpha
    does not move and V_z takes the whole -t_s u_wz."""
    th = np.array([150.0, 0.05, 0.0, 0.5, -9.7, 3000.0])
    x = np.array([0.06, 150.0, 5.0, 1.0])
    u = np.array([0.0, 0.0, 0.0, 12.0])  # 12 m/s^2 vertical gust rate
    dt = 0.05
    d = x[0] - th[1]
    for p, dalpha_expected in ((P, -dt * 12.0 * math.cos(d) / 150.0),
                               (AirDataModelParams(wind_accel_in_alpha=False), 0.0)):
        x1 = airdata_f(x, u, th, dt, p)
        x0 = airdata_f(x, np.zeros(4), th, dt, p)
        assert x1[0] - x0[0] == pytest.approx(dalpha_expected, rel=1e-12, abs=1e-15)
        assert x1[3] - x0[3] == pytest.approx(dt * 12.0, rel=1e-12)
    x1, x0 = airdata_f(x, u, th, dt, P), airdata_f(x, np.zeros(4), th, dt, P)
    dvz = airdata_h(x1, th)[1] - airdata_h(x0, th)[1]
    assert abs(dvz) < dt * 12.0 * math.sin(d) ** 2 + 1e-6  # second order in d (+ O(dalpha^2))


def test_lateral_terms_reduce_to_the_paper_and_match_the_kinematics() -> None:
    """With phi = beta = 0 the 8-entry Theta gives Wan2018's eqs. 13-15 exactly; with bank and
    sideslip V_z is the vertical component of the air velocity (body FRD -> NED by phi, theta)."""
    rng = np.random.default_rng(21)
    for _ in range(20):
        x, th = _random_point(rng)
        th8 = np.concatenate((th, [0.0, 0.0]))
        np.testing.assert_allclose(airdata_h(x, th8), airdata_h(x, th), rtol=1e-13, atol=1e-12)
        np.testing.assert_allclose(airdata_derivative(x, th8, P), airdata_derivative(x, th, P),
                                   rtol=1e-13, atol=1e-13)
    # no wind, V_g = V: V_z(up) = -(C_nb v_b)_down for v_b = V [ca cb, sb, sa cb]
    v, alpha, beta, phi, theta = 250.0, 0.04, 0.05, -0.55, 0.03
    th8 = np.array([v, theta, 0.0, 0.0, -9.8, 5000.0, phi, beta])
    vb = v * np.array([math.cos(alpha) * math.cos(beta), math.sin(beta),
                       math.sin(alpha) * math.cos(beta)])
    sp, cp, st, ct = math.sin(phi), math.cos(phi), math.sin(theta), math.cos(theta)
    down = -st * vb[0] + sp * ct * vb[1] + cp * ct * vb[2]  # third row of C_nb at psi = 0
    y = airdata_h(np.array([alpha, v, 0.0, 0.0]), th8)
    assert y[1] == pytest.approx(-down, rel=1e-12)
    # the wings-level form is off by degrees of flight path here (Wan2018 eq. 15)
    y6 = airdata_h(np.array([alpha, v, 0.0, 0.0]), th8[:6])
    assert abs(y6[1] - y[1]) > 0.01 * v
    # gravity along the body normal (alpha_dot) carries cos(phi): level turn at 30 deg bank
    x = np.array([0.05, 200.0, 0.0, 0.0])
    th_turn = np.array([200.0, 0.05, 0.0, 0.0, 0.0, 1000.0, math.radians(30.0), 0.0])
    g_a = (airdata_derivative(x, th_turn, P)[0] - 0.0) * 200.0  # (A = 0, q = 0) -> g_alpha
    assert g_a == pytest.approx(GRAVITY_STD_MPS2 * (math.cos(0.05) ** 2 * math.cos(math.radians(30))
                                                    + math.sin(0.05) ** 2), rel=1e-12)
