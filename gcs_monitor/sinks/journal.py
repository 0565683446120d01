"""Append-only, crash-safe alarm journal: one JSON line per AlarmEvent.

Each line is written with a single ``write`` on a file opened in append mode and flushed to the
OS at once (optionally ``os.fsync``-ed), so a crash of the monitor loses no alarm that was
published: the OS owns the bytes after ``flush``. ``fsync=True`` also survives a power loss at the
price of a disk sync per alarm (alarms are rare, so the cost is acceptable where it matters).

**Opening repairs what a crash left.** A crash in the middle of a ``write`` leaves a torn last
line (no newline). On open, the journal is checked: a torn last line is moved aside to
``<journal>.torn`` (appended there, with the time and offset it was found at), the journal is
cut back to its last complete line (written to a temporary file and renamed over it, so the
repair is itself crash-safe), and :attr:`AlarmJournal.repair` reports what was done. Appends
therefore always start on a fresh line. A line that an older monitor appended onto a torn
fragment (``<fragment>{"schema_version": ...}``) is split the same way: the fragment goes aside,
the alarm stays.

**Stable ids, no duplicates.** Every alarm payload carries its ``alarm_id`` (vehicle, channel,
raise time; :func:`gcs_monitor.sinks.schema.alarm_id`). A transition already in the journal
(same id, state and vehicle time) is not written again, so a monitor that restarts and replays
what it had seen, or takes over alarms it had journaled, adds no duplicate; and
:meth:`AlarmJournal.active_alarms` gives the alarms the journal says are still active, which a
restarted monitor inherits (:class:`gcs_monitor.monitor.AlarmBook`).

The reader skips a torn last line (a crash in the middle of ``write``), never earlier lines.
"""

from __future__ import annotations

import json
import logging
import os
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gcs_monitor.core.types import ChannelId
from gcs_monitor.fdi.events import AlarmEvent, AlarmState
from gcs_monitor.fdi.records import StepOutput
from gcs_monitor.sinks.schema import alarm_from_dict, alarm_id, alarm_to_dict, dumps
from gcs_monitor.telemetry.frame import Frame

log = logging.getLogger(__name__)

PAYLOAD_START = b'{"schema_version"'


@dataclass
class JournalRepair:
    """What opening a journal found and did (all zero: nothing to repair)."""

    torn_bytes: int = 0  # a torn last line of this many bytes was moved aside
    split_lines: int = 0  # lines that began with a torn fragment: the fragment moved aside
    corrupt_lines: int = 0  # complete lines that are no JSON at all: moved aside
    moved_to: Path | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def repaired(self) -> bool:
        return bool(self.torn_bytes or self.split_lines or self.corrupt_lines)

    def describe(self) -> str:
        return "; ".join(self.notes)


def _key(d: dict[str, Any]) -> tuple[str, str, int]:
    return (str(d.get("alarm_id") or ""), str(d.get("state")), int(d.get("t_us", 0)))


def _repair(path: Path) -> tuple[JournalRepair, list[dict[str, Any]]]:
    """Check a journal file; move torn or corrupt bytes aside; return the valid payloads."""
    rep = JournalRepair()
    if not path.exists() or path.stat().st_size == 0:
        return rep, []
    data = path.read_bytes()
    parts = data.split(b"\n")
    tail = parts.pop()  # after the last newline: empty unless the last line is torn
    keep: list[bytes] = []
    payloads: list[dict[str, Any]] = []
    aside: list[tuple[int, bytes, str]] = []
    offset = 0
    for line in parts:
        at = offset
        offset += len(line) + 1
        if not line.strip():
            continue
        try:
            payloads.append(json.loads(line))
            keep.append(line)
            continue
        except ValueError:
            pass
        i = line.rfind(PAYLOAD_START)
        if i > 0:
            try:
                payloads.append(json.loads(line[i:]))
                keep.append(line[i:])
                aside.append((at, line[:i], "fragment before a line"))
                rep.split_lines += 1
                continue
            except ValueError:
                pass
        aside.append((at, line, "corrupt line"))
        rep.corrupt_lines += 1
    if tail.strip():
        try:  # a complete payload whose newline was lost: keep it
            payloads.append(json.loads(tail))
            keep.append(tail)
        except ValueError:
            aside.append((offset, tail, "torn last line"))
            rep.torn_bytes = len(tail)
    if not aside and not tail:
        return rep, payloads
    if aside:
        rep.moved_to = path.with_name(path.name + ".torn")
        stamp = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
        with rep.moved_to.open("ab") as f:
            for at, frag, what in aside:
                f.write(f"# {stamp} {path.name} offset {at}: {what}, {len(frag)} bytes\n"
                        .encode())
                f.write(frag + b"\n")
            f.flush()
            os.fsync(f.fileno())
    tmp = path.with_name(path.name + ".tmp")
    with tmp.open("wb") as f:
        f.write(b"".join(line + b"\n" for line in keep))
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    if rep.torn_bytes:
        rep.notes.append(f"torn last line ({rep.torn_bytes} bytes) moved to {rep.moved_to}")
    if rep.split_lines:
        rep.notes.append(f"{rep.split_lines} lines began with a torn fragment: fragments "
                         f"moved to {rep.moved_to}")
    if rep.corrupt_lines:
        rep.notes.append(f"{rep.corrupt_lines} corrupt lines moved to {rep.moved_to}")
    if not rep.notes:
        rep.notes.append("missing final newline added")
    return rep, payloads


