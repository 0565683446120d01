"""Lu2017 servo: model functions, NDI tracking of the reference model, actuator faults."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_monitor.models.servo import (
    ServoLoopParams,
    ServoParams,
    max_rod_rate_mps,
    ndi_control,
    reference_model_derivative,
    servo_derivative,
    stalled_pressure,
)
from sim_vehicle.actuators.faults import ActuatorFault, apply_to_valve, fault_effect
from sim_vehicle.actuators.servo_bank import ActuatorGeometry, ServoBank
from tests.reference import servo_bank as ref

GEO = ActuatorGeometry(rod_gain_radpm=5.0, rod_stroke_m=0.1)
DT = 0.01


def _run(bank: ServoBank, cmd: tuple[float, float, float], t0: float, t1: float) -> np.ndarray:
    out = []
    t = t0
    while t < t1 - 1e-9:
        bank.step(t, DT, cmd)
        t += DT
        out.append([t, bank.rod_m(1), bank.x[1][3], bank.x[1][1]])
    return np.array(out)


def test_servo_derivative_hand_values() -> None:
    # Lu2017 eq. 4 at x1 = 0: x3' = 2 A_p E / (P_s V_m) (phi_n/A_p sqrt(1 - x3) u - L x3 - x2)
    p = ServoParams()
    x1d, x2d, x3d = servo_derivative(0.0, 0.1, 0.01, 0.5, p)
    assert x1d == 0.1
    assert math.isclose(x2d, (0.0025 * 1.4e7 * 0.01 - 52.3 * 0.1) / 2000.0)
    c = 2 * 0.0025 * 1e9 / (1.4e7 * 0.001973)
    assert math.isclose(x3d, c * (1.0 * math.sqrt(0.99) * 0.5 - 0.023 * 0.01 - 0.1))


def test_ndi_inverts_the_plant() -> None:
    # Relative degree 3: with u from eq. 13 the third derivative of y equals nu.
    p, lp = ServoParams(), ServoLoopParams()
    x = (0.01, 0.02, 0.003)
    ref = (0.015, 0.01, 0.2, 1.0)
    u = ndi_control(x[0], x[1], x[2], ref, p, lp)
    # y''' by finite difference of y'' = x2' along the flow
    x1d, x2d, x3d = servo_derivative(*x, u, p)
    yddd = (0.0025 * 1.4e7 * x3d - 52.3 * x2d) / 2000.0
    lam = lp.ndi_pole_radps
    nu = ref[3] + 3 * lam * (ref[2] - x2d) + 3 * lam**2 * (ref[1] - x[1]) + lam**3 * (ref[0] - x[0])
    assert abs(u) < 1.0
    assert math.isclose(yddd, nu, rel_tol=1e-9)


def test_reference_closure_matches_model_functions() -> None:
    """The kernel's plain-float reference (tests/reference/servo_bank.py) against the model in
    the paper's form (gcs_monitor.models.servo, eqs. 4, 13 and the reference model)."""
    p, lp = ServoParams(), ServoLoopParams()
    s = (0.01, 0.02, 0.003, 0.015, 0.01, 0.2)
    got = ref.make_deriv(p, lp)(*s, 0.03, 0.0, None)
    r = reference_model_derivative(s[3], s[4], s[5], 0.03, lp)
    u = ndi_control(s[0], s[1], s[2], (s[3], s[4], s[5], r[2]), p, lp)
    want = (*servo_derivative(s[0], s[1], s[2], u, p), *r)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)


def test_step_response_follows_reference_model() -> None:
    bank = ServoBank(GEO, (0.0, 0.0, 0.0))
    step_rad = 0.1  # 0.02 m of rod: the valve stays unsaturated
    rec = _run(bank, (0.0, step_rad, 0.0), 0.0, 1.0)
    # Independent reference: the reference model w^3/((s+w)(s^2+2 zeta w s+w^2)) step response
    from scipy.signal import lti, step

    lp = ServoLoopParams()
    w, z = lp.ref_bandwidth_radps, lp.ref_damping
    sys_ = lti([w**3], np.polymul([1, w], [1, 2 * z * w, w * w]))
    _, y = step(sys_, T=np.concatenate([[0.0], rec[:, 0]]))  # lsim starts the step at T[0]
    y = y[1:]
    q_target = step_rad / GEO.rod_gain_radpm
    np.testing.assert_allclose(rec[:, 1], q_target * y, atol=2e-3 * q_target)  # 0.2 % of the step
    assert abs(bank.deflection_rad(1) - step_rad) < 1e-3 * step_rad


