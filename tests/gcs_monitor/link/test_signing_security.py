"""MAVLink 2 signing: forged, unsigned and replayed packets are rejected, counted apart, alarmed as
a link problem (LINK/signature) and never reach the families; the simulator signs."""

from __future__ import annotations

import hashlib
import math
import subprocess
import sys
import time

import pytest

from gcs_monitor.fdi.events import AlarmKind, AlarmState
from gcs_monitor.link.decode import Decoder
from gcs_monitor.link.mav import mavlink
from gcs_monitor.link.signing import SigningKeyError, load_signing_key
from gcs_monitor.monitor import Monitor
from sim_vehicle.mavlink_out import MavlinkSigner
from tests.helpers.fleet import ROOT, free_port, template

KEY = hashlib.sha256(b"fleet key").digest()
WRONG = hashlib.sha256(b"not the key").digest()
S = 1_000_000
INJECT = (3 * S, 4 * S)  # injected packets ride among the genuine ones in this window


def _aoa_spoof(t_us: int, seq: int) -> bytes:
    """An AOA_SSA of vehicle 1 saying 25 deg: judged, it would raise an AoA fault at once."""
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    mav.seq = seq
    return bytes(mavlink.MAVLink_aoa_ssa_message(t_us, 25.0, 0.0).pack(mav))


@pytest.fixture(scope="module")
def genuine() -> list[tuple[int, bytes]]:
    signer = MavlinkSigner(KEY)  # the simulator signs with its clock
    return [(t, signer.sign(p, t)) for t, p in template(10.0, 1, None)]


def _run(stream: list[bytes]) -> Monitor:
    m = Monitor(decoder=Decoder(signing_key=KEY, require_signing=True))
    data = b"".join(stream)
    for i in range(0, len(data), 4096):
        m.feed(data[i:i + 4096])
    m.finish()
    return m


def _inject(genuine: list[tuple[int, bytes]], make) -> tuple[list[bytes], int]:  # type: ignore[no-untyped-def]
    out, n = [], 0
    for k, (t, p) in enumerate(genuine):
        out.append(p)
        if INJECT[0] <= t < INJECT[1] and k % 5 == 0:
            out.append(make(t, k))
            n += 1
    return out, n


def _check(m: Monitor, *, unsigned: int, wrong_key: int, replayed: int) -> None:
    c = m.decoder.counters
    assert (c.unsigned_rejected, c.wrong_key, c.replayed) == (unsigned, wrong_key, replayed)
    assert c.bad_signature == unsigned + wrong_key + replayed
    st = m.decoder.stats[1]
    assert (st.unsigned_rejected, st.wrong_key, st.replayed) == (unsigned, wrong_key, replayed)
    assert not [e for e in m.events if e.kind is not AlarmKind.LINK]  # families never fed
    sig = [e.state for e in m.events if e.channel.axis == "signature"]
    # raised once (updated as the count grows), cleared 5 s after the last rejection
    assert sig[0] is AlarmState.RAISED and sig[-1] is AlarmState.CLEARED
    assert sig.count(AlarmState.RAISED) == 1 and set(sig[1:-1]) <= {AlarmState.UPDATED}
    raised = next(e for e in m.events if e.channel.axis == "signature")
    assert INJECT[0] <= raised.t_us <= INJECT[1] + 1_100_000  # next link check (1 s)
    h = m.vehicle_health(1)["link"]
    assert h["signature_failures"] == unsigned + wrong_key + replayed
    assert h["signed_packets"] == m.decoder.stats[1].messages


def test_forged_packets_are_rejected_and_counted(genuine) -> None:
    forger = MavlinkSigner(WRONG)
    stream, n = _inject(genuine, lambda t, k: forger.sign(_aoa_spoof(t, k % 256)))
    _check(_run(stream), unsigned=0, wrong_key=n, replayed=0)
    assert n >= 100  # one in five of the genuine packets of that second (about 650)


def test_unsigned_packets_are_rejected_and_counted(genuine) -> None:
    stream, n = _inject(genuine, lambda t, k: _aoa_spoof(t, k % 256))
    _check(_run(stream), unsigned=n, wrong_key=0, replayed=0)


def test_replayed_packets_are_rejected_and_counted(genuine) -> None:
    earlier = [p for t, p in genuine if 1 * S <= t < 2 * S]
    stream, n = _inject(genuine, lambda t, k: earlier[k % len(earlier)])
    _check(_run(stream), unsigned=0, wrong_key=0, replayed=n)


def test_a_forged_future_timestamp_does_not_lock_the_vehicle_out(genuine) -> None:
    """pymavlink records a stream's timestamp before it checks the signature: one forged
    packet from the far future would make every genuine packet after it 'replayed'."""
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    mav.signing.secret_key = WRONG
    mav.signing.sign_outgoing = True
    mav.signing.timestamp = 2**47  # ~ the year 2059
    poison = bytes(mavlink.MAVLink_aoa_ssa_message(0, 25.0, 0.0).pack(mav))
    stream = [p for _, p in genuine]
    m = _run(stream[:100] + [poison] + stream[100:])
    assert m.decoder.counters.wrong_key == 1 and m.decoder.counters.replayed == 0
    assert m.decoder.stats[1].messages == len(stream)


def test_key_files() -> None:
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as d:
        hexf, raw, bad = Path(d, "k.hex"), Path(d, "k.bin"), Path(d, "k.bad")
        hexf.write_text(KEY.hex() + "\n")
        raw.write_bytes(KEY)
        bad.write_text("passphrase")
        assert load_signing_key(hexf) == KEY == load_signing_key(raw)
        with pytest.raises(SigningKeyError, match="expected 64 hexadecimal characters or 32 "
                                                  "raw bytes, found 10 bytes"):
            load_signing_key(bad)


def test_live_with_require_signing_counts_and_reports(tmp_path, genuine) -> None:
    """``gcs-monitor live --signing-key K --require-signing``: the summary says what was
    rejected and why; the alarm journal holds the LINK/signature alarm and no fault."""
    key = tmp_path / "key.hex"
    key.write_text(KEY.hex())
    port = free_port(kind=2)  # SOCK_DGRAM
    journal = tmp_path / "alarms.jsonl"
    forger = MavlinkSigner(WRONG)
    stream, n_forged = _inject(genuine[: len(genuine) // 2],
                               lambda t, k: forger.sign(_aoa_spoof(t, k % 256)))
    proc = subprocess.Popen(
        [sys.executable, "-m", "gcs_monitor.cli", "live", f"udpin:127.0.0.1:{port}",
         "--signing-key", str(key), "--require-signing", "--idle-timeout", "2", "--quiet",
         "--journal", str(journal)],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().startswith("listening on")  # the socket is bound
        import socket

        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            for k, p in enumerate(stream):
                s.sendto(p, ("127.0.0.1", port))
                if k % 100 == 0:
                    time.sleep(0.06)  # ~2 s: the monitor reports while it happens
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    assert (f"{n_forged} rejected by signing (unsigned 0, wrong key {n_forged}, replayed 0)"
            in out), out
    assert f"signing: {n_forged} rejected (unsigned 0, wrong key {n_forged}, replayed 0)" in out
    assert "packets rejected by signing" in err  # said while it happens, not only at the end
    lines = journal.read_text().splitlines()
    assert lines and all('"kind":"link"' in ln and '"axis":"signature"' in ln for ln in lines)
    assert math.isfinite(n_forged)
