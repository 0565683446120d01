"""MAVLink 2 signing on the receiving side: key files and a signature check that cannot be
poisoned.

pymavlink's ``MAVLink.check_signature`` records a stream's timestamp *before* it verifies the
signature, so one forged packet with a far-future timestamp makes every genuine packet after it
look replayed. :class:`SigningMAVLink` verifies the signature first and only then checks and
records the timestamp, and says why a packet failed (``last_failure``: ``wrong_key`` or
``replayed``), so the decoder can count unsigned, forged and replayed packets apart.

A key file holds the 32-byte secret key: 64 hexadecimal characters (whitespace ignored), or the
32 raw bytes. ``gcs-monitor`` never prints it.
"""

from __future__ import annotations

import hashlib
import string
import struct
import time
from pathlib import Path
from typing import Any

from gcs_monitor.link.mav import mavlink

KEY_BYTES = 32
SIGNATURE_BYTES = 6
SIGNING_EPOCH_S = 1_420_070_400  # 2015-01-01T00:00:00Z, the MAVLink signing epoch
SIGNING_UNITS_PER_S = 100_000  # timestamps count 10 µs
NEW_STREAM_BEHIND = 60 * SIGNING_UNITS_PER_S  # a new stream may start at most a minute behind
_TIMESTAMP = struct.Struct("<IH")


class SigningKeyError(ValueError):
    """A signing key file that cannot be used; the message says what is expected."""


def load_signing_key(path: Path | str) -> bytes:
    """The 32-byte key in ``path`` (64 hex characters, or 32 raw bytes)."""
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise SigningKeyError(f"signing key {p}: {exc.strerror or exc}") from None
    text = raw.decode("ascii", errors="replace").strip()
    if len(text) == 2 * KEY_BYTES and all(ch in string.hexdigits for ch in text):
        return bytes.fromhex(text)
    if len(raw) == KEY_BYTES:
        return raw
    raise SigningKeyError(f"signing key {p}: expected 64 hexadecimal characters or 32 raw "
                          f"bytes, found {len(raw)} bytes")


def signing_now() -> int:
    """The current signing timestamp (10 µs units since 2015-01-01)."""
    return int((max(time.time(), SIGNING_EPOCH_S) - SIGNING_EPOCH_S) * SIGNING_UNITS_PER_S)


class SigningMAVLink(mavlink.MAVLink):  # type: ignore[misc]
    """The dialect's parser with a signature check that verifies before it records."""

    last_failure = ""

    def setup(self, key: bytes, *, require: bool, allow_unsigned_heartbeat: bool = False,
              timestamp: int | None = None) -> None:
        """Check signatures with ``key``; ``require``: reject unsigned packets."""
        if len(key) != KEY_BYTES:
            raise SigningKeyError(f"a signing key has {KEY_BYTES} bytes, not {len(key)}")
        sig = self.signing
        sig.secret_key = key
        sig.sign_outgoing = False
        sig.timestamp = signing_now() if timestamp is None else timestamp
        self._signed_now = False

        def allow_unsigned(mav: Any, msg_id: int) -> bool:
            # pymavlink also asks this for a *failed* signature: never let one through
            signed, self._signed_now = self._signed_now, False
            if signed:
                return False
            return not require or (allow_unsigned_heartbeat and
                                    msg_id == mavlink.MAVLINK_MSG_ID_HEARTBEAT)

        sig.allow_unsigned_callback = allow_unsigned

    def check_signature(self, msgbuf: bytearray, srcSystem: int,  # noqa: N803 - pymavlink's
                        srcComponent: int) -> bool:  # noqa: N803
        self._signed_now = True
        sig = self.signing
        h = hashlib.sha256()
        h.update(sig.secret_key)
        h.update(msgbuf[:-SIGNATURE_BYTES])
        if h.digest()[:SIGNATURE_BYTES] != bytes(msgbuf[-SIGNATURE_BYTES:]):
            self.last_failure = "wrong_key"
            return False
        tlow, thigh = _TIMESTAMP.unpack(bytes(msgbuf[-12:-6]))
        ts = tlow + (thigh << 32)
        stream = (msgbuf[-13], srcSystem, srcComponent)
        last = sig.stream_timestamps.get(stream)
        if (ts <= last) if last is not None else (ts + NEW_STREAM_BEHIND < sig.timestamp):
            self.last_failure = "replayed"
            return False
        sig.stream_timestamps[stream] = ts
        sig.timestamp = max(sig.timestamp, ts)
        self._signed_now = False  # accepted: the unsigned callback is not asked
        return True
