"""Any flight log as a byte source: ``open_log`` (the reader other commands call).

A ``.tlog`` is read as it is (:class:`~gcs_monitor.link.transports.TlogSource`); an ArduPilot
DataFlash log, a PX4 ULog or a CSV goes through its reader in :mod:`gcs_monitor.convert`,
which gives the contract's MAVLink messages, and :class:`MessageSource` packs them as MAVLink 2
bytes. Either way the monitor decodes bytes, as from a live link.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from gcs_monitor.convert.encode import TLOG_EPOCH_US, Packer
from gcs_monitor.convert.logbase import LogError, LogInfo, Messages, log_error
from gcs_monitor.convert.logs import detect_log_format, extension_note, read_messages
from gcs_monitor.link.transports import Source, TlogSource

DEFAULT_CHUNK_BYTES = 16384


# A reader yields (vehicle time µs, MAVLink message object) in time order and fills its info.
class MessageSource(Source):
    """A log's contract messages as MAVLink 2 byte chunks (a :class:`Source`, like a tlog).

    Each chunk's wall time is the vehicle time of its last message on the converters' fixed
    epoch (``encode.TLOG_EPOCH_US``), so link statistics measure the log's own rates.

    Parameters
    ----------
    messages : the reader's ``(t_us, message)`` iterator
    info : the reader's :class:`LogInfo` (counts filled in while iterating)
    speed : replay speed factor against vehicle time (None: as fast as possible)
    on_progress : called with (done, total) in vehicle-time µs when ``total_us`` is known
    """

    def __init__(self, messages: Messages, info: LogInfo, *, sysid: int = 1,
                 speed: float | None = None, chunk_bytes: int = DEFAULT_CHUNK_BYTES,
                 on_progress: Callable[[int, int], None] | None = None,
                 total_us: int | None = None) -> None:
        if speed is not None and not speed > 0:
            raise LogError(f"replay speed must be > 0, got {speed}")
        self.info = info
        self.path = info.path
        self._messages = messages
        self._packer = Packer(sysid=sysid, compid=1)
        self.speed = speed
        self.chunk_bytes = chunk_bytes
        self.on_progress = on_progress
        self.total_us = total_us
        self.records = 0
        self.truncated_bytes = 0
        self.total_bytes = info.path.stat().st_size if info.path.exists() else 0

    def __iter__(self) -> Iterator[tuple[bytes, float]]:
        pack = self._packer.pack
        parts: list[bytes] = []
        size = 0
        t_us = 0
        t0_us: int | None = None
        t0_wall = time.monotonic()
        n = 0
        for t_us, msg in self._messages:
            if t0_us is None:
                t0_us = t_us
            b = pack(msg)
            parts.append(b)
            size += len(b)
            n += 1
            if size >= self.chunk_bytes:
                yield self._chunk(parts, t_us, t0_us, t0_wall)
                parts, size = [], 0
        self.records = n
        if parts and t0_us is not None:
            yield self._chunk(parts, t_us, t0_us, t0_wall)
        self.info.messages = dict(self._packer.count)

    def _chunk(self, parts: list[bytes], t_us: int, t0_us: int,
               t0_wall: float) -> tuple[bytes, float]:
        if self.speed is not None:
            wait = t0_wall + (t_us - t0_us) * 1e-6 / self.speed - time.monotonic()
            if wait > 0:
                time.sleep(wait)
        if self.on_progress is not None and self.total_us:
            self.on_progress(min(t_us - t0_us, self.total_us), self.total_us)
        return b"".join(parts), (TLOG_EPOCH_US + t_us) * 1e-6

    @property
    def message_counts(self) -> dict[str, int]:
        return dict(self._packer.count)


@dataclass
class OpenedLog:
    """A log ready to replay: its byte source and what its reader found."""

    source: Source
    info: LogInfo


def open_log(path: Path | str, fmt: str | None = None, *, speed: float | None = None,
             column_map: Path | None = None, imu_rate_hz: float | None = None,
             on_progress: Callable[[int, int], None] | None = None) -> OpenedLog:
    """Open any flight log the monitor reads as a MAVLink byte source.

    Parameters
    ----------
    path : the log (.tlog, .bin, .log, .ulg, .csv)
    fmt : force a format (a key of :data:`FORMATS`); None detects it from the content
    speed : replay speed factor (None: as fast as possible)
    column_map : a TOML column map for a generic CSV (implies ``fmt="csvmap"``)
    imu_rate_hz : highest IMU rate given to the monitor (block averages above it)
    on_progress : progress callback ``(done, total)``

    Raises
    ------
    LogError : the file is missing, empty, of no known format or holds nothing usable
    """
    path = Path(path)
    if column_map is not None:
        fmt = "csvmap"
    detected = fmt is None
    fmt = fmt or detect_log_format(path)
    note = extension_note(path, fmt) if detected else None
    if fmt == "tlog":
        if path.stat().st_size == 0:
            raise log_error(path, "empty file (0 bytes)")
        src: Source = TlogSource(path, speed=speed, on_progress=on_progress)
        return OpenedLog(src, LogInfo(path=path, fmt="tlog", warnings=[note] if note else []))
    messages, info = read_messages(path, fmt, column_map=column_map, imu_rate_hz=imu_rate_hz)
    if note:
        info.warnings.insert(0, note)
    total = (info.t1_us - info.t0_us) if info.t0_us is not None and info.t1_us is not None \
        else None
    src = MessageSource(messages, info, speed=speed, on_progress=on_progress, total_us=total)
    return OpenedLog(src, info)


