"""MAVLink output: contract fields decode back with stock pymavlink; rates in .tlog; live pacing.

Pacing is checked on a fake clock (exact, no waiting); the live UDP test checks delivery only.
How closely real pacing follows the wall clock is measured by ``benchmarks/bench_pacing.py``.
"""

from __future__ import annotations

import math
import socket
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

sys.path.insert(0, str(Path(__file__).parent))
from test_run import FakeSim, demo  # noqa: E402

import sim_vehicle.mavlink_out as mavlink_out  # noqa: E402
from gcs_monitor.core.units import RAD2DEG  # noqa: E402
from sim_vehicle.mavlink_out import TLOG_EPOCH_US, MavlinkEncoder, UdpSender, parse_hostport  # noqa: E402
from sim_vehicle.run import run_scenario  # noqa: E402
from sim_vehicle.sensors.suite import SensorSample  # noqa: E402
from tests.helpers.clock import FakeClock  # noqa: E402
from tests.helpers.stock_mavutil import stock_mavutil  # noqa: E402


def decode(packets: list[tuple[str, bytes]]) -> list:
    mav = mavlink.MAVLink(None)
    out = []
    for _, p in packets:
        out += mav.parse_buffer(p) or []
    return out


def test_contract_fields_round_trip() -> None:
    enc = MavlinkEncoder(sysid=7)
    air = np.array([0.05, 0.06, 0.07, 100.0, 101.0, 102.0, 0.01])
    gps = np.array([100.0, -5.0, 2.5, math.radians(52.0), math.radians(4.4), 1234.567])
    pk = []
    pk += enc.encode_sample(SensorSample("static", 1_000_000, np.array([89_000.0, 281.65])))
    pk += enc.encode_sample(SensorSample("imu2", 1_230_000, np.array([1, 2, 3, .1, .2, .3])))
    pk += enc.encode_sample(SensorSample("attitude", 1_230_000, np.array([0.1, -0.2, 3.0])))
    pk += enc.encode_sample(SensorSample("gps", 1_300_000, gps))
    pk += enc.encode_sample(SensorSample("airdata", 1_350_000, air))
    pk += enc.encode_sample(SensorSample("baro", 1_350_000, np.array([987.5, 1.25])))
    def key(m):  # noqa: ANN001, ANN202
        t = m.get_type()
        return (t, m.id if t in ("HIGHRES_IMU", "AIRSPEED") else None,
                m.to_dict()["name"] if t == "NAMED_VALUE_FLOAT" else None)

    msgs = {key(m): m for m in decode(pk)}
    assert all(m.get_srcSystem() == 7 and m.get_srcComponent() == 1 for m in msgs.values())
    imu = msgs[("HIGHRES_IMU", 2, None)]
    assert imu.time_usec == 1_230_000 and imu.zacc == 3.0 and abs(imu.zgyro - 0.3) < 1e-7
    att = msgs[("ATTITUDE", None, None)]
    assert att.time_boot_ms == 1230 and abs(att.yaw - 3.0) < 1e-6
    gp = msgs[("GLOBAL_POSITION_INT", None, None)]
    assert gp.lat == 520_000_000 and gp.lon == 44_000_000 and gp.alt == 1_234_567
    assert (gp.vx, gp.vy, gp.vz) == (10_000, -500, 250) and gp.time_boot_ms == 1300
    assert msgs[("GPS_RAW_INT", None, None)].fix_type == 3
    for i in range(3):
        a = msgs[("AIRSPEED", i, None)]
        assert abs(a.airspeed - air[3 + i]) < 1e-4 and a.temperature == 850  # 8.5 degC
    aoa = msgs[("AOA_SSA", None, None)]
    assert abs(aoa.AOA - 0.05 * RAD2DEG) < 1e-5 and abs(aoa.SSA - 0.01 * RAD2DEG) < 1e-5
    assert aoa.time_usec == 1_350_000
    assert abs(msgs[("NAMED_VALUE_FLOAT", None, "AOA2")].value - 0.07 * RAD2DEG) < 1e-5
    hud = msgs[("VFR_HUD", None, None)]
    assert abs(hud.alt - 987.5) < 1e-4 and hud.climb == 1.25
    sp = msgs[("SCALED_PRESSURE", None, None)]
    assert abs(sp.press_abs - 890.0) < 1e-3 and sp.temperature == 850


