"""Alarm journal: one line per alarm, flushed at once, survives a killed process."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from gcs_monitor.core.types import ChannelId
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState, FaultType
from gcs_monitor.sinks.journal import AlarmJournal, iter_journal, read_journal


def _ev(i: int, state: AlarmState = AlarmState.RAISED) -> AlarmEvent:
    return AlarmEvent(
        i * 10_000,
        ChannelId("cas", i % 3),
        state,
        AlarmKind.SENSOR_FAULT,
        FaultType.DRIFT,
        1.5 * i,
        0.3,
        0.2,
        "voting",
        f"alarm {i}",
    )


def test_write_read_in_order(tmp_path: Path) -> None:
    p = tmp_path / "sub" / "alarms.jsonl"
    with AlarmJournal(p, fsync=True) as j:
        for i in range(5):
            j.write(_ev(i), wall_time_s=100.0 + i)
    with AlarmJournal(p) as j:  # append, not truncate
        j.write(_ev(5, AlarmState.CLEARED))
    assert read_journal(p) == [_ev(i) for i in range(5)] + [_ev(5, AlarmState.CLEARED)]
    assert [d["wall_time_s"] for d in iter_journal(p)][:5] == [100.0, 101.0, 102.0, 103.0, 104.0]
    assert len(p.read_text().splitlines()) == 6


def test_alarm_on_disk_before_close(tmp_path: Path) -> None:
    p = tmp_path / "a.jsonl"
    j = AlarmJournal(p)
    j.write(_ev(1))
    # Another reader sees it while the journal is still open: it was flushed.
    assert read_journal(p) == [_ev(1)]
    j.close()


def test_crash_without_close_loses_nothing(tmp_path: Path) -> None:
    """A child writes alarms and is SIGKILLed without close(); every alarm is on disk."""
    p = tmp_path / "crash.jsonl"
    code = textwrap.dedent(f"""
        import sys, time
        from gcs_monitor.core.types import ChannelId
        from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState, FaultType
        from gcs_monitor.sinks.journal import AlarmJournal
        j = AlarmJournal({str(p)!r})
        for i in range(20):
            j.write(AlarmEvent(i * 10_000, ChannelId("cas", i % 3), AlarmState.RAISED,
                    AlarmKind.SENSOR_FAULT, FaultType.DRIFT, 1.5 * i, 0.3, 0.2, "voting",
                    f"alarm {{i}}"))
        print("written", flush=True)
        time.sleep(60)
    """)
    child = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout is not None
        assert child.stdout.readline().strip() == "written"
        os.kill(child.pid, signal.SIGKILL)
    finally:
        child.wait(timeout=10)
    assert child.returncode == -signal.SIGKILL
    assert read_journal(p) == [_ev(i) for i in range(20)]


def test_torn_last_line_skipped_but_corruption_raises(tmp_path: Path) -> None:
    p = tmp_path / "torn.jsonl"
    with AlarmJournal(p) as j:
        j.write(_ev(1))
        j.write(_ev(2))
    with p.open("a") as f:
        f.write('{"schema_version": 1, "type": "ala')  # crash mid-write
    assert read_journal(p) == [_ev(1), _ev(2)]
    lines = p.read_text().splitlines(keepends=True)
    p.write_text(lines[0] + "garbage\n" + lines[1])
    with pytest.raises(ValueError, match="line 2"):
        read_journal(p)


def test_write_after_close_raises(tmp_path: Path) -> None:
    j = AlarmJournal(tmp_path / "c.jsonl")
    j.close()
    j.close()  # idempotent
    with pytest.raises(ValueError, match="closed"):
        j.write(_ev(1))
