"""What every log reader shares: the error it raises, what it reports, the message stream and
the block averaging of fast streams (:mod:`gcs_monitor.convert.logs` dispatches to the readers,
which import this module, not the dispatcher)."""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gcs_monitor.convert.formats import ConvertError

KNOWN_FORMATS = (
    "a MAVLink telemetry log (.tlog), an ArduPilot DataFlash log (.bin, or text .log), "
    "a PX4 ULog (.ulg), or a CSV (Zipline, OnSpeed, ALFA, or any CSV with --map COLUMNS.toml)")

class LogError(ConvertError):
    """A file cannot be used: the message is one line for the operator.

    ``partial`` is True when part of the file was read (a cut file): the caller exits non-zero
    but the part read was used.
    """

    def __init__(self, message: str, *, partial: bool = False) -> None:
        super().__init__(message)
        self.partial = partial


def log_error(path: Path, what: str) -> LogError:
    """``FILE: what; expected KNOWN_FORMATS`` as one line."""
    return LogError(f"{path}: {what}; expected {KNOWN_FORMATS}")


@dataclass
class LogInfo:
    """What a log reader found: the format, the vehicle, what it read and what it could not.

    Attributes
    ----------
    fmt : format name (a key of :data:`FORMATS`)
    vehicle : what the log says the vehicle is ("ArduCopter V3.2", "PX4 AUAV_X21", ...)
    records : log records read per log message / topic name (what the log holds)
    messages : MAVLink messages produced per type (what the monitor is given)
    duration_s : vehicle time covered by the messages produced
    warnings : operator lines about the file (truncation, dropped records, fallbacks)
    """

    path: Path
    fmt: str
    vehicle: str = ""
    records: dict[str, int] = field(default_factory=dict)
    messages: dict[str, int] = field(default_factory=dict)
    t0_us: int | None = None
    t1_us: int | None = None
    warnings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def duration_s(self) -> float:
        if self.t0_us is None or self.t1_us is None:
            return 0.0
        return (self.t1_us - self.t0_us) * 1e-6


# A reader yields (vehicle time µs, MAVLink message object) in time order and fills its info.
Messages = Iterator[tuple[int, Any]]


def block_means(t_us: Any, values: Any, rate_hz: float | None) -> tuple[Any, Any]:
    """Average consecutive samples in blocks so the rate stays at or below ``rate_hz``.

    ``t_us`` (n,) int, ``values`` (n, k); returns the block-end times and block means. Blocks
    hold ``ceil(measured rate / rate_hz)`` samples; nothing changes at or below the rate.
    """
    n = len(t_us)
    if rate_hz is None or n < 3:
        return t_us, values
    dt_s = float(np.median(np.diff(t_us))) * 1e-6
    if not dt_s > 0:
        return t_us, values
    k = int(math.ceil((1.0 / dt_s) / rate_hz - 1e-9))
    if k <= 1:
        return t_us, values
    m = n // k
    v = values[:m * k].reshape(m, k, -1).mean(axis=1)
    return t_us[k - 1:m * k:k], v
