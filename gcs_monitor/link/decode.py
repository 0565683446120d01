"""pymavlink decoding on the hot path (``parse_buffer``) and per-sysid demultiplexing."""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

from gcs_monitor.link.mav import mavlink
from gcs_monitor.link.stats import LinkCounters, LinkStats

log = logging.getLogger(__name__)

MSG_HEARTBEAT = mavlink.MAVLINK_MSG_ID_HEARTBEAT
_BAD = mavlink.MAVLink_bad_data
_UNKNOWN = mavlink.MAVLink_unknown


class _NullFile:
    def write(self, data: bytes) -> None:  # pragma: no cover - never sends
        pass


class Decoder:
    """Decodes byte chunks into messages, counting everything it cannot use.

    ``feed`` returns the decoded messages in arrival order; BAD_DATA (CRC errors, garbage,
    bad signatures, unknown ids) are counted in ``counters`` and not returned. Per-vehicle
    statistics live in ``stats[sysid]``.

    Parameters
    ----------
    signing_key : 32-byte MAVLink 2 signing key; when set, unsigned or badly signed packets
        are rejected and counted as signature failures
    """

    def __init__(self, *, signing_key: bytes | None = None) -> None:
        self._mav = mavlink.MAVLink(_NullFile())
        self._mav.robust_parsing = True
        if signing_key is not None:
            self._mav.signing.secret_key = signing_key
            self._mav.signing.sign_outgoing = False
            self._mav.signing.allow_unsigned_callback = None
        self.counters = LinkCounters()
        self.stats: dict[int, LinkStats] = {}
        self._last_wall = 0.0

    def vehicle_stats(self, sysid: int) -> LinkStats:
        st = self.stats.get(sysid)
        if st is None:
            st = self.stats[sysid] = LinkStats(sysid)
        return st

    def feed(self, data: bytes, wall_s: float) -> list[Any]:
        c = self.counters
        c.bytes_in += len(data)
        c.chunks += 1
        try:
            msgs = self._mav.parse_buffer(data)
        except Exception as exc:  # pymavlink raises on some malformed input even when robust
            c.parse_errors += 1
            log.debug("parse error: %s", exc)
            self._mav.buf = bytearray()
            self._mav.buf_index = 0
            return []
        if not msgs:
            return []
        out: list[Any] = []
        stats = self.stats
        for m in msgs:
            if isinstance(m, _BAD):
                reason = getattr(m, "reason", "")
                if "signature" in reason:
                    c.bad_signature += 1
                elif "unknown" in reason.lower():
                    c.unknown_messages += 1
                else:
                    c.parse_errors += 1
                continue
            if isinstance(m, _UNKNOWN):
                c.unknown_messages += 1
            hdr = m._header
            sysid = hdr.srcSystem
            st = stats.get(sysid)
            if st is None:
                st = stats[sysid] = LinkStats(sysid)
            st.on_message(hdr.srcComponent, hdr.seq, m._type, len(m._msgbuf), wall_s)
            if hdr.msgId == MSG_HEARTBEAT:
                st.on_heartbeat(hdr.srcComponent, m.type, m.autopilot)
            out.append(m)
        c.bad_signature = max(c.bad_signature, int(getattr(self._mav.signing, "badsig_count", 0)))
        return out


def decode_all(chunks: Any, on_message: Callable[[Any], None],
               decoder: Decoder | None = None) -> Decoder:
    """Feed every (bytes, wall_s) chunk through a decoder, calling ``on_message`` per message."""
    dec = decoder or Decoder()
    for data, wall in chunks:
        for m in dec.feed(data, wall):
            on_message(m)
    return dec