def test_solid_jam_stops_the_surface() -> None:
    jam = ActuatorFault(surface=1, kind="solid_jam", t_start_s=0.1)
    bank = ServoBank(GEO, (0.0, 0.0, 0.0), faults=(jam,))
    rec = _run(bank, (0.0, 0.2, 0.0), 0.0, 0.1)
    pos_at_jam = bank.deflection_rad(1)
    assert 0.0 < pos_at_jam < 0.2  # moving when it jams
    for cmd in (0.3, -0.3, 0.0):
        _run(bank, (0.0, cmd, 0.0), 0.1, 1.1)
        assert bank.deflection_rad(1) == pos_at_jam
        assert bank.x[1][1] == 0.0
    assert rec.shape[0] == 10


def test_runaway_reaches_the_stop_at_the_rate_limit() -> None:
    run = ActuatorFault(surface=1, kind="runaway", t_start_s=0.2, amplitude=-1.0)
    bank = ServoBank(GEO, (0.0, 0.0, 0.0), faults=(run,))
    rec = _run(bank, (0.0, 0.0, 0.0), 0.0, 1.0)
    assert math.isclose(bank.rod_m(1), -GEO.rod_stroke_m)
    rate = np.diff(rec[:, 1]) / DT
    vmax = max_rod_rate_mps(ServoParams())
    # hydraulic transient (56 rad/s, lightly damped) then the no-load maximum rate
    assert abs(rate.min() + vmax) < 0.1 * vmax
    moving = rec[:-1][(rate < -0.5 * vmax)]
    assert moving.shape[0] > 0
    t_reach = rec[np.argmax(rec[:, 1] <= -GEO.rod_stroke_m + 1e-12), 0]
    # stroke / rate plus the pressure build-up (a few hydraulic time constants)
    assert 0.2 + GEO.rod_stroke_m / vmax <= t_reach + DT < 0.2 + GEO.rod_stroke_m / vmax + 0.1
    # and it stays at the stop
    _run(bank, (0.0, 0.3, 0.0), 1.0, 2.0)
    assert math.isclose(bank.rod_m(1), -GEO.rod_stroke_m)


def test_liquid_jam_biases_sensor_and_surface() -> None:
    bias = 0.005
    f = ActuatorFault(surface=1, kind="liquid_jam", t_start_s=0.0, amplitude=bias)
    bank = ServoBank(GEO, (0.0, 0.0, 0.0), faults=(f,))
    _run(bank, (0.0, 0.1, 0.0), 0.0, 2.0)
    q_cmd = 0.1 / GEO.rod_gain_radpm
    assert abs(bank.rod_sensor_m(1) - q_cmd) < 1e-5  # the loop closes on the biased sensor
    assert abs(bank.rod_m(1) - (q_cmd - bias)) < 1e-5  # so the rod is off by -bias


@pytest.mark.parametrize("kind", ["liquid_ofc", "solid_ofc"])
def test_ofc_oscillates_the_rod(kind: str) -> None:
    f = ActuatorFault(surface=1, kind=kind, t_start_s=1.0, amplitude=0.05, frequency_hz=2.0)
    bank = ServoBank(GEO, (0.0, 0.0, 0.0), faults=(f,))
    rec = _run(bank, (0.0, 0.05, 0.0), 0.0, 4.0)
    before = rec[(rec[:, 0] > 0.6) & (rec[:, 0] < 1.0), 1]
    after = rec[rec[:, 0] > 2.0, 1]
    assert np.ptp(before) < 1e-5
    assert np.ptp(after) > (1e-3 if kind == "solid_ofc" else 2e-5)


