"""FrameAssembler: causal GPS interpolation, attitude/IMU alignment, ages, stale flags, units.

The synthetic stream (tests/helpers/mavgen.py) has a GPS velocity that is linear in time, so the
interpolated value is known exactly up to the cm/s quantisation of GLOBAL_POSITION_INT.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_monitor.link.decode import Decoder
from gcs_monitor.link.mav import mavlink
from gcs_monitor.telemetry import contract as ct
from gcs_monitor.telemetry.assembler import FrameAssembler
from gcs_monitor.telemetry.frame import Frame
from tests.helpers.mavgen import MavGen

GPS_PERIOD_US = 100_000  # MavGen default 10 Hz
QUANT_MPS = 0.005 + 1e-9  # cm/s rounding of each GPS sample; interpolation cannot exceed it


def _run(packets, asm: FrameAssembler | None = None, *, on_frame=None) -> list[Frame]:
    """Decode and assemble; ``on_frame(frame, newest_imu_t_us)`` sees each frame as it leaves."""
    d = Decoder()
    asm = asm or FrameAssembler(stats=d.vehicle_stats(1))
    frames: list[Frame] = []
    newest = 0
    for _, p in packets:
        for m in d.feed(p, 0.0):
            if m.get_type() == "HIGHRES_IMU":
                newest = max(newest, m.time_usec)
            for f in asm.push(m):
                frames.append(f)
                if on_frame is not None:
                    on_frame(f, newest)
    frames += asm.flush()
    return frames


def _gps_truth(t_us: int) -> np.ndarray:
    return np.array(MavGen.gps_vel_ned(t_us * 1e-6))


def test_gps_interpolation_exact_on_a_linear_ramp_with_one_period_delay():
    g = MavGen(n_imu=1)
    asm = FrameAssembler(gps_delay_us=GPS_PERIOD_US)
    frames = _run(g.packets(3.0), asm)
    checked = 0
    for f in frames:
        if f.t_us < g.t0_us + GPS_PERIOD_US:  # no bracketing pair yet
            continue
        assert f.gps_delay_us == GPS_PERIOD_US
        np.testing.assert_allclose(f.gps_vel_ned_mps, _gps_truth(f.t_us - GPS_PERIOD_US),
                                   atol=QUANT_MPS)
        # bounded delay: the base sample is at most one GPS period older than the query instant
        assert 0.0 <= f.gps_age_s < GPS_PERIOD_US * 1e-6
        checked += 1
    assert checked > 250


def test_gps_aligned_mode_gives_the_velocity_at_the_frame_time():
    g = MavGen(n_imu=1)
    asm = FrameAssembler(gps_delay_us=GPS_PERIOD_US, align_delay_us=GPS_PERIOD_US)
    newest = [0]

    def check(f: Frame, newest_imu_us: int) -> None:
        # a held frame leaves once vehicle time has reached t_us + R: causal, delay exactly R
        assert newest_imu_us - f.t_us == GPS_PERIOD_US
        newest[0] = newest_imu_us

    frames = _run(g.packets(2.0), asm, on_frame=check)
    inner = [f for f in frames if g.t0_us + GPS_PERIOD_US <= f.t_us <= newest[0] - GPS_PERIOD_US]
    assert len(inner) > 150
    for f in inner:
        assert f.gps_delay_us == 0 and f.output_delay_us == GPS_PERIOD_US
        np.testing.assert_allclose(f.gps_vel_ned_mps, _gps_truth(f.t_us), atol=QUANT_MPS)


def test_gps_value_never_depends_on_a_sample_after_the_bracketing_one():
    """Perturb one GPS sample: only frames whose query instant lies within one GPS period of it
    change (the interpolation uses the bracketing pair only: causal, delay = one period)."""
    g0, g1 = MavGen(n_imu=1), MavGen(n_imu=1)
    base = g0.packets(2.0)
    t_bad = g0.t0_us + 10 * GPS_PERIOD_US
    pert = []
    for t, p in g1.packets(2.0):
        if t == t_bad and p[7:10] == bytes((33, 0, 0)):  # GLOBAL_POSITION_INT (id 33)
            p = g1.global_position(t, (99.0, 99.0, 99.0), g1.lat_lon_alt(t * 1e-6))
            g1.mav.seq = (g1.mav.seq - 1) % 256  # keep the sequence numbers of the clean run
            p = p[:4] + bytes([base[len(pert)][1][4]]) + p[5:]
            p = _recrc(p)
        pert.append((t, p))
    fa = _run(base, FrameAssembler(gps_delay_us=GPS_PERIOD_US))
    fb = _run(pert, FrameAssembler(gps_delay_us=GPS_PERIOD_US))
    assert len(fa) == len(fb)
    changed = [a.t_us for a, b in zip(fa, fb, strict=True)
               if not np.array_equal(a.gps_vel_ned_mps, b.gps_vel_ned_mps)]
    q = np.array(changed) - GPS_PERIOD_US  # query instants
    assert len(changed) > 0
    assert np.all(np.abs(q - t_bad) < GPS_PERIOD_US)


def _recrc(p: bytes) -> bytes:
    """Recompute a MAVLink 2 packet's CRC after editing its header."""
    crc_extra = mavlink.mavlink_map[p[7] | p[8] << 8 | p[9] << 16].crc_extra
    body = p[1:-2]
    crc = mavlink.x25crc(body + bytes([crc_extra])).crc
    return p[:-2] + crc.to_bytes(2, "little")


