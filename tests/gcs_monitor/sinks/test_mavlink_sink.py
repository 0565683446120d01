"""Alarms as STATUSTEXT: severity map, text, MAVLink 2 chunking, never blocking."""

from __future__ import annotations

import socket
import time
from collections.abc import Callable

import numpy as np
import pytest

from gcs_monitor.core.types import ChannelId
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState, FaultType
from gcs_monitor.fdi.records import StepOutput
from gcs_monitor.link.mav import mavlink
from gcs_monitor.link.rates import RateRequester
from gcs_monitor.sinks.mavlink_sink import MavlinkAlarmSink, chunks, severity
from gcs_monitor.telemetry.frame import Frame


def _event(kind: AlarmKind, state: AlarmState = AlarmState.RAISED, msg: str = "") -> AlarmEvent:
    return AlarmEvent(t_us=1_000_000, channel=ChannelId(kind="acc", instance=0, axis="z"),
                      state=state, kind=kind, fault_type=FaultType.BIAS, magnitude=1.86,
                      residual_rms=2.0, threshold=1.0, estimator="imu_ts", message=msg,
                      vehicle=7)


def test_severity_map() -> None:
    assert severity(_event(AlarmKind.SET_LOST)) == mavlink.MAV_SEVERITY_CRITICAL
    assert severity(_event(AlarmKind.ACTUATOR_FAULT)) == mavlink.MAV_SEVERITY_ALERT
    assert severity(_event(AlarmKind.SENSOR_FAULT)) == mavlink.MAV_SEVERITY_WARNING
    assert severity(_event(AlarmKind.MONITOR_DEGRADED)) == mavlink.MAV_SEVERITY_NOTICE
    assert severity(_event(AlarmKind.SET_LOST, AlarmState.CLEARED)) == mavlink.MAV_SEVERITY_INFO


def test_chunking() -> None:
    assert chunks("short", 5) == [(0, b"short", 0)]
    c = chunks("x" * 120, 9)
    assert [len(p) for _, p, _ in c] == [50, 50, 20] and {i for i, _, _ in c} == {9}
    assert [s for _, _, s in c] == [0, 1, 2]
    c = chunks("y" * 100, 3)  # exact multiple: an empty last chunk ends the text
    assert [len(p) for _, p, _ in c] == [50, 50, 0]


def _receive(sock: socket.socket, n: int, timeout_s: float = 3.0) -> list:
    mav = mavlink.MAVLink(None)
    mav.robust_parsing = True
    out: list = []
    t_end = time.monotonic() + timeout_s
    sock.settimeout(0.2)
    while len(out) < n and time.monotonic() < t_end:
        try:
            data = sock.recv(65535)
        except TimeoutError:
            continue
        out += [m for m in mav.parse_buffer(data) or [] if m.get_type() != "BAD_DATA"]
    return out


def test_sink_sends_raise_and_clear_from_its_component() -> None:
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    port = rx.getsockname()[1]
    sink = MavlinkAlarmSink(f"udpout:127.0.0.1:{port}", vehicle=7, named_values=True)
    long_msg = "a long explanation that does not fit in one statustext message at all"
    frame = Frame(t_us=1_000_000, imu=[None])
    sink.publish(frame, StepOutput(events=[_event(AlarmKind.SENSOR_FAULT, msg=long_msg),
                                           _event(AlarmKind.SENSOR_FAULT, AlarmState.UPDATED),
                                           _event(AlarmKind.SENSOR_FAULT, AlarmState.CLEARED)]))
    msgs = _receive(rx, 4)
    sink.close()
    rx.close()
    texts = [m for m in msgs if m.get_type() == "STATUSTEXT"]
    assert all(m.get_srcSystem() == 7 and m.get_srcComponent() == 191 for m in texts)
    raised = [m for m in texts if m.severity == mavlink.MAV_SEVERITY_WARNING]
    assert len(raised) >= 2 and len({m.id for m in raised}) == 1 and raised[0].id != 0
    full = "".join(m.text for m in sorted(raised, key=lambda m: m.chunk_seq))
    assert full.startswith("FDI raised acc0.z sensor_fault bias +1.86") and long_msg in full
    cleared = [m for m in texts if m.severity == mavlink.MAV_SEVERITY_INFO]
    assert len(cleared) == 1 and cleared[0].text.startswith("FDI cleared acc0.z")
    assert sink.n_dropped == 0


