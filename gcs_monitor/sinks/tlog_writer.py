"""Raw input recording to .tlog (8-byte big-endian µs wall timestamp + one packet)."""

from __future__ import annotations

import struct
import time
from pathlib import Path
from typing import Any, BinaryIO

_TS = struct.Struct(">Q")


class TlogWriter:
    """Appends every decoded packet, as received, to a .tlog; flushed about once a second."""

    def __init__(self, path: Path | str, *, flush_period_s: float = 1.0) -> None:
        self.path = Path(path)
        self._fh: BinaryIO | None = open(self.path, "ab")  # noqa: SIM115 - closed in close()
        self._period = flush_period_s
        self._next = time.monotonic() + flush_period_s
        self.packets = 0

    def write_message(self, msg: Any) -> None:
        """Record one pymavlink message with its receive time (``msg._timestamp`` if set)."""
        if self._fh is None:
            return
        ts = getattr(msg, "_timestamp", None) or time.time()
        self._fh.write(_TS.pack(int(ts * 1e6)) + bytes(msg.get_msgbuf()))
        self.packets += 1
        now = time.monotonic()
        if now >= self._next:
            self._fh.flush()
            self._next = now + self._period

    def close(self) -> None:
        if self._fh is not None:
            self._fh.close()
            self._fh = None
