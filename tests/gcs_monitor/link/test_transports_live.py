"""Live sources on loopback (udpin, udpout, tcp, zenoh), serial errors, tlog pacing/progress and
the .tlog recorder round trip. Each test uses its own ports."""

from __future__ import annotations

import json
import socket
import threading
import time

import pytest

import gcs_monitor.link.transports as transports
from gcs_monitor.link.decode import Decoder
from gcs_monitor.link.transports import SourceError, TlogSource, open_source
from gcs_monitor.sinks.tlog_writer import TlogRecorder, split_packets
from tests.helpers.clock import FakeClock
from tests.helpers.mavgen import TLOG_EPOCH_US, MavGen, to_tlog


def _free_port(kind: int = socket.SOCK_DGRAM) -> int:
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _collect(src, n_expected: int, timeout_s: float = 3.0) -> list:
    d = Decoder()
    out: list = []
    t_end = time.monotonic() + timeout_s
    for data, _wall in src:
        out += d.feed(data, _wall)
        if len(out) >= n_expected or time.monotonic() > t_end:
            break
    return out


@pytest.fixture(scope="module")
def packets():
    return MavGen(n_imu=1).packets(0.2)


def test_udpin_receives_datagrams(packets):
    port = _free_port()
    with open_source(f"udpin:127.0.0.1:{port}", idle_timeout_s=2.0) as src:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
            for _, p in packets:
                tx.sendto(p, ("127.0.0.1", port))
        msgs = _collect(src, len(packets))
    assert len(msgs) == len(packets)


def test_udpout_says_hello_then_reads_replies(packets):
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as vehicle:
        vehicle.bind(("127.0.0.1", 0))
        vehicle.settimeout(2.0)
        port = vehicle.getsockname()[1]
        with open_source(f"udpout:127.0.0.1:{port}", idle_timeout_s=2.0) as src:
            hello, gcs_addr = vehicle.recvfrom(1024)
            hb = Decoder().feed(hello, 0.0)
            assert [m._type for m in hb] == ["HEARTBEAT"] and hb[0]._header.srcSystem == 255
            for _, p in packets:
                vehicle.sendto(p, gcs_addr)
            msgs = _collect(src, len(packets))
    assert len(msgs) == len(packets)


def test_tcp_client_reads_a_stream(packets):
    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    port = server.getsockname()[1]
    data = b"".join(p for _, p in packets)

    def serve() -> None:
        conn, _ = server.accept()
        with conn:
            for i in range(0, len(data), 777):  # split packets across reads
                conn.sendall(data[i:i + 777])
            time.sleep(0.3)

    th = threading.Thread(target=serve, daemon=True)
    th.start()
    try:
        with open_source(f"tcp:127.0.0.1:{port}", idle_timeout_s=2.0) as src:
            msgs = _collect(src, len(packets))
    finally:
        th.join(2.0)
        server.close()
    assert len(msgs) == len(packets)


def test_tcp_refused_is_a_source_error():
    port = _free_port(socket.SOCK_STREAM)
    with pytest.raises(SourceError, match="cannot connect"):
        open_source(f"tcp:127.0.0.1:{port}")


def test_serial_missing_device_is_a_clear_error():
    with pytest.raises(SourceError, match="pyserial|serial"):
        open_source("/dev/ttyDOES_NOT_EXIST:115200")


def test_zenoh_source_receives_raw_frames(packets):
    zenoh = pytest.importorskip("zenoh")
    port = _free_port(socket.SOCK_STREAM)
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("scouting/gossip/enabled", "false")
    conf.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    with zenoh.open(conf) as pub_session:
        pub = pub_session.declare_publisher("sim/vehicle/1/mavlink")
        with open_source(f"zenoh:sim/vehicle/1/mavlink@tcp/127.0.0.1:{port}",
                         idle_timeout_s=3.0) as src:
            time.sleep(0.3)  # let the peers link up (late subscribers get no history)
            for _, p in packets:
                pub.put(p)
            msgs = _collect(src, len(packets))
        pub.undeclare()
    assert len(msgs) == len(packets)


def test_tlog_speed_factor_and_progress(tmp_path, packets, monkeypatch):
    # Fake clock: each chunk is released when the clock reaches its recorded time at 2x.
    # (bench_pacing.py measures how closely the real clock follows.)
    clock = FakeClock()
    monkeypatch.setattr(transports, "time", clock)
    path = tmp_path / "run.tlog"
    path.write_bytes(to_tlog(packets))  # 0.2 s of vehicle time
    seen: list[tuple[int, int]] = []
    src = TlogSource(path, speed=2.0, chunk_bytes=512, on_progress=lambda a, b: seen.append((a, b)))
    t0_s = clock.now_s
    t_first_s = (TLOG_EPOCH_US + packets[0][0]) * 1e-6
    n = 0
    released = []
    for c, t_rec in src:
        n += len(Decoder().feed(c, t_rec))
        released.append((t_rec, clock.now_s))
        clock.advance(0.001)  # the consumer's work does not shift the schedule
    assert n == len(packets) and len(released) > 5
    for t_rec, at_s in released:
        assert at_s == pytest.approx(t0_s + (t_rec - t_first_s) / 2.0, abs=1e-6)  # s: µs stamps
    span_s = (packets[-1][0] - packets[0][0]) * 1e-6
    assert released[-1][1] - t0_s == pytest.approx(span_s / 2.0, abs=1e-6)
    done = [a for a, _ in seen]
    assert done == sorted(done) and seen[-1] == (path.stat().st_size, path.stat().st_size)


def test_recorder_round_trip(tmp_path, packets):
    path = tmp_path / "rec" / "out.tlog"
    d = Decoder()
    msgs = d.feed(b"".join(p for _, p in packets), 0.0)
    with TlogRecorder(path, flush_interval_s=0.0) as rec:
        for k, m in enumerate(msgs):
            rec.write_message(m, 1_700_000_000.0 + 0.001 * k)
        assert path.stat().st_size == rec.bytes_written  # flushed as it goes
    replay = [m for c, _ in TlogSource(path) for m in Decoder().feed(c, 0.0)]
    assert [bytes(m._msgbuf) for m in replay] == [p for _, p in packets]
    raw = path.read_bytes()
    assert int.from_bytes(raw[:8], "big") == 1_700_000_000_000_000  # big-endian µs


def test_split_packets_skips_garbage_and_cut_tail(packets):
    data = b"\x00\x01" + packets[0][1] + packets[1][1] + packets[2][1][:5]
    frames, skipped = split_packets(data)
    assert frames == [packets[0][1], packets[1][1]] and skipped == 2 + 5
