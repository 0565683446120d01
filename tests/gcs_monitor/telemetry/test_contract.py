"""The contract table: scales are the hand-derived ones, and every numeric contract field
survives encode (mavgen) -> Decoder -> FrameAssembler in SI (docs/telemetry.md against the code:
test_contract_doc.py)."""

from __future__ import annotations

import math

import numpy as np

from gcs_monitor.link.decode import Decoder
from gcs_monitor.telemetry import contract as ct
from gcs_monitor.telemetry.assembler import FrameAssembler
from tests.helpers.mavgen import MavGen


def test_scale_factors_by_hand():
    assert math.isclose(ct.MG_TO_MPS2, 9.80665e-3, rel_tol=1e-15)  # 1 mG = g0 / 1000
    assert math.isclose(ct.DEGE7_TO_RAD, math.pi / 180.0 * 1e-7, rel_tol=1e-15)
    assert math.isclose(ct.DEG_TO_RAD * 180.0, math.pi, rel_tol=1e-15)
    assert (ct.MS_TO_US, ct.CMPS_TO_MPS, ct.MM_TO_M, ct.HPA_TO_PA) == (1000, 0.01, 0.001, 100.0)
    assert math.isclose(2500 * ct.CDEGC_TO_K + ct.ZERO_C_K, 298.15)  # 25.00 degC


def test_only_flag_and_display_rows_have_no_scale():
    no_scale = {(r.message, r.fields) for r in ct.ROWS if r.scale is None}
    assert no_scale == {("HEARTBEAT", "type, autopilot, base_mode"),
                        ("GPS_RAW_INT", "fix_type, satellites_visible"),
                        ("", "servo1_raw .. servo16_raw")}


def test_round_trip_of_every_contract_field():
    g = MavGen()
    d = Decoder()
    asm = FrameAssembler(stats=d.vehicle_stats(1), align_delay_us=100_000, gps_delay_us=100_000)
    frames = []
    for m in d.feed(b"".join(p for _, p in g.packets(2.0)), 0.0):
        frames += asm.push(m)
    f = frames[-1]
    t = f.t_us * 1e-6
    f32 = 1e-6  # float32 fields carry ~7 significant digits
    for i in range(3):
        s = f.imu[i]
        assert s is not None and s.t_us == f.t_us  # aligned: every instance at the frame time
        np.testing.assert_allclose(s.acc_frd_mps2, g.acc_frd(t, i), rtol=f32, atol=f32)
        np.testing.assert_allclose(s.omega_frd_radps, g.gyro_frd(t, i), rtol=f32, atol=f32)
    assert f.att_age_s == 0.0
    np.testing.assert_allclose(f.euler_rad, g.euler(t), rtol=f32, atol=f32)
    # GPS velocity linear in t: interpolation exact up to the cm/s rounding of each sample
    np.testing.assert_allclose(f.gps_vel_ned_mps, g.gps_vel_ned(t), atol=0.005 + 1e-9)
    lat, lon, alt = g.lat_lon_alt((f.t_us - int(f.gps_age_s * 1e6)) * 1e-6)
    assert abs(f.lat_rad - lat) <= 0.5 * ct.DEGE7_TO_RAD + 1e-15  # degE7 rounding
    assert abs(f.lon_rad - lon) <= 0.5 * ct.DEGE7_TO_RAD + 1e-15
    assert abs(f.alt_msl_m - alt) <= 0.0005 + 1e-9  # mm rounding
    # air data is 20 Hz: the frame holds the latest sample, age <= one air period
    t_air = (f.t_us - int(round(f.aoa_age_s[0] * 1e6))) * 1e-6
    for i in range(3):
        assert math.isclose(f.cas_mps[i], g.cas(t_air, i), rel_tol=f32)
        assert math.isclose(f.aoa_rad[i], g.aoa(t_air, i), rel_tol=1e-5, abs_tol=1e-7)
        assert 0.0 <= f.cas_age_s[i] <= 0.05 + 1e-9
    assert math.isclose(f.ssa_rad, g.ssa(t_air), rel_tol=1e-5, abs_tol=1e-7)
    alt_b, climb = g.baro(t_air)
    assert math.isclose(f.baro_alt_m, alt_b, rel_tol=f32) and math.isclose(f.climb_mps, climb)
    p_pa, oat_k = g.static(f.t_us * 1e-6 - 0.1 * (f.t_us % 100_000 != 0))
    assert abs(f.static_pressure_pa - p_pa) <= 1.0  # 10 Hz sample, <= 0.1 s old, 5 Pa/s ramp
    assert abs(f.oat_k - oat_k) <= 0.005 + 1e-9  # cdegC rounding
    surf = np.array(g.surf((f.t_us - int(round(f.surf_age_s * 1e6))) * 1e-6))
    np.testing.assert_allclose(f.surf_cmd_rad, surf[0::3], atol=1e-7)
    np.testing.assert_allclose(f.surf_pos_rad, surf[1::3], atol=1e-7)
    np.testing.assert_allclose(f.rod_pos_m, surf[2::3], atol=1e-9)
    assert f.gps_fix == 3
    np.testing.assert_allclose(f.att_rate_frd_radps, g.att_rates(t), rtol=f32, atol=f32)
    # 10 Hz control telemetry: the latest sample, stamped with its arrival time
    assert f.servo is not None and 0.0 <= f.servo_age_s <= 0.1 + 1e-9
    t_ctl = (f.t_us - int(round(f.servo_age_s * 1e6))) * 1e-6
    pwm = g.servo_pwm(t_ctl)
    assert f.servo.pwm_us[:4] == tuple(float(x) for x in pwm[:4])
    assert all(math.isnan(x) for x in f.servo.pwm_us[4:])  # 0 = unused
    assert math.isclose(f.servo.norm[0], (pwm[0] - 1500) / 500)
    assert f.nav is not None and math.isclose(f.nav_age_s, f.servo_age_s)
    for got, want in zip((f.nav.nav_roll_rad, f.nav.nav_pitch_rad, f.nav.nav_bearing_rad,
                          f.nav.target_bearing_rad, f.nav.wp_dist_m, f.nav.alt_error_m,
                          f.nav.aspd_error_mps, f.nav.xtrack_error_m), g.nav(t_ctl), strict=True):
        assert math.isclose(got, want, rel_tol=1e-5, abs_tol=1e-6)
    assert f.att_target is not None and f.att_target.euler_rad is not None
    euler, rates, thrust = g.target(t_ctl)
    np.testing.assert_allclose(f.att_target.euler_rad, euler, atol=1e-6)
    np.testing.assert_allclose(f.att_target.rate_frd_radps, rates, atol=1e-7)
    assert math.isclose(f.att_target.thrust, thrust, rel_tol=1e-6)
    assert f.hud is not None
    a, gs, hdg, thr = g.hud(t_air)
    assert (f.hud.airspeed_mps, f.hud.groundspeed_mps, f.hud.throttle) == (a, gs, thr)
    assert math.isclose(f.hud.heading_rad, hdg)
