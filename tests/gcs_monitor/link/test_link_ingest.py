"""Ingest layer: transports (tlog walker, UDP bounded queue), Decoder and LinkStats on bad bytes.

Every check is against a count the test constructs itself (packets sent, dropped, duplicated,
reordered, flipped), so a wrong counter shows up as an exact mismatch.
"""

from __future__ import annotations

import socket
import time

import numpy as np
import pytest

from gcs_monitor.link.decode import MAX_BUFFER_BYTES, Decoder
from gcs_monitor.link.stats import LinkStats
from gcs_monitor.link.transports import (
    SourceError,
    TlogSource,
    UdpSource,
    _BoundedQueue,
    open_source,
)
from tests.helpers.mavgen import MavGen, drop, duplicate, flip_bits, join, reorder, to_tlog


@pytest.fixture(scope="module")
def packets() -> list[tuple[int, bytes]]:
    return MavGen(n_imu=1).packets(2.0)  # ~1300 packets, every contract message


def _decode(data: bytes, chunk: int = 4096) -> tuple[Decoder, list]:
    d = Decoder()
    out = []
    for i in range(0, len(data), chunk):
        out += d.feed(data[i:i + chunk], 0.0)
    out += d.flush()
    return d, out


def test_clean_stream_decodes_every_packet(packets):
    d, msgs = _decode(join(packets))
    assert len(msgs) == len(packets)
    st = d.stats[1]
    assert (st.lost, st.duplicates, st.reordered, st.duplicate_sysid) == (0, 0, 0, False)
    assert d.counters.parse_errors == 0 and d.counters.garbage_bytes == 0


def test_chunking_does_not_change_the_result(packets):
    data = join(packets)
    _, whole = _decode(data, chunk=len(data))
    _, small = _decode(data, chunk=7)  # splits almost every packet across chunks
    assert [bytes(m._msgbuf) for m in small] == [bytes(m._msgbuf) for m in whole]


def test_random_bytes_are_counted_not_raised():
    rng = np.random.default_rng(1)
    data = rng.integers(0, 256, 200_000, dtype=np.uint8).tobytes()
    d, msgs = _decode(data)
    c = d.counters
    # a random frame passes the 16-bit CRC (with the right CRC extra) about once in 2^16 tries
    assert len(msgs) <= 3
    assert c.garbage_bytes + c.parse_errors > 1000
    assert len(d._mav.buf) <= MAX_BUFFER_BYTES


def test_flipped_bits_cost_about_one_packet_each(packets):
    rng = np.random.default_rng(2)
    n_flips = 20
    data = flip_bits(join(packets), n_flips, rng)
    d, msgs = _decode(data)
    good = {p for _, p in packets}
    # CRC catches corruption: every delivered packet is one that was sent, bit for bit
    assert all(bytes(m._msgbuf) in good for m in msgs)
    # resynchronisation: a flip costs its own packet (a corrupted length byte may cost one more)
    assert len(packets) - len(msgs) <= 2 * n_flips
    assert d.counters.parse_errors > 0


def test_duplicates_are_dropped_and_counted(packets):
    dup = duplicate(packets, 0.1, np.random.default_rng(3))
    n_dup = len(dup) - len(packets)
    d, msgs = _decode(join(dup))
    assert len(msgs) == len(packets)
    assert d.counters.duplicates == n_dup == d.stats[1].duplicates


def test_reordered_packets_are_delivered_and_not_counted_lost(packets):
    ro = reorder(packets, 0.1, np.random.default_rng(4))
    n_swapped = sum(a != b for a, b in zip(ro, packets, strict=True)) // 2
    d, msgs = _decode(join(ro))
    st = d.stats[1]
    assert len(msgs) == len(packets)
    assert st.reordered == n_swapped
    assert st.lost == 0  # each late packet was taken back off the loss count


def test_thirty_percent_loss_is_measured(packets):
    kept = drop(packets, 0.3, np.random.default_rng(5))
    d, msgs = _decode(join(kept))
    st = d.stats[1]
    assert len(msgs) == len(kept)
    # lost = sequence gaps between the first and last packet received (drops before the first
    # or after the last leave no gap); a run of >= 256 consecutive drops could hide some
    idx = {p: i for i, (_, p) in enumerate(packets)}
    span = idx[kept[-1][1]] - idx[kept[0][1]] + 1
    assert st.lost == span - len(kept)
    assert st.loss_pct == pytest.approx(100 * (1 - len(kept) / span))
    assert 25 < st.loss_pct < 35