def test_attitude_aligned_with_the_imu_sample_of_the_same_time():
    g = MavGen(n_imu=1)
    aligned = _run(g.packets(1.0), FrameAssembler(gps_delay_us=GPS_PERIOD_US,
                                                  align_delay_us=GPS_PERIOD_US))
    for f in aligned[1:-20]:
        # ATTITUDE is sent just after HIGHRES_IMU of the same instant and filled in while held
        assert f.att_age_s == 0.0
        np.testing.assert_allclose(f.euler_rad, MavGen.euler(f.t_us * 1e-6), atol=1e-6)
        np.testing.assert_allclose(f.imu[0].acc_frd_mps2, MavGen.acc_frd(f.t_us * 1e-6),
                                   atol=1e-5)  # float32 on the wire
    latest = _run(MavGen(n_imu=1).packets(1.0), FrameAssembler())
    for f in latest[1:]:
        # mode "latest": the frame leaves with the IMU sample, attitude is the previous one
        assert f.att_age_s == pytest.approx(0.01)
        np.testing.assert_allclose(f.euler_rad, MavGen.euler(f.t_us * 1e-6 - 0.01), atol=1e-6)


def test_ages_grow_and_inputs_go_stale():
    g = MavGen(n_imu=1)
    pk = g.packets(2.0)
    t_cut = g.t0_us + 1_000_000
    keep = {"HIGHRES_IMU", "HEARTBEAT"}
    # after t_cut only the IMU keeps sending
    data = [(t, p) for t, p in pk
            if t < t_cut or mavlink.mavlink_map[p[7] | p[8] << 8].msgname in keep]
    stale_s = 0.5
    frames = _run(data, FrameAssembler(stale_after_s=stale_s, gps_delay_us=GPS_PERIOD_US))
    last_att = t_cut - 10_000  # ATTITUDE 100 Hz
    last_air = t_cut - 50_000  # air data 20 Hz
    for f in frames:
        if f.t_us <= t_cut:
            continue
        assert f.att_age_s == pytest.approx((f.t_us - last_att) * 1e-6)
        age_s = (f.t_us - last_air) * 1e-6
        np.testing.assert_allclose(f.aoa_age_s, age_s)
        np.testing.assert_allclose(f.cas_age_s, age_s)
        if (f.t_us - last_att) * 1e-6 > stale_s:
            assert f.euler_rad is None
        if age_s > stale_s:
            assert np.isnan(f.aoa_rad).all() and np.isnan(f.cas_mps).all()
            assert math.isnan(f.baro_alt_m)
        else:
            assert f.euler_rad is not None and np.isfinite(f.cas_mps).all()
        q_age_s = (f.t_us - GPS_PERIOD_US - (t_cut - GPS_PERIOD_US)) * 1e-6  # one period back
        if q_age_s > stale_s:
            assert f.gps_vel_ned_mps is None  # held at most stale_after_s, never extrapolated
    assert frames[-1].t_us - t_cut > 0.9e6