def test_fault_effect_pure_function() -> None:
    f1 = ActuatorFault(
        surface=0, kind="liquid_ofc", t_start_s=1.0, t_end_s=2.0, amplitude=0.1, frequency_hz=1.0
    )
    assert fault_effect((f1,), 0, 0.5).u_add == 0.0
    assert math.isclose(fault_effect((f1,), 0, 1.25).u_add, 0.1)  # sin(pi/2)
    assert fault_effect((f1,), 0, 2.5).u_add == 0.0
    assert fault_effect((f1,), 1, 1.25).u_add == 0.0  # other surface
    f2 = ActuatorFault(surface=0, kind="solid_ofc", t_start_s=0.0, amplitude=0.2, frequency_hz=0.25)
    eff = fault_effect((f2,), 0, 1.0)
    assert apply_to_valve(0.7, eff) == pytest.approx(0.2)
    with pytest.raises(ValueError):
        ActuatorFault(surface=0, kind="bogus")


def test_stalled_pressure_balances_leakage() -> None:
    p = ServoParams()
    x3 = stalled_pressure(1.0, p)
    assert math.isclose(
        p.max_valve_flow_m3ps / p.piston_area_m2 * math.sqrt(1 - x3), p.leakage_mps * x3
    )
    assert stalled_pressure(-1.0, p) == pytest.approx(-x3)


def test_kernel_bank_step_matches_reference_rk4() -> None:
    """_servo_jit.step_bank against the plain-float RK4 of tests/reference/servo_bank.py."""
    # Faults on all three surfaces (OFC added / replaced, runaway into the stop).
    faults = (
        ActuatorFault(surface=0, kind="liquid_ofc", t_start_s=0.1, amplitude=0.05,
                      frequency_hz=2.0),
        ActuatorFault(surface=1, kind="runaway", t_start_s=0.2, amplitude=1.0),
        ActuatorFault(surface=2, kind="solid_ofc", t_start_s=0.3, t_end_s=0.6, amplitude=0.1,
                      frequency_hz=3.0),
    )
    bank = ServoBank(GEO, (0.01, -0.02, 0.0), faults=faults)
    x_ref = [list(row) for row in bank.x.tolist()]
    deriv = ref.make_deriv(bank.p, bank.lp)

    def ref_step(bank: ServoBank, x: list[list[float]], t_s: float, cmd: tuple) -> None:
        ref.rk4_bank_step(deriv, bank.p, bank.faults, GEO.rod_stroke_m, GEO.rod_gain_radpm, x,
                          t_s, DT, cmd)

    hit_stop = False
    for k in range(100):
        t = k * DT
        cmd = (0.1 * math.sin(3.0 * t), -0.05, 0.2 * math.cos(2.0 * t))
        ref_step(bank, x_ref, t, cmd)
        bank.step(t, DT, cmd)
        np.testing.assert_allclose(bank.x, np.array(x_ref), rtol=1e-10, atol=1e-13)
        hit_stop |= bank.rod_m(1) == GEO.rod_stroke_m
    assert hit_stop  # the runaway reached the stop inside the compared window
    assert bank.deflection_rad(1) == GEO.rod_gain_radpm * GEO.rod_stroke_m


def test_kernel_jam_step_matches_reference() -> None:
    """_servo_jit.jam_step (solid jam: rod frozen, reference model running) against the
    reference: the same operations, identical numbers."""
    jam = ActuatorFault(surface=1, kind="solid_jam", t_start_s=0.2)
    bank = ServoBank(GEO, (0.0, 0.0, 0.0), faults=(jam,))
    deriv = ref.make_deriv(bank.p, bank.lp)
    x_ref: list[float] | None = None
    jam_pos = 0.0
    for k in range(60):
        t = k * DT
        cmd = (0.0, 0.2 * math.sin(4.0 * t), 0.0)
        if k == 20:
            x_ref, jam_pos = bank.x[1].tolist(), float(bank.x[1][0])
        if x_ref is not None:
            q_com = max(-GEO.rod_stroke_m, min(GEO.rod_stroke_m, cmd[1] / GEO.rod_gain_radpm))
            ref.jam_step(deriv, x_ref, q_com, fault_effect(bank.faults, 1, t), DT, jam_pos)
        bank.step(t, DT, cmd)
        if x_ref is not None:
            np.testing.assert_array_equal(bank.x[1], x_ref)
    assert x_ref is not None and x_ref[3] != jam_pos  # the reference model kept moving