def test_unknown_message_ids_are_counted_and_skipped():
    g = MavGen()
    data = g.heartbeat() + g.unknown_message() + g.heartbeat()
    d, msgs = _decode(data)
    assert [m.get_type() for m in msgs] == ["HEARTBEAT", "HEARTBEAT"]
    assert d.counters.unknown_messages == 1 and d.stats[1].unknown_messages == 1


def test_two_senders_with_one_sysid_are_flagged():
    a = MavGen(sysid=1, seq0=0).packets(1.0)
    b = MavGen(sysid=1, seq0=128, t0_us=90_000_000).packets(1.0)
    merged = [p for pair in zip(a, b, strict=False) for p in pair]  # strictly interleaved
    d, _ = _decode(join(merged))
    assert d.stats[1].duplicate_sysid


def test_sequence_wraparound_is_not_loss():
    st = LinkStats(1)
    seqs = [*range(250, 256), *range(0, 6)]
    for s in seqs:
        assert st.on_packet(1, s, "X", bytes([s]), 0.0)
    assert st.lost == 0 and st.messages == len(seqs)
    st.on_packet(1, 9, "X", b"\x09", 0.0)  # 6, 7, 8 missing
    assert st.lost == 3


# -- tlog walker ------------------------------------------------------------------------------
def test_tlog_cut_mid_packet_ends_cleanly(tmp_path, packets):
    img = to_tlog(packets)
    cut = len(img) - 5  # inside the last packet
    path = tmp_path / "cut.tlog"
    path.write_bytes(img[:cut])
    src = TlogSource(path, chunk_bytes=1000)
    data = b"".join(c for c, _ in src)
    assert src.records == len(packets) - 1
    assert src.truncated_bytes == 8 + len(packets[-1][1]) - 5
    assert data == join(packets[:-1])


def test_tlog_garbage_between_records_is_skipped(tmp_path, packets):
    img = to_tlog(packets[:10])
    rec0 = 8 + len(packets[0][1])
    junk = b"\x00\x11\x22"  # no MAVLink magic
    path = tmp_path / "junk.tlog"
    path.write_bytes(img[:rec0] + junk + img[rec0:])
    src = TlogSource(path)
    data = b"".join(c for c, _ in src)
    assert src.resync_bytes == len(junk)
    assert data == join(packets[:10])


def test_empty_tlog_yields_nothing(tmp_path):
    path = tmp_path / "empty.tlog"
    path.write_bytes(b"")
    assert list(TlogSource(path)) == []


def test_open_source_rejects_bad_urls(tmp_path):
    with pytest.raises(SourceError, match="expected"):
        open_source("udpin:nohostport")
    with pytest.raises(SourceError, match="no such file"):
        open_source(str(tmp_path / "missing.tlog"))
    with pytest.raises(SourceError, match="expected one of"):
        open_source("carrier-pigeon:42")


# -- bounded memory ---------------------------------------------------------------------------
def test_bounded_queue_drops_oldest_and_counts():
    q = _BoundedQueue(max_chunks=10, max_bytes=1 << 20)
    for i in range(25):
        q.put((bytes([i]) * 3, float(i)))
    assert len(q) == 10 and q.high_water == 10
    assert (q.dropped_chunks, q.dropped_bytes) == (15, 45)
    assert q.get(0.0) == (bytes([15]) * 3, 15.0)  # the oldest kept one


def test_bounded_queue_byte_limit():
    q = _BoundedQueue(max_chunks=1000, max_bytes=100)
    for _ in range(50):
        q.put((b"x" * 10, 0.0))
    assert len(q) == 10 and q.dropped_chunks == 40


def test_udp_flood_keeps_queue_bounded():
    max_chunks = 50
    src = UdpSource("127.0.0.1", 0, listen=True, max_chunks=max_chunks, idle_timeout_s=0.3)
    port = src.sock.getsockname()[1]
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    n_sent = 2000
    try:
        pkt = MavGen().heartbeat()
        for _ in range(n_sent):  # nobody consumes while the flood arrives
            tx.sendto(pkt, ("127.0.0.1", port))
        deadline = time.monotonic() + 3.0
        while src._queue.dropped_chunks + len(src._queue) < n_sent \
                and time.monotonic() < deadline:
            time.sleep(0.02)
        received = src._queue.dropped_chunks + len(src._queue)
        assert len(src._queue) <= max_chunks and src._queue.high_water <= max_chunks
        assert src.dropped_chunks == received - max_chunks > 0
        got = list(src)  # drains the queue, then the idle timeout ends the iteration
        assert len(got) == max_chunks
    finally:
        tx.close()
        src.close()