class AlarmJournal:
    """JSON-lines journal of alarm transitions; implements the Sink protocol.

    Parameters
    ----------
    path : the journal file; created (with parents) if missing, checked, repaired and appended
        to otherwise (module docstring)
    fsync : also ``os.fsync`` after every alarm (survives power loss, costs a disk sync)
    monitor : the monitor's name written in every payload (a fleet worker's id)

    Attributes
    ----------
    repair : what opening found (:class:`JournalRepair`)
    n_written, n_duplicates, n_errors : lines written, transitions already in the journal (not
        written again), write failures
    """

    def __init__(self, path: Path | str, *, fsync: bool = False, monitor: str = "") -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fsync = fsync
        self.monitor = monitor
        self.repair, payloads = _repair(self.path)
        if self.repair.repaired:
            log.warning("alarm journal %s: %s", self.path, self.repair.describe())
        self._payloads = [d for d in payloads if d.get("type") == "alarm"]
        self._seen = {_key(d) for d in self._payloads}
        # Line buffering is not enough on its own (a partial line could be flushed), so every
        # record is one write() followed by an explicit flush().
        self._f = self.path.open("a", encoding="utf-8")
        self.n_written = 0
        self.n_duplicates = 0
        self.n_errors = 0

    def active_alarms(self) -> dict[int, list[AlarmEvent]]:
        """Per vehicle, the alarms the journal says are active (last transition not a clear),
        each as its last transition with its ``alarm_id``."""
        return active_from_payloads(self._payloads)

    def write(self, event: AlarmEvent, *, wall_time_s: float | None = None) -> None:
        """Append one alarm and flush it (and fsync it if configured); a transition already
        in the journal is not written again."""
        if self._f.closed:
            raise ValueError(f"journal {self.path} is closed")
        wall = time.time() if wall_time_s is None else wall_time_s
        d = alarm_to_dict(event, wall_time_s=wall, monitor=self.monitor)
        key = _key(d)
        if key[0] and key in self._seen:
            self.n_duplicates += 1
            return
        line = dumps(d) + "\n"
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
        if key[0]:
            self._seen.add(key)
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


def active_from_payloads(payloads: list[dict[str, Any]]) -> dict[int, list[AlarmEvent]]:
    """Per vehicle, the alarms still active after these transitions (in order), as their last
    transition with ``alarm_id`` (payloads without one get it from their raise)."""
    last: dict[tuple[int, ChannelId], AlarmEvent] = {}
    for d in payloads:
        try:
            ev = alarm_from_dict(d)
        except (ValueError, KeyError):
            continue
        k = (ev.vehicle, ev.channel)
        if ev.state is AlarmState.CLEARED:
            last.pop(k, None)
            continue
        if not ev.alarm_id:
            prev = last.get(k)
            aid = prev.alarm_id if prev is not None and ev.state is AlarmState.UPDATED \
                else alarm_id(ev.vehicle, ev.channel, ev.t_us)
            ev = AlarmEvent(**{f: getattr(ev, f) for f in AlarmEvent.__dataclass_fields__
                               if f != "alarm_id"}, alarm_id=aid)
        last[k] = ev
    out: dict[int, list[AlarmEvent]] = {}
    for (vehicle, _), ev in sorted(last.items(), key=lambda kv: (kv[0][0], kv[0][1])):
        out.setdefault(vehicle, []).append(ev)
    return out


def iter_journal(path: Path | str) -> Iterator[dict[str, Any]]:
    """Yield the alarm payloads (dicts, see :func:`schema.alarm_to_dict`) of a journal.

    A torn final line (no newline, invalid JSON) is skipped with a warning, and so is a torn
    fragment that an older monitor appended a line onto (the line is kept); invalid JSON on an
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
            j = line.rfind(PAYLOAD_START.decode())
            if j > 0:
                try:
                    d = json.loads(line[j:])
                except json.JSONDecodeError:
                    pass
                else:
                    log.warning("journal %s: line %d began with a torn fragment (skipped)",
                                path, i + 1)
                    yield d
                    continue
            raise ValueError(f"journal {path}: line {i + 1} is not valid JSON") from e


def read_journal(path: Path | str) -> list[AlarmEvent]:
    """All alarm events of a journal, in the order written."""
    return [alarm_from_dict(d) for d in iter_journal(path)]