def test_sink_never_blocks_and_counts_drops() -> None:
    sink = MavlinkAlarmSink("tcp:127.0.0.1:9", vehicle=1, queue_size=10)  # nothing listens
    frame = Frame(t_us=0, imu=[None])
    t0 = time.monotonic()
    for _ in range(200):
        sink.publish(frame, StepOutput(events=[_event(AlarmKind.SENSOR_FAULT)]))
    assert time.monotonic() - t0 < 0.5  # s: formatting only, the sender thread does the I/O
    sink.close()
    assert sink.n_dropped > 0


class _FakeTcp:
    """A TCP connection whose sends fail (``broken``) or are kept."""

    def __init__(self, broken: bool) -> None:
        self.broken = broken
        self.sent: list[bytes] = []
        self.closed = False

    def sendall(self, packet: bytes) -> None:
        if self.broken:
            raise OSError("connection reset by peer")
        self.sent.append(packet)

    def close(self) -> None:
        self.closed = True


def _wait_for(cond: Callable[[], bool], timeout_s: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while not cond() and time.monotonic() < deadline:
        time.sleep(0.01)
    return cond()


def test_sink_survives_a_broken_tcp_connection(monkeypatch: pytest.MonkeyPatch) -> None:
    """A send failing mid-batch drops the rest of the batch; the next batch reconnects."""
    sink = MavlinkAlarmSink("tcp:127.0.0.1:9", vehicle=1)
    conns = [_FakeTcp(broken=True), _FakeTcp(broken=False)]
    monkeypatch.setattr(sink, "_connect", lambda: conns.pop(0))
    broken, good = conns
    with sink._cv:  # three texts in one batch (the condition's lock is re-entrant)
        for _ in range(3):
            sink.send_text("FDI test", mavlink.MAV_SEVERITY_WARNING)
    assert _wait_for(lambda: sink.n_dropped == 3)
    assert broken.closed and sink.n_errors == 1 and sink.n_published == 0
    sink.send_text("FDI again", mavlink.MAV_SEVERITY_WARNING)
    assert _wait_for(lambda: sink.n_published == 1)
    sink.close()
    assert len(good.sent) == 1 and good.closed


def test_rate_requester_falls_back_and_measures() -> None:
    sent: list[bytes] = []
    req = RateRequester(sent.append, rates_hz={"ATTITUDE": 50.0, "VFR_HUD": 20.0},
                        ack_timeout_s=1.0, measure_s=4.0)
    ap = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    parse = mavlink.MAVLink(None)

    def msg(m):  # as the decoder delivers it
        return parse.decode(bytearray(m.pack(ap)))

    req.on_message(msg(mavlink.MAVLink_heartbeat_message(1, 3, 0, 0, 4, 3)))
    assert req.poll(0.0) is None and len(sent) == 2  # two SET_MESSAGE_INTERVAL
    cmds = [parse.decode(bytearray(b)) for b in sent]
    assert {c.param1 for c in cmds} == {30.0, 74.0}
    assert {round(c.param2) for c in cmds} == {20_000, 50_000}
    req.on_message(msg(mavlink.MAVLink_command_ack_message(
        mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, mavlink.MAV_RESULT_ACCEPTED)))
    req.poll(1.5)  # no answer for the second: REQUEST_DATA_STREAM for its group
    rds = [parse.decode(bytearray(b)) for b in sent[2:]]
    assert [r.get_type() for r in rds] == ["REQUEST_DATA_STREAM"]
    assert rds[0].req_stream_id == mavlink.MAV_DATA_STREAM_EXTRA2
    for k in range(80):
        req.on_message(msg(mavlink.MAVLink_attitude_message(k, 0, 0, 0, 0, 0, 0)))
    res = req.poll(4.0)
    assert res is not None
    by = {r.name: r for r in res}
    assert by["ATTITUDE"].ack == "ACCEPTED" and np.isclose(by["ATTITUDE"].measured_hz, 20.0)
    assert by["VFR_HUD"].ack == "no answer" and by["VFR_HUD"].fallback_stream == "EXTRA2"
