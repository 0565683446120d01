"""Rigid body: attitude kinematics vs Lu2016 eq. 11 rows 4-6, helpers vs core, airframe files."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gcs_monitor.core import atmosphere as atm
from gcs_monitor.core.constants import EARTH_RADIUS_M, EARTH_RATE_RADPS
from gcs_monitor.core.frames import dcm_from_quat, quat_from_euler
from gcs_monitor.core.kernels import load_kernels
from sim_vehicle.autopilot.trim import level_state, trim_level
from sim_vehicle.dynamics.airframe import load_airframe
from sim_vehicle.dynamics.rigid_body import RigidBody, dcm_from_quat_fast, gravity_fast
from sim_vehicle.physics import euler_from_quat
from tests.reference import rigid_body as ref


def _euler_rates_lu2016(x: list[float], *, as_printed: bool = False) -> np.ndarray:
    """Lu2016 eq. 11 rows 4-6 (fault-free), from the paper.

    Row 6 as printed has ``+ (U_E/(R+h) + Omega c(delta)) t(theta) c(psi)``; projecting
    omega_in onto the yaw-rate axis ``[t(theta) c(psi), t(theta) s(psi), 1]`` gives a minus sign
    (rows 4 and 5 do have the consistent signs). We use the corrected sign unless ``as_printed``.
    """
    lat, _, h, un, ue, _ud = x[:6]
    ph, th, ps = euler_from_quat(*x[6:10])
    p, q, r = x[10:13]
    s, c, t = math.sin, math.cos, math.tan
    rh = EARTH_RADIUS_M + h
    om = EARTH_RATE_RADPS
    a = ue / rh + om * c(lat)
    return np.array(
        [
            p
            + q * s(ph) * t(th)
            + r * c(ph) * t(th)
            - a * c(ps) / c(th)
            + un * s(ps) / (rh * c(th)),
            q * c(ph) - r * s(ph) + a * s(ps) + un * c(ps) / rh,
            q * s(ph) / c(th)
            + r * c(ph) / c(th)
            + (1.0 if as_printed else -1.0) * a * t(th) * c(ps)
            + un * t(th) * s(ps) / rh
            + ue * t(lat) / rh
            + om * s(lat),
        ]
    )


@pytest.mark.parametrize("seed", range(5))
def test_attitude_kinematics_match_lu2016_eq11_rows_4_6(seed: int) -> None:
    rng = np.random.default_rng(seed)
    body = RigidBody(load_airframe("uav"))
    eul = rng.uniform([-1.0, -0.6, -3.0], [1.0, 0.6, 3.0])
    q = quat_from_euler(*eul)
    x = [
        rng.uniform(-1.2, 1.2),
        0.3,
        rng.uniform(0, 5000),
        *rng.uniform(-200, 200, 3),
        *q,
        *rng.uniform(-0.5, 0.5, 3),
        0.5,
    ]
    x = [float(v) for v in x]
    d, _ = body.evaluate(x, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0)
    # Euler rates by a tiny step along the quaternion derivative
    eps = 1e-5
    qv, dq = np.array(x[6:10]), np.array(d[6:10])
    e1 = np.array(euler_from_quat(*(qv + eps * dq)))
    e0 = np.array(euler_from_quat(*(qv - eps * dq)))
    num = (e1 - e0) / (
        2.0 * eps
    )  # central difference along q' (q' is tangent: |q| const to O(eps^2))
    np.testing.assert_allclose(num, _euler_rates_lu2016(x), atol=1e-8)  # rad/s, O(eps^2) error
    # the printed row 6 differs by exactly 2 (U_E/(R+h) + Omega cos(lat)) tan(theta) cos(psi)
    diff = _euler_rates_lu2016(x, as_printed=True)[2] - num[2]
    a = x[4] / (EARTH_RADIUS_M + x[2]) + EARTH_RATE_RADPS * math.cos(x[0])
    e = euler_from_quat(*x[6:10])
    assert math.isclose(
        diff, 2.0 * a * math.tan(e[1]) * math.cos(e[2]), rel_tol=1e-4, abs_tol=1e-10
    )


def test_trimmed_level_flight_gyro_reads_earth_and_transport_rate() -> None:
    body = RigidBody(load_airframe("transport"))
    lat = math.radians(52.0)
    tr = trim_level(body, lat, 0.1, 1000.0, 128.6, math.radians(90.0))
    x = list(tr.state)
    d, _ = body.evaluate(x, 0.0, tr.elevator_rad, 0.0, tr.throttle, 0.0, 0.0, 0.0)
    np.testing.assert_allclose(_euler_rates_lu2016(x), 0.0, atol=1e-12)  # attitude stays level
    w = np.array(x[10:13])
    ve = 128.6
    rh = EARTH_RADIUS_M + 1000.0
    w_in = np.array(
        [
            ve / rh + EARTH_RATE_RADPS * math.cos(lat),
            0.0,
            -ve * math.tan(lat) / rh - EARTH_RATE_RADPS * math.sin(lat),
        ]
    )
    c = dcm_from_quat(np.array(x[6:10]))
    np.testing.assert_allclose(w, c.T @ w_in, atol=1e-15)
    assert np.linalg.norm(w) > 5e-5  # a perfect gyro sees the earth rate
    # vertical and along-track accelerations vanish at trim
    assert abs(d[5]) < 1e-9 and abs(d[4]) < 1e-9


def test_dcm_and_euler_agree_with_scipy() -> None:
    rng = np.random.default_rng(0)
    for _ in range(20):
        eul = rng.uniform([-3.0, -1.5, -3.0], [3.0, 1.5, 3.0])
        q = quat_from_euler(*eul)
        c = np.array(dcm_from_quat_fast(*q)).reshape(3, 3)
        ref = Rotation.from_euler("ZYX", eul[::-1]).as_matrix()
        np.testing.assert_allclose(c, ref, atol=1e-12)
        np.testing.assert_allclose(euler_from_quat(*q), eul, atol=1e-9)


def test_fast_helpers_equal_core() -> None:
    rbj = load_kernels("sim_vehicle.dynamics._rigid_body_jit")
    for h in (0.0, 1000.0, 9000.0):
        assert math.isclose(rbj.isa_density(h), atm.isa_density_kgpm3(h), rel_tol=1e-12)
        for lat in (0.0, 0.7, -1.2):
            assert math.isclose(gravity_fast(lat, h), atm.gravity_mps2(lat, h), rel_tol=1e-12)


def test_level_state_flies_through_the_air_mass() -> None:
    body = RigidBody(load_airframe("uav"))
    x = level_state(body, 0.5, 0.0, 500.0, 25.0, 0.3, 0.05, 0.4, (3.0, -1.0, 0.0))
    assert math.isclose(math.hypot(x[3] - 3.0, x[4] + 1.0), 25.0)


def test_airframe_loader_rejects_unknown_keys(tmp_path: Path) -> None:
    src = (
        Path(__file__).resolve().parents[3] / "sim_vehicle" / "airframes" / "uav.toml"
    ).read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(src.replace("cl0 = 0.23", "cl0 = 0.23\ncl_bogus = 1.0"))
    with pytest.raises(ValueError, match="aero.cl_bogus"):
        load_airframe(bad)
    good = tmp_path / "good.toml"
    good.write_text(src)
    assert load_airframe(good).aero.cl0 == 0.23


def test_both_airframes_load_with_sources() -> None:
    for name in ("uav", "transport"):
        af = load_airframe(name)
        assert af.source and af.mass.mass_kg > 0 and af.default_tas_mps > 0


# --------------------------------------------------------------------------- compiled kernel
def _random_state(rng: np.random.Generator, tas: float) -> list[float]:
    q = quat_from_euler(*rng.uniform([-0.6, -0.3, -3.0], [0.6, 0.3, 3.0]))
    v = rng.normal(0.0, 0.1 * tas, 3) + np.array([tas, 0.0, 0.0])
    return [
        *rng.uniform([0.1, -1.0, 50.0], [1.2, 1.0, 9000.0]),
        *v,
        *(float(x) for x in q),
        *rng.normal(0.0, 0.2, 3),
        float(rng.uniform(0.0, 1.0)),
    ]


@pytest.mark.parametrize("name", ["uav", "transport"])
def test_kernel_matches_reference_evaluate_and_rk4(name: str) -> None:
    """_rigid_body_jit (evaluate, step) against the plain-float reference
    (tests/reference/rigid_body.py): same equations, same operation order."""
    rbj = load_kernels("sim_vehicle.dynamics._rigid_body_jit")
    af = load_airframe(name)
    body = RigidBody(af)
    prm = rbj.pack_params(body)
    rng = np.random.default_rng(7)
    for _ in range(20):
        x = _random_state(rng, af.default_tas_mps)
        inp0 = tuple(float(v) for v in rng.normal(0.0, [0.1, 0.1, 0.1, 0.3, 3, 3, 1]))
        inp1 = tuple(float(v) for v in rng.normal(0.0, [0.1, 0.1, 0.1, 0.3, 3, 3, 1]))
        d_ref, out_ref = ref.evaluate(body, x, *inp0)
        d, out = np.empty(14), np.empty(rbj.N_OUT)
        rbj.evaluate(np.array(x), np.array(inp0), prm, d, out)
        np.testing.assert_allclose(d, d_ref, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(out, out_ref, rtol=1e-12, atol=1e-15)
        # step = RK4 (k1 given) then evaluate at the new state with the end inputs
        x_ref = ref.rk4_step(body, x, 0.01, inp0, inp1, list(d_ref))
        d1_ref, out1_ref = ref.evaluate(body, x_ref, *inp1)
        xn, dn, on = np.empty(14), np.empty(14), np.empty(rbj.N_OUT)
        rbj.step(np.array(x), 0.01, np.array(inp0 + inp1), d, prm, xn, dn, on)
        np.testing.assert_allclose(xn, x_ref, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(dn, d1_ref, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(on, out1_ref, rtol=1e-12, atol=1e-15)
        assert math.isclose(float(np.linalg.norm(xn[6:10])), 1.0, rel_tol=1e-14)
        # RigidBody.evaluate (the trim's) returns the kernel's numbers
        d2, out2 = body.evaluate(x, *inp0)
        np.testing.assert_array_equal(d2, d)
        np.testing.assert_array_equal(out2, out)
