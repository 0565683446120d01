"""Every flight log the monitor reads, as one MAVLink byte source (``open_log``).

A log reader turns its log into the MAVLink messages of the telemetry contract
(docs/telemetry.md): ArduPilot DataFlash (``dataflash.py``), PX4 ULog (``ulog.py``), the CSV
layouts (``formats.py``) and any CSV described by a column map (``csvmap.py``). Units and
frames are converted at that boundary; the messages are packed with the converter's encoder
(``encode.py``) and leave as ``(bytes, wall time)`` chunks, exactly like a ``.tlog``
(:class:`gcs_monitor.link.transports.TlogSource`), so every family sees a log as it would see
live telemetry through the normal decode path.

Formats are recognised by their content (``detect_log_format``), not only by the extension.
Anything that cannot be read raises :class:`LogError` with one line that names the file,
says what is wrong and lists the formats that are read (:data:`KNOWN_FORMATS`). A file that is
read only in part (cut mid-record) is replayed up to the cut and says so in
``LogInfo.warnings``.

``gcs_monitor.link.logs.open_log`` is the function other commands (``replay``, ``report``,
``calibrate``) call: it gives any of these logs as a byte source.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from gcs_monitor.convert.csvmap import csvmap_messages, flight_messages
from gcs_monitor.convert.dataflash import dataflash_messages
from gcs_monitor.convert.formats import READERS, csv_layout
from gcs_monitor.convert.logbase import LogError, LogInfo, Messages, log_error
from gcs_monitor.convert.ulog import ulog_messages

MAV1_MAGIC = 0xFE
MAV2_MAGIC = 0xFD

# --format names: what each reads
FORMATS = {
    "tlog": "MAVLink telemetry log (8-byte µs timestamp + packet)",
    "dataflash": "ArduPilot DataFlash binary log (.bin)",
    "dataflash-text": "ArduPilot DataFlash text log (.log)",
    "ulog": "PX4 ULog (.ulg)",
    "zipline": "Zipline launch CSV",
    "onspeed": "OnSpeed / VN-300 SD-card CSV (with header)",
    "alfa": "ALFA (CMU AirLab) derived CSV",
    "csvmap": "any CSV described by a TOML column map (--map)",
}

EXTENSIONS = {"tlog": (".tlog",), "dataflash": (".bin",), "dataflash-text": (".log",),
              "ulog": (".ulg",), "zipline": (".csv",), "onspeed": (".csv",), "alfa": (".csv",),
              "csvmap": (".csv", ".txt", ".dat")}
ULOG_MAGIC = b"ULog\x01\x12\x35"
DATAFLASH_HEAD = b"\xa3\x95"
SNIFF_BYTES = 4096
TLOG_CHECK_RECORDS = 8
TLOG_MAX_SKEW_US = 366 * 86_400 * 1_000_000  # consecutive tlog stamps never a year apart


def extension_note(path: Path, fmt: str) -> str | None:
    """A warning when the file's extension names another format than its content."""
    suffix = Path(path).suffix.lower()
    expected = EXTENSIONS.get(fmt, ())
    if not suffix or suffix in expected:
        return None
    return (f"named {suffix} but the content is a {FORMATS.get(fmt, fmt)}: read as that "
            "(--format forces a format)")


# -- format detection ----------------------------------------------------------------------------
def _looks_like_tlog(head: bytes, size: int) -> bool:
    """Records line up: 8-byte big-endian µs stamp, MAVLink magic, length-consistent walk."""
    p = 0
    last_t: int | None = None
    n = 0
    while p + 10 <= len(head) and n < TLOG_CHECK_RECORDS:
        magic = head[p + 8]
        if magic == MAV2_MAGIC:
            length = head[p + 9] + 12 + (13 if p + 10 < len(head) and head[p + 10] & 1 else 0)
        elif magic == MAV1_MAGIC:
            length = head[p + 9] + 8
        else:
            return False
        t = int.from_bytes(head[p:p + 8], "big")
        if last_t is not None and abs(t - last_t) > TLOG_MAX_SKEW_US:
            return False
        last_t = t
        p += 8 + length
        n += 1
    return n >= min(TLOG_CHECK_RECORDS, 2) or (n == 1 and p >= size)


