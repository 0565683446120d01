"""Issue 3 "Bad input": decoder + assembler never raise and count each kind of bad input.

Streams come from tests/helpers/mavgen.py; every expected count is constructed by the test.
"""

from __future__ import annotations

import math

import numpy as np

from gcs_monitor.link.decode import Decoder
from gcs_monitor.link.mav import mavlink
from gcs_monitor.telemetry.assembler import FrameAssembler, input_availability
from gcs_monitor.telemetry.frame import Frame
from tests.helpers import mavgen
from tests.helpers.mavgen import MavGen


def _run(data_chunks, *, align_delay_us: int = 0) -> tuple[Decoder, dict[int, FrameAssembler],
                                                           list[Frame]]:
    d = Decoder()
    asm: dict[int, FrameAssembler] = {}
    frames: list[Frame] = []
    def push(msgs) -> None:
        for m in msgs:
            s = m._header.srcSystem
            a = asm.get(s)
            if a is None:
                a = asm[s] = FrameAssembler(stats=d.vehicle_stats(s), align_delay_us=align_delay_us)
            frames.extend(a.push(m))

    for data in data_chunks:
        push(d.feed(data, 0.0))
    push(d.flush())  # bytes held by a frame that never completed
    for a in asm.values():
        frames += a.flush()
    return d, asm, frames


def _chunks(data: bytes, n: int = 997) -> list[bytes]:
    return [data[i:i + n] for i in range(0, len(data), n)]


def test_everything_bad_at_once_never_raises_and_is_counted():
    rng = np.random.default_rng(7)
    g = MavGen()
    pk = g.packets(4.0)
    n_sent = len(pk)
    pk = mavgen.drop(pk, 0.3, rng)
    n_after_drop = len(pk)
    pk = mavgen.duplicate(pk, 0.05, rng)
    pk = mavgen.reorder(pk, 0.05, rng)
    t = pk[-1][0] + 10_000
    bad = [g.highres_imu(t, 0, (math.nan, 0.0, -9.8), (0.0, 0.0, 0.0)),
           g.highres_imu(t + 1, 0, (0.0, 0.0, -9.8), (math.inf, 0.0, 0.0)),
           g.highres_imu(t + 2, 0, (1e4, 0.0, -9.8), (0.0, 0.0, 0.0)),  # 1000 g
           g.airspeed(1, 2000.0), g.airspeed(2, math.nan),
           g.aoa_ssa(t, math.radians(200.0), 0.0),
           g.unknown_message()]
    data = mavgen.join(pk) + b"".join(bad)
    data = mavgen.flip_bits(data, 10, rng)
    data = rng.integers(0, 256, 3000, dtype=np.uint8).tobytes() + data  # garbage first
    d, asm, frames = _run(_chunks(data))
    st = d.stats[1]
    assert frames, "the good part of the stream still produces frames"
    assert 0.25 < st.loss_pct / 100 < 0.36  # 30 % dropped (+ a few bit flips)
    assert st.lost >= n_sent - n_after_drop - 40  # seq gaps see the dropped packets
    assert st.duplicates > 0 and st.reordered > 0
    assert d.counters.parse_errors > 0 and d.counters.garbage_bytes > 0
    assert d.counters.unknown_messages >= 1
    bv = st.bad_values
    assert bv.get("HIGHRES_IMU.xacc", 0) >= 2  # NaN and 1000 g
    assert bv.get("HIGHRES_IMU.xgyro", 0) >= 1  # inf
    assert bv.get("AIRSPEED.airspeed", 0) >= 2
    assert bv.get("AOA_SSA.AOA", 0) >= 1
    ts = [f.t_us for f in frames]
    assert all(b > a for a, b in zip(ts, ts[1:], strict=False))  # time strictly increasing
    for f in frames:  # nothing non-finite leaks into a frame
        for s in f.imu:
            if s is not None:
                assert np.all(np.isfinite(s.acc_frd_mps2))
                assert np.all(np.isfinite(s.omega_frd_radps))
        assert np.all(np.isnan(f.cas_mps) | ((f.cas_mps >= 0) & (f.cas_mps < 400)))


def test_random_bytes_only():
    rng = np.random.default_rng(3)
    d, asm, frames = _run(_chunks(rng.integers(0, 256, 100_000, dtype=np.uint8).tobytes()))
    assert frames == [] and d.counters.garbage_bytes + d.counters.parse_errors > 100


def test_second_vehicle_with_the_same_sysid_is_flagged_without_reset_storm():
    a = MavGen(sysid=1, seq0=0, t0_us=50_000_000).packets(6.0)
    b = MavGen(sysid=1, seq0=128, t0_us=5_000_000).packets(6.0)  # other clock, other seq
    merged = [p for pair in zip(a, b, strict=False) for p in pair]
    d, asm, frames = _run([p for _, p in merged])
    st = d.stats[1]
    assert st.duplicate_sysid
    assert st.reboots == 0 and st.clock_conflicts >= 3  # interleaved clocks never reset
    assert st.time_backwards > 0


def test_duplicate_sysid_by_heartbeat_type():
    a = MavGen(sysid=4, mav_type=mavlink.MAV_TYPE_FIXED_WING)
    b = MavGen(sysid=4, mav_type=mavlink.MAV_TYPE_QUADROTOR, compid=1, seq0=1)
    d = Decoder()
    d.feed(a.heartbeat() + b.heartbeat(), 0.0)
    assert d.stats[4].duplicate_sysid and d.stats[4].heartbeat_conflicts == 1