def test_tlog_rates_with_stock_mavutil(tmp_path: Path) -> None:
    sc = demo(20.0)
    res = run_scenario(sc, tmp_path, progress=False, simulation_factory=FakeSim)
    times: dict[str, list[float]] = {}
    with stock_mavutil() as mavutil:  # no MAVLINK20 / MAVLINK_DIALECT: a reader as installed
        log = mavutil.mavlink_connection(str(res.tlog_path))
        while (m := log.recv_match()) is not None:
            key = m.get_type()
            if key in ("HIGHRES_IMU", "AIRSPEED"):
                key += str(m.id)
            elif key == "NAMED_VALUE_FLOAT":
                key += m.to_dict()["name"]
            times.setdefault(key, []).append(m._timestamp)
    r, o = sc.sensors.rates, sc.output
    expected = {"HEARTBEAT": o.heartbeat_hz, "ATTITUDE": r.attitude_hz,
                "GLOBAL_POSITION_INT": r.gps_hz, "GPS_RAW_INT": r.gps_hz, "AOA_SSA": r.airdata_hz,
                "NAMED_VALUE_FLOAT" + "AOA1": r.airdata_hz, "NAMED_VALUE_FLOATAOA2": r.airdata_hz,
                "VFR_HUD": r.baro_hz, "SCALED_PRESSURE": r.static_hz,
                "SERVO_OUTPUT_RAW": o.servo_output_raw_hz, "DEBUG_FLOAT_ARRAY": o.surf_hz,
                "NAV_CONTROLLER_OUTPUT": o.nav_hz, "ATTITUDE_TARGET": o.nav_hz,
                **{f"HIGHRES_IMU{i}": r.imu_hz for i in range(3)},
                **{f"AIRSPEED{i}": r.airdata_hz for i in range(3)}}
    assert set(times) == set(expected)
    for k, hz in expected.items():
        t = np.array(times[k])
        rate = (len(t) - 1) / (t[-1] - t[0])
        assert abs(rate / hz - 1) < 0.05, (k, rate, hz)
    assert times["HEARTBEAT"][0] == TLOG_EPOCH_US * 1e-6  # timestamps = epoch + vehicle time


def test_live_run_delivers_over_udp_loopback(tmp_path: Path) -> None:
    # Real sockets, real pacing (3 s): stock mavutil receives what the live run sends.
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    port = rx.getsockname()[1]
    rx.close()
    received: list[str] = []
    with stock_mavutil() as mavutil:
        conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}")
        stop = threading.Event()

        def receive() -> None:  # until the run has stopped and nothing came for 0.2 s
            while (m := conn.recv_match(blocking=True, timeout=0.2)) is not None \
                    or not stop.is_set():
                if m is not None:
                    received.append(m.get_type())

        th = threading.Thread(target=receive, daemon=True)
        th.start()
        sc = demo(3.0)
        res = run_scenario(sc, tmp_path, live=True,
                           udp=("127.0.0.1", port), simulation_factory=FakeSim)
        stop.set()
        th.join()
        conn.close()
    assert res.tlog_path is None
    for name in ("ATTITUDE", "AIRSPEED", "AOA_SSA", "HIGHRES_IMU"):  # AOA_SSA: ardupilotmega
        assert received.count(name) >= 0.95 * res.counts[name], name


