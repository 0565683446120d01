"""Bad input through the whole Monitor (issue 3): one focused test per kind of damage.

The base stream is a fault-free simulated flight (lu2016_calm with its faults removed, 8 s).
Each test damages it one way and checks that the Monitor keeps running, counts the damage in
``Monitor.health()``, reinitialises what must be, and never raises a sensor-fault alarm for a
link problem (link problems are ``AlarmKind.LINK``). One probe that stops delivering while its
peers go on is a sensor fault (``no_data``), not a link problem.
"""

from __future__ import annotations

import dataclasses
import math
import socket

import numpy as np
import pytest

from gcs_monitor.link.mav import mavlink
from gcs_monitor.link.transports import TlogSource
from tests.helpers.mavgen import MavGen, drop, duplicate, flip_bits, join, reorder, to_tlog
from tests.integration.support import msg_name, repack, run_monitor


def test_clean_stream_gives_no_alarm(base_packets):
    r = run_monitor(join(base_packets))
    assert r.events == []
    v = r.health["vehicles"]["1"]
    assert v["link"]["lost"] == 0 and v["link"]["bad_values_total"] == 0
    assert v["vehicle_time_s"] > 7.0


def test_random_bytes():
    rng = np.random.default_rng(0)
    r = run_monitor(rng.integers(0, 256, 300_000, dtype=np.uint8).tobytes())
    link = r.health["link"]
    assert link["garbage_bytes"] + link["parse_errors"] > 1000
    assert r.sensor_alarms == []


def test_random_bytes_between_good_packets(base_packets):
    rng = np.random.default_rng(1)
    noisy = b"".join(p + rng.integers(0, 256, 5, dtype=np.uint8).tobytes()
                     for _, p in base_packets)
    r = run_monitor(noisy)
    assert r.health["link"]["garbage_bytes"] > 0
    assert r.sensor_alarms == []
    # nearly every packet still gets through (random bytes look like a header now and then)
    assert r.health["vehicles"]["1"]["link"]["messages"] > 0.95 * len(base_packets)


def test_flipped_bits(base_packets):
    data = flip_bits(join(base_packets), 200, np.random.default_rng(2))
    r = run_monitor(data)
    assert r.health["link"]["parse_errors"] > 100
    assert r.link_alarms("crc")  # CRC errors are a LINK alarm ...
    assert r.sensor_alarms == []  # ... never a sensor fault