def test_truncated_tlog_assembles_cleanly(tmp_path):
    from gcs_monitor.link.transports import TlogSource

    image = mavgen.to_tlog(MavGen().packets(1.0))
    path = tmp_path / "cut.tlog"
    path.write_bytes(image[: len(image) - 17])  # cut inside the last record
    src = TlogSource(path)
    d, asm, frames = _run([c for c, _ in src])
    assert src.truncated_bytes > 0 and len(frames) >= 99


def test_primary_imu_switch_when_imu0_stops():
    g = MavGen()
    pk = g.packets(3.0)
    t_stop = g.t0_us + 1_000_000
    is_imu0 = [m for m in Decoder().feed(mavgen.join(pk), 0.0)]
    keep = [p for (t, p), m in zip(pk, is_imu0, strict=True)
            if not (m._type == "HIGHRES_IMU" and m.id == 0 and t >= t_stop)]
    d, asm, frames = _run([b"".join(keep)])
    a = asm[1]
    assert d.stats[1].primary_imu_switches == 1 and a.availability()["primary_imu"] == 1
    late = [f for f in frames if f.t_us > t_stop + 600_000]
    assert late and all(f.primary_imu is not None for f in late)
    assert all(f.imu[0].t_us < t_stop for f in late)  # the stopped IMU is visibly old
    gaps = np.diff([f.t_us for f in frames])
    assert gaps.max() <= 500_000 + 10_000  # frames resume within stale_after_s


def test_gps_without_3d_fix_gives_no_velocity():
    g = MavGen()
    pk = g.packets(1.0)
    data = mavgen.join(pk)
    d = Decoder()
    a = FrameAssembler(stats=d.vehicle_stats(1))
    frames = []
    for m in d.feed(data, 0.0):
        if m._type == "GPS_RAW_INT":
            m.fix_type = 1  # no fix
        frames += a.push(m)
    assert frames and all(f.gps_vel_ned_mps is None for f in frames)
    assert all(f.gps_fix == 1 for f in frames[1:])  # GPS_RAW_INT follows the first IMU sample


def test_raw_imu_only_used_for_ardupilot():
    g = MavGen(mav_type=mavlink.MAV_TYPE_QUADROTOR)
    mav = g.mav
    raw = [mavlink.MAVLink_raw_imu_message(1_000_000 + 10_000 * k, 0, 0, -1000, 0, 0, 100,
                                          0, 0, 0, 0, 0).pack(mav) for k in range(5)]
    other = mavlink.MAVLink_heartbeat_message(2, mavlink.MAV_AUTOPILOT_PX4, 0, 0, 4, 3).pack(mav)
    d = Decoder()
    a = FrameAssembler(stats=d.vehicle_stats(1))
    frames = a.push_many(d.feed(bytes(other) + b"".join(raw[:2]), 0.0))
    assert frames == []  # PX4: RAW_IMU is raw counts
    d2 = Decoder()
    a2 = FrameAssembler(stats=d2.vehicle_stats(1))
    frames = a2.push_many(d2.feed(g.heartbeat() + b"".join(raw), 0.0))
    assert len(frames) == 5
    np.testing.assert_allclose(frames[0].imu[0].acc_frd_mps2, [0, 0, -9.80665], atol=1e-12)
    np.testing.assert_allclose(frames[0].imu[0].omega_frd_radps, [0, 0, 0.1], atol=1e-12)


def test_input_availability_lists_what_is_there():
    g = MavGen(n_imu=2)
    pk = [(t, p) for t, p in g.packets(1.0)]
    d = Decoder()
    msgs = [m for m in d.feed(mavgen.join(pk), 0.0)
            if m._type not in ("AIRSPEED", "DEBUG_FLOAT_ARRAY")
            and not (m._type == "NAMED_VALUE_FLOAT")]
    a = FrameAssembler(stats=d.vehicle_stats(1))
    frames = a.push_many(msgs)
    for av in (input_availability(a), input_availability(frames)):
        assert av["imu_ids"] == [0, 1] and av["attitude"] and av["gps_velocity"]
        assert av["aoa_ids"] == [0] and av["cas_instances"] == 0 and not av["surfaces"]


def test_after_the_other_sender_stops_the_remaining_clock_is_followed():
    a = MavGen(sysid=1, seq0=0, t0_us=50_000_000).packets(3.0)
    b_gen = MavGen(sysid=1, seq0=128, t0_us=5_000_000)
    b = b_gen.packets(3.0)
    merged = [p for pair in zip(a, b, strict=False) for p in pair]
    b_alone = b_gen.packets(3.0, start_us=8_000_000)  # sender A has gone quiet
    d, asm, frames = _run([p for _, p in merged + b_alone])
    st = d.stats[1]
    assert st.reboots == 1  # one switch to B's clock, after 1 s
    # flagged while both sent, cleared once A had been quiet for DUP_SUSTAIN packets
    assert st.duplicate_sysid_seen and not st.duplicate_sysid
    assert frames[-1].t_us == b_alone[-1][0] and asm[1].availability()["primary_imu"] == 0


def test_aligned_constructor_uses_the_config_delay():
    class Cfg:
        gps_delay_s = 0.2
        stale_after_s = 0.7
        primary_imu = 1

    a = FrameAssembler.aligned(Cfg())
    assert (a.gps_delay_us, a.align_delay_us, a.query_lag_us) == (200_000, 200_000, 0)
    assert a.stale_us == 700_000 and a.preferred_imu == 1