def test_live_run_is_paced_to_vehicle_time(tmp_path: Path,
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    # Fake clock: every packet leaves at t0 + its vehicle time, exactly.
    clock = FakeClock()
    monkeypatch.setattr(mavlink_out, "time", clock)
    sent: list[tuple[int, float]] = []
    monkeypatch.setattr(UdpSender, "write",
                        lambda self, t_us, packet: sent.append((t_us, clock.now_s)))
    sc = demo(3.0)
    res = run_scenario(sc, tmp_path, live=True, udp=("127.0.0.1", 9), simulation_factory=FakeSim)
    assert len(sent) == sum(res.counts.values())
    t0_s = sent[0][1] - sent[0][0] * 1e-6
    for t_us, at_s in sent:
        assert at_s == pytest.approx(t0_s + t_us * 1e-6, abs=1e-9), t_us  # s: float round-off
    assert sent[-1][1] - sent[0][1] == pytest.approx(res.vehicle_duration_s, abs=1e-9)


def test_udp_sender_paces_on_absolute_schedule(monkeypatch: pytest.MonkeyPatch) -> None:
    # 3 ms of work before each 10 ms-period call, one 25 ms stall: each call returns at
    # t0 + t_us, or at once when already late, and the calls after the stall catch up (no drift).
    clock = FakeClock()
    monkeypatch.setattr(mavlink_out, "time", clock)
    s = UdpSender("127.0.0.1", 9)
    late = []
    for k in range(50):
        clock.advance(0.025 if k == 20 else 0.003)
        before = clock.now_s
        s.pace(k * 10_000)
        if k == 0:
            t0_s = before  # the schedule starts at the first call
        due_s = t0_s + k * 0.01
        if before > due_s:
            late.append(k)
            assert clock.now_s == before  # late: no sleep
        else:
            assert clock.now_s == pytest.approx(due_s, abs=1e-9)  # s: float round-off
    s.close()
    assert late == [20, 21, 22]  # 15, 8, 1 ms behind: 10 ms period - 3 ms work = 7 ms less each


def test_parse_hostport() -> None:
    assert parse_hostport("10.0.0.2:14551") == ("10.0.0.2", 14551)
    assert parse_hostport("localhost") == ("localhost", 14550)
    for bad in ("host:notaport", ":14550", "h:70000"):
        try:
            parse_hostport(bad)
        except ValueError:
            continue
        raise AssertionError(bad)


def test_fast_packer_bytes_equal_pymavlink_pack() -> None:
    # Every message type the encoder emits: decode with stock pymavlink, re-pack with
    # pymavlink's own MAVLink_message.pack at the same sequence number -> the same bytes.
    enc = MavlinkEncoder(sysid=9, compid=1, home_alt_m=100.0)
    air = np.array([0.05, -0.06, 0.07, 100.0, 0.0, 102.5, 0.01])
    gps = np.array([-10.0, 5.0, -2.5, math.radians(-33.0), math.radians(151.2), 12.0])
    st = FakeSim(None).state()
    pk = [enc.heartbeat(), enc.servo_output_raw(123_456, st), enc.surf(123_456, st)]
    for g, v in (("static", [101_325.0, 288.15]), ("imu0", [0.1, -0.2, -9.8, 0.0, 1e-3, -2.0]),
                 ("attitude", [-0.1, 0.2, -3.0]), ("gps", gps), ("airdata", air),
                 ("baro", [12.5, -0.5])):
        pk += enc.encode_sample(SensorSample(g, 2_000_000 + len(pk), np.asarray(v, float)))
    assert {n for n, _ in pk} >= {"HEARTBEAT", "SERVO_OUTPUT_RAW", "DEBUG_FLOAT_ARRAY",
                                  "SCALED_PRESSURE", "HIGHRES_IMU", "ATTITUDE",
                                  "GLOBAL_POSITION_INT", "GPS_RAW_INT", "AIRSPEED", "AOA_SSA",
                                  "NAMED_VALUE_FLOAT", "VFR_HUD"}
    for seq, (name, p) in enumerate(pk):
        (msg,) = decode([(name, p)])
        assert msg.get_type() == name and p[4] == seq
        mav = mavlink.MAVLink(None, srcSystem=9, srcComponent=1)
        mav.seq = seq
        assert msg.pack(mav) == p, name