def test_truncated_tlog(tmp_path, base_packets):
    img = to_tlog(base_packets)
    path = tmp_path / "cut.tlog"
    path.write_bytes(img[: len(img) // 2 + 7])  # cut mid-packet
    src = TlogSource(path)
    data = b"".join(c for c, _ in src)
    r = run_monitor(data)
    assert src.truncated_bytes > 0
    assert r.sensor_alarms == [] and r.health["link"]["parse_errors"] == 0
    assert 3.0 < r.health["vehicles"]["1"]["vehicle_time_s"] < 5.0


def test_duplicated_packets(base_packets):
    dup = duplicate(base_packets, 0.2, np.random.default_rng(3))
    r = run_monitor(join(dup))
    assert r.health["link"]["duplicates"] == len(dup) - len(base_packets)
    assert r.events == []


def test_reordered_packets(base_packets):
    ro = reorder(base_packets, 0.05, np.random.default_rng(4))
    n_swapped = sum(a != b for a, b in zip(ro, base_packets, strict=True)) // 2
    r = run_monitor(join(ro))
    lk = r.health["vehicles"]["1"]["link"]
    assert lk["reordered"] == n_swapped and lk["lost"] == 0
    assert not lk["duplicate_sysid"]
    assert r.sensor_alarms == []


def test_thirty_percent_packet_loss(base_packets):
    kept = drop(base_packets, 0.3, np.random.default_rng(5))
    r = run_monitor(join(kept))
    lk = r.health["vehicles"]["1"]["link"]
    assert 27.0 < lk["loss_pct"] < 33.0
    assert r.link_alarms("loss")
    assert r.sensor_alarms == []


def _damage(packets, rules):
    """Repack every ``every``-th message of a type (counted within that type, so the damage does
    not depend on which other messages the stream carries)."""
    out = []
    count: dict[str, int] = {}
    for t, p in packets:
        name = msg_name(p)
        n = count[name] = count.get(name, -1) + 1
        for msg, every, phase, fields in rules:
            if name == msg and n % every == phase:
                p = repack(p, **fields)
                break
        out.append((t, p))
    return out


def test_nan_and_infinite_values(base_packets):
    rules = [("HIGHRES_IMU", 7, 0, {"xacc": math.nan}), ("HIGHRES_IMU", 7, 3, {"ygyro": math.inf}),
             ("ATTITUDE", 11, 0, {"roll": math.nan}), ("AIRSPEED", 5, 0, {"airspeed": -math.inf}),
             ("AOA_SSA", 3, 0, {"AOA": math.nan})]
    r = run_monitor(join(_damage(base_packets, rules)))
    bv = r.health["vehicles"]["1"]["link"]["bad_values"]
    for key in ("HIGHRES_IMU.xacc", "HIGHRES_IMU.ygyro", "ATTITUDE.roll", "AIRSPEED.airspeed",
                "AOA_SSA.AOA"):
        assert bv.get(key, 0) > 0, key
    assert r.sensor_alarms == []


def test_values_out_of_physical_range(base_packets):
    rules = [("HIGHRES_IMU", 13, 0, {"zacc": 5000.0}), ("AIRSPEED", 7, 1, {"airspeed": 2000.0}),
             ("GLOBAL_POSITION_INT", 3, 0, {"lat": 950_000_000}),  # 95 deg
             ("SCALED_PRESSURE", 4, 0, {"press_abs": 5.0})]
    r = run_monitor(join(_damage(base_packets, rules)))
    bv = r.health["vehicles"]["1"]["link"]["bad_values"]
    for key in ("HIGHRES_IMU.zacc", "AIRSPEED.airspeed", "GLOBAL_POSITION_INT.lat",
                "SCALED_PRESSURE.press_abs"):
        assert bv.get(key, 0) > 0, key
    assert r.sensor_alarms == []


def test_time_going_backwards_is_an_autopilot_reboot(base_packets):
    """The same flight twice: vehicle time restarts (autopilot reboot)."""
    r = run_monitor(join(base_packets) + join(base_packets))
    assert r.health["vehicles"]["1"]["link"]["reboots"] == 1
    # the families start afresh once: built at the first frames and again after the reboot
    assert r.builds == [["imu", "airdata", "yaw_rate", "actuators"],
                        ["imu", "airdata", "yaw_rate", "actuators"]]
    assert r.link_alarms("reboot")  # LINK/reboot alarm, raised after the restart
    assert r.sensor_alarms == []


def test_second_vehicle_with_the_same_sysid(base_packets):
    from sim_vehicle.run import iter_packets
    from sim_vehicle.scenario import load_scenario

    sc = dataclasses.replace(load_scenario("lu2016_calm"), faults=(), duration_s=4.0, seed=7)
    other = list(iter_packets(sc))
    merged = sorted(base_packets[: len(other)] + other, key=lambda tp: tp[0])
    r = run_monitor(join(merged))
    lk = r.health["vehicles"]["1"]["link"]
    assert lk["duplicate_sysid"]
    assert r.link_alarms("duplicate_sysid")  # its own LINK alarm, never a sensor fault
    assert r.sensor_alarms == []


def test_unknown_message_types(base_packets):
    g = MavGen(sysid=1, seq0=0)
    data = b"".join(p + (g.unknown_message(60_000 + n % 7) if n % 10 == 0 else b"")
                    for n, (_, p) in enumerate(base_packets))
    r = run_monitor(data)
    n_unknown = (len(base_packets) + 9) // 10
    # the decoder re-scans an unknown frame byte by byte (noise also looks "unknown"), which may
    # find a phantom or two inside it; every real one is counted, every good packet delivered
    assert n_unknown <= r.health["link"]["unknown_messages"] <= n_unknown + 5
    assert r.health["vehicles"]["1"]["link"]["unknown_messages"] >= n_unknown
    assert r.health["vehicles"]["1"]["link"]["messages"] == len(base_packets)
    assert r.sensor_alarms == []


def _free_tcp_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_unreachable_zenoh_endpoint(base_packets):
    from gcs_monitor.sinks.zenoh_sink import ZenohSink

    port = _free_tcp_port()  # nothing listens there
    sinks = []

    def sinks_for(sysid: int) -> list[ZenohSink]:
        s = ZenohSink(sysid, listen=[], connect=[f"tcp/127.0.0.1:{port}"])
        sinks.append(s)
        return [s]

    try:
        r = run_monitor(join(base_packets[: len(base_packets) // 4]), sinks_for=sinks_for)
    finally:
        for s in sinks:
            s.close()
    assert r.events == []
    sink_h = r.health["vehicles"]["1"]["sinks"]
    assert sink_h[0]["sink"] == "ZenohSink" and "n_errors" in sink_h[0]


def test_unbindable_zenoh_listen_endpoint(base_packets):
    """A listen endpoint already taken: a clear one-line error before any data is judged, not
    a monitor running on silently without its Zenoh outputs (issue 19)."""
    from gcs_monitor.link.zenoh_bus import ZenohError
    from gcs_monitor.sinks.zenoh_sink import ZenohSink

    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]

        def sinks_for(sysid: int) -> list[ZenohSink]:
            return [ZenohSink(sysid, listen=[f"tcp/127.0.0.1:{port}"])]

        with pytest.raises(ZenohError) as err:
            run_monitor(join(base_packets[: len(base_packets) // 4]), sinks_for=sinks_for)
    assert str(err.value) == (f"zenoh sink of vehicle 1: cannot listen on tcp/127.0.0.1:{port}: "
                              "address already in use")


def _airspeed_id(packet: bytes) -> int:
    return int(mavlink.MAVLink(None).decode(bytearray(packet)).id)


@pytest.mark.parametrize("how", ["silent", "out_of_range"])
def test_one_airspeed_instance_stops_delivering(base_packets, how):
    """One CAS probe goes silent (or sends only impossible values) from t = 4 s while its peers
    keep delivering: the no-data check isolates exactly that probe (fault type no_data)."""
    out = []
    for t, p in base_packets:
        if t >= 4_000_000 and msg_name(p) == "AIRSPEED" and _airspeed_id(p) == 1:
            if how == "silent":
                continue
            p = repack(p, airspeed=-5.0)
        out.append((t, p))
    r = run_monitor(join(out))
    raised = [e for e in r.sensor_alarms if e.state.value == "raised"]
    assert [(str(e.channel), e.fault_type.value) for e in raised] == [("cas1", "no_data")]
    # stale after 0.5 s, then 0.5 s of no data at 20 Hz
    assert 4.9e6 <= raised[0].t_us <= 4e6 + 1.3e6