def test_scaled_imu_fallback_units():
    """SCALED_IMU/2/3 carry mG and mrad/s (contract fallback rows)."""
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    asm = FrameAssembler()
    frames = []
    for k in range(3):
        t_ms = 1000 + 10 * k
        # xacc changes: three identical samples would be one sample held twice (test_held_imu)
        msg = mavlink.MAVLink_scaled_imu_message(t_ms, 998 + k, -500, -1000, 1000, 250, -2000,
                                                 0, 0, 0)
        m = mavlink.MAVLink(None).decode(bytearray(msg.pack(mav)))
        frames += asm.push(m)
    assert len(frames) == 3
    s = frames[-1].imu[0]
    assert s.t_us == 1_020_000
    np.testing.assert_allclose(s.acc_frd_mps2, np.array([1.0, -0.5, -1.0]) * 9.80665,
                               rtol=1e-12)
    np.testing.assert_allclose(s.omega_frd_radps, [1.0, 0.25, -2.0], rtol=1e-12)
    assert asm.availability()["imu_source"] == "SCALED_IMU"
    assert ct.MG_TO_MPS2 == pytest.approx(9.80665e-3) and ct.MRAD_TO_RAD == 1e-3


def test_non_finite_and_impossible_values_are_counted_and_dropped():
    g = MavGen(n_imu=1)
    d = Decoder()
    asm = FrameAssembler(stats=d.vehicle_stats(1))
    t = g.t0_us
    bad = [g.highres_imu(t, 0, (math.nan, 0.0, -9.8), (0.0, 0.0, 0.0)),
           g.highres_imu(t, 0, (0.0, 0.0, -9.8), (math.inf, 0.0, 0.0)),
           g.highres_imu(t, 0, (1e4, 0.0, -9.8), (0.0, 0.0, 0.0)),  # 1000 g
           g.airspeed(0, math.nan), g.airspeed(1, -5.0),
           g.attitude(t, (0.0, math.nan, 0.0)), g.aoa_ssa(t, math.radians(170.0), 0.0)]
    frames = []
    for p in bad:
        for m in d.feed(p, 0.0):
            frames += asm.push(m)
    assert frames == []
    bv = d.stats[1].bad_values
    assert bv["HIGHRES_IMU.xacc"] == 2 and bv["HIGHRES_IMU.xgyro"] == 1
    assert bv["AIRSPEED.airspeed"] == 2 and bv["ATTITUDE.pitch"] == 1 and bv["AOA_SSA.AOA"] == 1
    avail = asm.availability()  # nothing bad was stored (public view, no internals)
    assert avail["cas_instances"] == 0 and avail["aoa_instances"] == 0


def test_time_going_backwards_is_a_reboot():
    g = MavGen(n_imu=1)
    first = g.packets(1.0)
    second = g.packets(1.0, start_us=200_000)  # vehicle clock restarted
    d = Decoder()
    asm = FrameAssembler(stats=d.vehicle_stats(1))
    frames = _run(first + second, asm)
    st = d.stats[1]
    assert st.reboots == 1 and asm.reboot_pending
    resets = [f for f in frames if f.reset]
    assert len(resets) == 1 and resets[0].t_us == 200_000
    after = frames[frames.index(resets[0]):]
    assert all(b.t_us > a.t_us for a, b in zip(after, after[1:], strict=False))
    assert len(frames) == len(first_frames(first)) + len(after)


def first_frames(packets):
    return _run(packets, FrameAssembler())


def test_small_backward_steps_are_dropped_not_reboots():
    g = MavGen(n_imu=1)
    pk = g.packets(0.5)
    t_back = pk[-1][0] - 50_000
    late = g.highres_imu(t_back, 0, (0.0, 0.0, -9.8), (0.0, 0.0, 0.0))
    d = Decoder()
    asm = FrameAssembler(stats=d.vehicle_stats(1))
    n = len(_run(pk, asm))
    for m in d.feed(late, 0.0):
        assert asm.push(m) == []
    assert d.stats[1].time_backwards == 1 and d.stats[1].reboots == 0
    assert n == 50