def _is_text(head: bytes) -> bool:
    if not head:
        return False
    try:
        head.decode("utf-8")
    except UnicodeDecodeError:
        # a cut multi-byte character at the very end of the sniffed block is still text
        try:
            head[:-3].decode("utf-8")
        except UnicodeDecodeError:
            return False
    return b"\x00" not in head


def detect_log_format(path: Path) -> str:
    """The format of a flight log from its content (a key of :data:`FORMATS`).

    Raises :class:`LogError` for a missing, empty or unrecognised file.
    """
    path = Path(path)
    if not path.exists():
        raise LogError(f"{path}: no such file")
    if path.is_dir():
        raise LogError(f"{path}: is a folder, not a flight log")
    size = path.stat().st_size
    if size == 0:
        raise log_error(path, "empty file (0 bytes)")
    with open(path, "rb") as fh:
        head = fh.read(SNIFF_BYTES)
    if head.startswith(ULOG_MAGIC):
        return "ulog"
    if head.startswith(DATAFLASH_HEAD):
        return "dataflash"
    if head[:1] in (bytes([MAV1_MAGIC]), bytes([MAV2_MAGIC])) and not _looks_like_tlog(head,
                                                                                       size):
        raise log_error(path, "raw MAVLink bytes without tlog timestamps (record it with "
                              "`gcs-monitor live --record-tlog`)")
    if len(head) >= 10 and _looks_like_tlog(head, size):
        return "tlog"
    if _is_text(head):
        text = head.decode("utf-8", errors="replace")
        first = text.lstrip().split("\n", 1)[0]
        if first.startswith("FMT,"):
            return "dataflash-text"
        layout = csv_layout(first)
        if layout is not None:
            return layout
        sample = " ".join(text.split("\n")[:2])[:120]
        kind = "a CSV with no known header" if "," in first else "a text file"
        raise log_error(path, f"{kind} (starts {sample!r}; for a CSV give --map COLUMNS.toml)")
    if path.suffix.lower() in (".bin", ".ulg", ".tlog", ".log"):
        raise log_error(path, f"not a {path.suffix} file: its first bytes "
                              f"{head[:8].hex(' ')} match no known log")
    raise log_error(path, f"unrecognised binary content (first bytes {head[:8].hex(' ')})")


def read_messages(path: Path, fmt: str | None = None, *, column_map: Path | None = None,
                  imu_rate_hz: float | None = None) -> tuple[Messages, LogInfo]:
    """The contract messages of a non-tlog log and its info (readers' common entry).

    ``imu_rate_hz`` caps the IMU rate: higher-rate IMU samples are averaged in blocks (the
    mean specific force and rate over the block, as an autopilot's downsampled stream);
    None keeps the reader's default (:data:`gcs_monitor.convert.dataflash.DEFAULT_IMU_RATE_HZ`).
    """
    path = Path(path)
    if column_map is not None:
        fmt = "csvmap"
    fmt = fmt or detect_log_format(path)
    if fmt not in FORMATS:
        raise LogError(f"unknown format {fmt!r}; expected one of {', '.join(FORMATS)}")
    if not path.exists():
        raise LogError(f"{path}: no such file")
    if path.stat().st_size == 0:
        raise log_error(path, "empty file (0 bytes)")
    kw: dict[str, Any] = {} if imu_rate_hz is None else {"imu_rate_hz": imu_rate_hz}
    if fmt in ("dataflash", "dataflash-text"):
        return dataflash_messages(path, text=fmt == "dataflash-text", **kw)
    if fmt == "ulog":
        return ulog_messages(path, **kw)
    if fmt == "csvmap":
        if column_map is None:
            raise LogError(f"{path}: --format csvmap needs --map COLUMNS.toml")
        return csvmap_messages(path, column_map)
    if fmt in ("zipline", "onspeed", "alfa"):
        if fmt == "zipline":  # as recorded: the monitor meets the reference's reset itself
            return flight_messages(READERS[fmt](path, mask_reset=False), path)  # type: ignore[call-arg]
        return flight_messages(READERS[fmt](path), path)
    raise LogError(f"{path}: a {fmt} needs no conversion")
