"""Append-only, crash-safe alarm journal: one JSON line per AlarmEvent.

Each line is written with a single ``write`` on a file opened in append mode and flushed to the
OS at once (optionally ``os.fsync``-ed), so a crash of the monitor loses no alarm that was
published: the OS owns the bytes after ``flush``. ``fsync=True`` also survives a power loss at the
price of a disk sync per alarm (alarms are rare, so the cost is acceptable where it matters).

The reader skips a torn last line (a crash in the middle of ``write``), never earlier lines.
"""

from __future__ import annotations

import json
import logging
import os
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from gcs_monitor.fdi.events import AlarmEvent
from gcs_monitor.fdi.records import StepOutput
from gcs_monitor.sinks.schema import alarm_from_dict, alarm_to_dict, dumps
from gcs_monitor.telemetry.frame import Frame

log = logging.getLogger(__name__)


class AlarmJournal:
    """JSON-lines journal of alarm transitions; implements the Sink protocol.

    Parameters
    ----------
    path : the journal file; created (with parents) if missing, appended to otherwise
    fsync : also ``os.fsync`` after every alarm (survives power loss, costs a disk sync)
    """

    def __init__(self, path: Path | str, *, fsync: bool = False) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fsync = fsync
        # Line buffering is not enough on its own (a partial line could be flushed), so every
        # record is one write() followed by an explicit flush().
        self._f = self.path.open("a", encoding="utf-8")
        self.n_written = 0
        self.n_errors = 0

    def write(self, event: AlarmEvent, *, wall_time_s: float | None = None) -> None:
        """Append one alarm and flush it (and fsync it if configured)."""
        if self._f.closed:
            raise ValueError(f"journal {self.path} is closed")
        wall = time.time() if wall_time_s is None else wall_time_s
        line = dumps(alarm_to_dict(event, wall_time_s=wall)) + "\n"
        try:
            self._f.write(line)
            self._f.flush()
            if self._fsync:
                os.fsync(self._f.fileno())
        except OSError:
            # A full disk must not stop the monitor; the Zenoh/Rerun sinks still carry the alarm.
            self.n_errors += 1
            log.exception("alarm journal %s: write failed", self.path)
            return
        self.n_written += 1

    def publish(self, frame: Frame, out: StepOutput) -> None:
        events = out.events
        if not events:
            return
        wall = time.time()
        for ev in events:
            self.write(ev, wall_time_s=wall)

    def update_health(self, health: dict[str, Any]) -> None:
        """The journal records alarm transitions only."""

    def close(self) -> None:
        if not self._f.closed:
            self._f.close()

    def __enter__(self) -> AlarmJournal:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def iter_journal(path: Path | str) -> Iterator[dict[str, Any]]:
    """Yield the alarm payloads (dicts, see :func:`schema.alarm_to_dict`) of a journal.

    A torn final line (no newline, invalid JSON) is skipped with a warning; invalid JSON on an
    earlier line raises ValueError, because it means corruption, not a crash.
    """
    with Path(path).open("r", encoding="utf-8") as f:
        lines = f.readlines()
    for i, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            yield json.loads(line)
        except json.JSONDecodeError as e:
            if i == len(lines) - 1 and not line.endswith("\n"):
                log.warning("journal %s: torn last line skipped", path)
                return
            raise ValueError(f"journal {path}: line {i + 1} is not valid JSON") from e


def read_journal(path: Path | str) -> list[AlarmEvent]:
    """All alarm events of a journal, in the order written."""
    return [alarm_from_dict(d) for d in iter_journal(path)]
