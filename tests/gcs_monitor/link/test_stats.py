"""LinkStats on hand-written sequence numbers, signing failures and the health dict."""

from __future__ import annotations

import hashlib
import json

from gcs_monitor.link.decode import Decoder
from gcs_monitor.link.signing import signing_now
from gcs_monitor.link.stats import DUP_HEARTBEATS_CLEAR, DUP_SUSTAIN, LinkStats
from tests.helpers.mavgen import MavGen


def _feed(st: LinkStats, seqs: list[int], compid: int = 1) -> None:
    for k, s in enumerate(seqs):
        st.on_packet(compid, s, "X", bytes([s, k % 256]), float(k))


def test_wraparound_is_not_loss_and_gap_across_wrap_counts_exactly():
    st = LinkStats(1)
    _feed(st, [253, 254, 255, 0, 1])
    assert st.lost == 0
    _feed(st, [5])  # 1 -> 5 skips 2, 3, 4
    assert st.lost == 3
    st2 = LinkStats(1)
    _feed(st2, [250, 2])  # 250 -> 2 across the wrap skips 251..255, 0, 1 = 7 packets
    assert st2.lost == 7


def test_late_packet_is_taken_back_off_lost():
    st = LinkStats(1)
    _feed(st, [10, 12, 11, 13])  # 11 arrives after 12
    assert (st.lost, st.reordered, st.messages) == (0, 1, 4)
    assert st.loss_pct == 0.0


def test_exact_repeat_is_a_duplicate_and_rejected():
    st = LinkStats(1)
    assert st.on_packet(1, 7, "X", b"abc", 0.0)
    assert not st.on_packet(1, 7, "X", b"abc", 0.0)
    assert (st.duplicates, st.messages) == (1, 1)


def test_components_have_separate_sequences():
    st = LinkStats(1)
    for k in range(10):
        st.on_packet(1, k, "A", b"a%d" % k, 0.0)
        st.on_packet(2, 100 + k, "B", b"b%d" % k, 0.0)
    assert st.lost == 0 and st.reordered == 0


def test_interleaved_streams_flag_duplicate_sysid_only_when_sustained():
    st = LinkStats(1)
    n = DUP_SUSTAIN * 3
    for k in range(n):  # two senders: seq k and seq k + 100, alternating
        st.on_packet(1, k % 256, "X", b"a%d" % k, 0.0)
        st.on_packet(1, (k + 100) % 256, "X", b"b%d" % k, 0.0)
    assert st.duplicate_sysid
    burst = LinkStats(1)
    seqs = list(range(200)) + [150 + (k % 2) * 30 for k in range(40)] + list(range(200, 256))
    _feed(burst, seqs)  # a short burst of backward steps (buffering radio at a reboot)
    assert not burst.duplicate_sysid


def test_heartbeat_type_change_flags_duplicate_sysid():
    st = LinkStats(1)
    st.on_heartbeat(1, 1, 3)
    assert not st.duplicate_sysid and st.is_vehicle
    st.on_heartbeat(1, 2, 3)
    assert st.duplicate_sysid and st.heartbeat_conflicts == 1


def test_rates_bad_values_and_json_health():
    st = LinkStats(3)
    for k in range(11):
        st.on_packet(1, k, "ATTITUDE", b"x" * 40 + bytes([k]), 100.0 + 0.1 * k)
    st.bad_value("HIGHRES_IMU.xacc", 2)
    d = st.as_dict()
    assert abs(d["rates_hz"]["ATTITUDE"] - 11 / 1.0) < 1e-9  # 11 packets over 1.0 s of wall time
    assert d["bytes"] == 11 * 41 and d["bad_values"] == {"HIGHRES_IMU.xacc": 2}
    json.dumps(d)


def test_signature_failures_are_counted_per_sender():
    key = hashlib.sha256(b"secret").digest()
    good = MavGen(sysid=7)
    good.mav.signing.secret_key = key
    good.mav.signing.sign_outgoing = True
    good.mav.signing.timestamp = signing_now()  # a real sender signs with its clock
    bad = MavGen(sysid=8)  # unsigned
    data = b"".join(good.heartbeat() for _ in range(5)) + b"".join(
        bad.heartbeat() for _ in range(4))
    d = Decoder(signing_key=key)
    msgs = d.feed(data, 0.0)
    assert [m._header.srcSystem for m in msgs] == [7] * 5
    assert d.counters.bad_signature == 4 and d.stats[8].signature_failures == 4
    json.dumps(d.health())


def test_recent_rates_follow_a_rate_change():
    st = LinkStats(1)
    k = 0
    for rate_hz, dur_s, t0 in ((10.0, 6.0, 0.0), (50.0, 10.0, 6.0)):
        n = int(rate_hz * dur_s)
        for j in range(n):
            st.on_packet(1, k % 256, "ATTITUDE", bytes([k % 256, k // 256 % 256]),
                         t0 + j / rate_hz)
            k += 1
    # windows close at 5, 10, 15 s: the last one (10-15 s) lies inside the 50 Hz part
    assert abs(st.recent_rates_hz["ATTITUDE"] - 50.0) < 50.0 * 0.05
    assert abs(st.as_dict()["rates_hz"]["ATTITUDE"] - k / st.span_s) < 1e-9


def test_duplicate_sysid_clears_when_the_second_sender_stops():
    st = LinkStats(1)
    for k in range(DUP_SUSTAIN * 3):  # two senders interleave
        st.on_packet(1, k % 256, "X", b"a%d" % k, 0.0)
        st.on_packet(1, (k + 100) % 256, "X", b"b%d" % k, 0.0)
    assert st.duplicate_sysid
    seq = DUP_SUSTAIN * 3
    for k in range(DUP_SUSTAIN):  # one sender left: the backward-step EWMA decays ...
        st.on_packet(1, (seq + k) % 256, "X", b"c%d" % k, 0.0)
    assert st.duplicate_sysid  # ... and must stay low for DUP_SUSTAIN packets
    for k in range(DUP_SUSTAIN, 3 * DUP_SUSTAIN):
        st.on_packet(1, (seq + k) % 256, "X", b"c%d" % k, 0.0)
    assert not st.duplicate_sysid and st.duplicate_sysid_seen
    assert st.as_dict()["duplicate_sysid"] is False


def test_heartbeat_conflict_clears_after_agreeing_heartbeats():
    st = LinkStats(1)
    st.on_heartbeat(1, 1, 3)
    st.on_heartbeat(1, 2, 3)  # another sender's type
    for _ in range(DUP_HEARTBEATS_CLEAR - 1):
        st.on_heartbeat(1, 2, 3)
        assert st.duplicate_sysid
    st.on_heartbeat(1, 2, 3)
    assert not st.duplicate_sysid and st.duplicate_sysid_seen


def test_clock_conflict_evidence_expires():
    st = LinkStats(1)
    st.duplicate_sysid = True  # what the assembler sets on interleaving vehicle clocks
    for k in range(DUP_SUSTAIN - 1):
        st.on_packet(1, k % 256, "X", b"a%d" % k, 0.0)
    assert st.duplicate_sysid
    st.on_packet(1, (DUP_SUSTAIN - 1) % 256, "X", b"last", 0.0)
    assert not st.duplicate_sysid and st.duplicate_sysid_seen
