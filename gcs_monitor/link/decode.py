"""pymavlink decoding on the hot path and per-vehicle (sysid/compid) demultiplexing.

The decoder drives pymavlink's own incremental parser (``MAVLink.parse_char``, the loop inside
``parse_buffer``) with ``robust_parsing`` on, and never goes through ``mavutil``. Two things are
added on top:

* **Resynchronisation.** pymavlink drops a whole frame when its CRC fails. When the failure was
  a corrupted length byte, that "frame" swallowed up to 280 bytes of the following good packets.
  After a CRC/length failure, or an unknown message id (pymavlink does not check the CRC of
  those, so noise shows up as "unknown"), the decoder re-feeds the frame minus its first byte,
  so the next good packet inside it is found (one corrupt byte costs one packet, not several).
* **Bounded buffer.** pymavlink only empties its buffer when a chunk ends exactly on a packet
  boundary; on stream links (TCP, serial) the buffer is compacted after every chunk.

Everything that cannot be passed on is counted (``counters`` link-wide, ``stats[sysid]`` per
vehicle), never raised.

**Signing** (MAVLink 2, :mod:`gcs_monitor.link.signing`): with a key, a signed packet is passed on
only if its signature verifies and its timestamp is newer than its stream's last one; unsigned
packets only when signing is not required. Rejected packets are counted by cause (unsigned,
wrong key, replayed), per claimed sender and link-wide, and never reach the families.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable
from typing import Any

from gcs_monitor.link.mav import mavlink
from gcs_monitor.link.signing import SigningMAVLink
from gcs_monitor.link.stats import LinkCounters, LinkStats

log = logging.getLogger(__name__)

MSG_HEARTBEAT = mavlink.MAVLINK_MSG_ID_HEARTBEAT
MAV1_MAGIC = 0xFE
MAV2_MAGIC = 0xFD
MAV2_SYSID_OFFSET = 5
MAV1_SYSID_OFFSET = 3
MAX_BUFFER_BYTES = 1 << 16  # a stuck partial frame can never hold more than this
MAV2_IFLAG_SIGNED = 0x01
# messages that carry the sender's clock (time since boot, ms): they bound burst losses
CLOCK_IDS = frozenset(mid for mid, cls in mavlink.mavlink_map.items()
                      if "time_boot_ms" in cls.fieldnames)
# messages with an instance id and a time stamp: (payload offset of the id, time field). A
# MAVLink 1 frame whose payload ends before that offset lacks the id (an extension): every
# instance then reads as 0
MAV1_INSTANCE_IDS = {
    mid: (int(cls.instance_offset), tf)
    for mid, cls in mavlink.mavlink_map.items()
    if getattr(cls, "instance_field", None) and getattr(cls, "instance_offset", None) is not None
    for tf in ("time_usec", "time_boot_ms") if tf in cls.fieldnames
}


def _sender(buf: bytes | bytearray) -> int | None:
    """Sysid from a raw frame's header, or None if the bytes are too short to say."""
    if len(buf) > MAV2_SYSID_OFFSET and buf[0] == MAV2_MAGIC:
        return buf[MAV2_SYSID_OFFSET]
    if len(buf) > MAV1_SYSID_OFFSET and buf[0] == MAV1_MAGIC:
        return buf[MAV1_SYSID_OFFSET]
    return None


