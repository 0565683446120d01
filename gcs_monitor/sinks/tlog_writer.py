"""Record the raw MAVLink input to a .tlog (8-byte big-endian µs timestamp + packet per record).

The file is readable by :class:`gcs_monitor.link.transports.TlogSource`, ``mavutil`` and
MAVProxy/Mission Planner. One record holds exactly one packet, so record decoded messages
(``write_message``: their wire bytes, ``msg.get_msgbuf()``) or packets you framed yourself
(``write_packet``); unframed chunks (``write_chunk``) are split into packets first and bytes that
are no MAVLink frame are skipped (counted). Data is flushed every ``flush_interval_s`` of wall
time and on close, so a crash loses at most that much.
"""

from __future__ import annotations

import struct
import time
from pathlib import Path
from types import TracebackType
from typing import Any, BinaryIO

TLOG_HEADER = struct.Struct(">Q")
MAV1_MAGIC = 0xFE
MAV2_MAGIC = 0xFD
MAV1_OVERHEAD = 8
MAV2_OVERHEAD = 12
MAV2_SIGNATURE = 13
MAV2_SIGNED = 0x01
US_PER_S = 1_000_000
DEFAULT_FLUSH_INTERVAL_S = 1.0


def split_packets(data: bytes) -> tuple[list[bytes], int]:
    """Split a byte chunk into whole MAVLink frames by their length bytes (no CRC check).

    Returns (frames, skipped bytes). A frame cut at the end of ``data`` is skipped too.
    """
    out: list[bytes] = []
    n = len(data)
    p = 0
    skipped = 0
    while p < n:
        magic = data[p]
        if magic == MAV2_MAGIC and p + 3 <= n:
            length = data[p + 1] + MAV2_OVERHEAD + (
                MAV2_SIGNATURE if data[p + 2] & MAV2_SIGNED else 0)
        elif magic == MAV1_MAGIC and p + 2 <= n:
            length = data[p + 1] + MAV1_OVERHEAD
        else:
            p += 1
            skipped += 1
            continue
        if p + length > n:
            skipped += n - p
            break
        out.append(data[p:p + length])
        p += length
    return out, skipped


class TlogRecorder:
    """Append-only .tlog recorder.

    Parameters
    ----------
    path : output file (created with its parent directory; an existing file is appended to)
    flush_interval_s : wall-time interval between flushes to the OS
    """

    def __init__(self, path: Path | str, *,
                 flush_interval_s: float = DEFAULT_FLUSH_INTERVAL_S) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fh: BinaryIO | None = open(self.path, "ab")  # noqa: SIM115 - closed in close()
        self.flush_interval_s = flush_interval_s
        self._last_flush = time.monotonic()
        self.records = 0
        self.bytes_written = 0
        self.skipped_bytes = 0

    def write_packet(self, packet: bytes, wall_s: float) -> None:
        """One record: ``wall_s`` (Unix seconds) as µs, then the packet bytes."""
        fh = self._fh
        if fh is None:
            raise ValueError(f"{self.path}: recorder is closed")
        fh.write(TLOG_HEADER.pack(int(round(wall_s * US_PER_S))))
        fh.write(packet)
        self.records += 1
        self.bytes_written += TLOG_HEADER.size + len(packet)
        now = time.monotonic()
        if now - self._last_flush >= self.flush_interval_s:
            fh.flush()
            self._last_flush = now

    def write_message(self, msg: Any, wall_s: float | None = None) -> None:
        """Record a decoded pymavlink message by its original wire bytes.

        ``wall_s`` defaults to ``msg._timestamp`` (set by mavutil, or by the monitor), else now.
        """
        if wall_s is None:
            wall_s = getattr(msg, "_timestamp", None) or time.time()
        self.write_packet(bytes(msg.get_msgbuf()), wall_s)

    def write_chunk(self, data: bytes, wall_s: float) -> None:
        """Record the whole frames in a raw chunk (one datagram, or frames on a stream link)."""
        frames, skipped = split_packets(data)
        self.skipped_bytes += skipped
        for f in frames:
            self.write_packet(f, wall_s)

    def flush(self) -> None:
        if self._fh is not None:
            self._fh.flush()
            self._last_flush = time.monotonic()

    def close(self) -> None:
        if self._fh is not None:
            self._fh.flush()
            self._fh.close()
            self._fh = None

    def __enter__(self) -> TlogRecorder:
        return self

    def __exit__(self, et: type[BaseException] | None, e: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


TlogWriter = TlogRecorder  # the name the CLI uses