class Decoder:
    """Decode byte chunks into MAVLink messages, per vehicle, counting what it cannot use.

    ``feed(data, wall_s)`` returns the decoded messages in arrival order (all sysids, minus
    exact duplicates, BAD_DATA and unknown ids). ``stats[sysid]`` holds each sender's
    :class:`LinkStats`; ``counters`` the link-wide :class:`LinkCounters`.

    Parameters
    ----------
    signing_key : 32-byte MAVLink 2 signing key. When set, badly signed and replayed packets are
        rejected (counted as signature failures), and so are unsigned ones if
        ``require_signing`` (except HEARTBEAT if ``allow_unsigned_heartbeat``)
    require_signing : reject unsigned packets (only with a key)
    signing_timestamp : the signing clock to start from (10 µs units since 2015-01-01): a
        stream first seen more than a minute behind it is a replay. None: now (as pymavlink's
        ``setup_signing``)
    resync : re-scan failed frames (module docstring); False gives plain pymavlink behaviour
    """

    def __init__(self, *, signing_key: bytes | None = None, require_signing: bool = True,
                 allow_unsigned_heartbeat: bool = False, signing_timestamp: int | None = None,
                 resync: bool = True) -> None:
        self.resync = resync
        self.signing = signing_key is not None
        self._mav = SigningMAVLink(None) if signing_key is not None else mavlink.MAVLink(None)
        self._mav.robust_parsing = True
        if signing_key is not None:
            assert isinstance(self._mav, SigningMAVLink)
            self._mav.setup(signing_key, require=require_signing,
                            allow_unsigned_heartbeat=allow_unsigned_heartbeat,
                            timestamp=signing_timestamp)
        self.counters = LinkCounters()
        self.stats: dict[int, LinkStats] = {}

    def vehicle_stats(self, sysid: int) -> LinkStats:
        """The statistics of one sysid (created on first use)."""
        st = self.stats.get(sysid)
        if st is None:
            st = self.stats[sysid] = LinkStats(sysid)
        return st

    def vehicles(self) -> list[int]:
        """Sysids whose HEARTBEAT says they are vehicles (not GCS, radio or companion)."""
        return sorted(s for s, st in self.stats.items() if st.is_vehicle)

    def note_source(self, source: Any) -> None:
        """Copy a source's drop/resync counters into ``counters`` (bounded-queue overflow)."""
        c = self.counters
        c.dropped_chunks = int(getattr(source, "dropped_chunks", 0))
        c.dropped_bytes = int(getattr(source, "dropped_bytes", 0))
        c.resync_bytes = int(getattr(source, "resync_bytes", 0))
        c.kernel_drops = int(getattr(source, "kernel_drops", 0) or 0)

    def health(self) -> dict[str, Any]:
        """JSON-ready link health: link-wide counters and every sender's statistics."""
        return {"link": self.counters.as_dict(),
                "senders": {str(k): v.as_dict() for k, v in sorted(self.stats.items())}}

    def feed(self, data: bytes, wall_s: float) -> list[Any]:
        """Decode one chunk (any framing: a datagram, a TCP read, several tlog packets)."""
        c = self.counters
        c.bytes_in += len(data)
        c.chunks += 1
        mav = self._mav
        parse = mav.parse_char
        out: list[Any] = []
        stats = self.stats
        try:
            m = parse(data)
            while m is not None:
                hdr = getattr(m, "_header", None)
                if hdr is None or m._type == "BAD_DATA" or hdr.msgId < 0:
                    self._reject(m)
                else:
                    sysid = hdr.srcSystem
                    st = stats.get(sysid)
                    if st is None:
                        st = stats[sysid] = LinkStats(sysid)
                    mid = hdr.msgId
                    if st.on_packet(hdr.srcComponent, hdr.seq, m._type, m._msgbuf, wall_s,
                                    m.time_boot_ms if mid in CLOCK_IDS else None):
                        if mid == MSG_HEARTBEAT:
                            st.on_heartbeat(hdr.srcComponent, m.type, m.autopilot)
                        elif mid in MAV1_INSTANCE_IDS and m._msgbuf[0] == MAV1_MAGIC:
                            offset, tfield = MAV1_INSTANCE_IDS[mid]
                            if m._msgbuf[1] <= offset:  # the frame ends before the id
                                st.on_mav1_instance(m._type, getattr(m, tfield))
                        if self.signing:
                            if hdr.incompat_flags & MAV2_IFLAG_SIGNED:
                                st.signed_packets += 1
                            else:
                                st.unsigned_accepted += 1
                        out.append(m)
                    else:
                        c.duplicates += 1
                m = parse(b"")
        except Exception as exc:  # robust_parsing should prevent this; never let bytes kill us
            c.parse_errors += 1
            log.debug("parse error: %s", exc)
            mav.buf = bytearray()
            mav.buf_index = 0
            mav.expected_length = mavlink.HEADER_LEN_V1 + 2
        if mav.buf_index:  # compact: keep only the unparsed tail (bounded memory)
            del mav.buf[:mav.buf_index]
            mav.buf_index = 0
        if len(mav.buf) > MAX_BUFFER_BYTES:
            c.parse_errors += 1
            mav.buf = bytearray()
        return out

    def flush(self, wall_s: float = 0.0) -> list[Any]:
        """End of input: re-scan bytes held by a frame that never completed (cut or fake length).

        Each pass drops the first held byte and parses the rest, so good packets behind a
        corrupted length byte at the very end of a file are still delivered.
        """
        out: list[Any] = []
        mav = self._mav
        while len(mav.buf) - mav.buf_index > 0:
            rest = bytes(mav.buf[mav.buf_index + 1:])
            self.counters.garbage_bytes += 1
            mav.buf = bytearray()
            mav.buf_index = 0
            mav.expected_length = mavlink.HEADER_LEN_V1 + 2
            out += self.feed(rest, wall_s)
            self.counters.chunks -= 1
            self.counters.bytes_in -= len(rest)
        return out

    def _reject(self, m: Any) -> None:
        c = self.counters
        raw = bytes(m._msgbuf)
        sysid = _sender(raw)
        if m._type != "BAD_DATA":
            # MAVLink_unknown: id not in the dialect. pymavlink returns these before any CRC
            # check, so noise that looks like a frame start lands here too, and its length
            # byte may span good packets: count it, then re-scan it like a CRC failure.
            c.unknown_messages += 1
            st = self.stats.get(sysid) if sysid is not None else None
            if st is not None:  # noise must not invent senders
                st.unknown_messages += 1
        else:
            reason = m.reason
            if reason == "Bad prefix":
                c.garbage_bytes += len(raw)
                return
            if "signature" in reason:
                c.bad_signature += 1
                signed = len(raw) > 2 and raw[0] == MAV2_MAGIC and raw[2] & MAV2_IFLAG_SIGNED
                cause = getattr(self._mav, "last_failure", "wrong_key") if signed \
                    else "unsigned_rejected"
                setattr(c, cause, getattr(c, cause) + 1)
                if sysid is not None:
                    st = self.vehicle_stats(sysid)
                    st.signature_failures += 1
                    setattr(st, cause, getattr(st, cause) + 1)
                return
            c.parse_errors += 1
        # resync: re-scan the failed frame from its second byte (see module docstring)
        if self.resync and len(raw) > 1:
            mav = self._mav
            tail = mav.buf[mav.buf_index:]
            mav.buf = bytearray(raw[1:]) + tail
            mav.buf_index = 0
            mav.expected_length = mavlink.HEADER_LEN_V1 + 2


def split_by_sysid(msgs: Iterable[Any]) -> dict[int, list[Any]]:
    """Group decoded messages by sender sysid, keeping arrival order within each vehicle."""
    out: dict[int, list[Any]] = {}
    for m in msgs:
        s = m._header.srcSystem
        lst = out.get(s)
        if lst is None:
            out[s] = [m]
        else:
            lst.append(m)
    return out


def decode_all(chunks: Iterable[tuple[bytes, float]], on_message: Callable[[Any], None],
               decoder: Decoder | None = None) -> Decoder:
    """Feed every (bytes, wall_s) chunk through a decoder, calling ``on_message`` per message."""
    dec = decoder or Decoder()
    for data, wall in chunks:
        for m in dec.feed(data, wall):
            on_message(m)
    dec.note_source(chunks)
    return dec
