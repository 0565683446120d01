"""A journal a crash cannot break: a torn last line is moved aside on open and reported, appends
start on a fresh line, a restarted monitor raises no duplicate of an alarm already journaled."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gcs_monitor.fdi.events import AlarmState
from gcs_monitor.monitor import Monitor
from gcs_monitor.sinks.journal import AlarmJournal, iter_journal, read_journal
from tests.helpers.fleet import template

S = 1_000_000
FAULT_AT_S = 3.0


@pytest.fixture(scope="module")
def flight() -> tuple[tuple[int, bytes], ...]:
    return template(14.0, 1, FAULT_AT_S)  # vehicle 1, AoA vane 1 biased 3 deg from 3 s


def _run(packets, journal: AlarmJournal, *, inherit=None) -> Monitor:  # type: ignore[no-untyped-def]
    m = Monitor(sinks_for=lambda sysid: [journal], inherit=inherit)
    data = b"".join(p for _, p in packets)
    for i in range(0, len(data), 8192):
        m.feed(data[i:i + 8192])
    m.finish()
    return m


def test_torn_last_line_is_moved_aside_and_the_restart_raises_nothing_twice(tmp_path, flight):
    path = tmp_path / "alarms.jsonl"
    first = [p for p in flight if p[0] < 8 * S]
    rest = [p for p in flight if p[0] >= 8 * S]
    with AlarmJournal(path) as j:
        m1 = _run(first, j)
    raised = [e for e in m1.events if e.state is AlarmState.RAISED]
    assert [str(e.channel) for e in raised] == ["aoa1"]
    aid = raised[0].alarm_id
    assert aid == f"1/aoa1/{raised[0].t_us}"
    lines_before = path.read_bytes().count(b"\n")
    assert lines_before == len(m1.events) >= 1
    # the crash: the monitor died in the middle of writing its next line
    good = path.read_bytes()
    fragment = good.splitlines()[-1][:57]
    path.write_bytes(good + fragment)

    j2 = AlarmJournal(path)  # the restart
    assert j2.repair.torn_bytes == 57 and j2.repair.split_lines == 0
    assert j2.repair.corrupt_lines == 0
    assert j2.repair.moved_to == tmp_path / "alarms.jsonl.torn"
    assert f"torn last line (57 bytes) moved to {j2.repair.moved_to}" in j2.repair.describe()
    aside = j2.repair.moved_to.read_bytes().splitlines()
    assert aside[0].startswith(b"# ") and b"offset %d: torn last line, 57 bytes" % len(good) \
        in aside[0]
    assert aside[1] == fragment
    assert path.read_bytes() == good  # cut back to the last complete line
    active = j2.active_alarms()
    assert [e.alarm_id for e in active[1]] == [aid]

    m2 = _run(rest, j2, inherit=active)  # the flight goes on; the bias is still there
    j2.close()
    assert not any(e.state is AlarmState.RAISED for e in m2.events)  # no duplicate raise
    assert {e.alarm_id for e in m2.events if str(e.channel) == "aoa1"} == {aid}
    h = m2.vehicle_health(1)["handover"]
    assert h["reason"] == "restart" and h["inherited"] == 1 and h["confirmed"] == 1
    # exact line count: the first run's lines, then one line per published transition
    lines = path.read_bytes().splitlines()
    assert len(lines) == lines_before + len(m2.events)
    events = read_journal(path)  # the whole file reads again
    assert sum(e.state is AlarmState.RAISED for e in events) == 1


def test_replaying_the_same_bytes_into_the_journal_writes_nothing_twice(tmp_path, flight):
    path = tmp_path / "alarms.jsonl"
    with AlarmJournal(path) as j:
        m = _run(flight, j)
    n = len(path.read_bytes().splitlines())
    assert n == len(m.events) >= 1
    with AlarmJournal(path) as j:
        _run(flight, j)  # same bytes: same alarm ids, same transitions
        assert j.n_written == 0 and j.n_duplicates == n
    assert len(path.read_bytes().splitlines()) == n


def test_a_line_appended_onto_a_torn_fragment_by_an_older_monitor_is_split(tmp_path: Path):
    path = tmp_path / "alarms.jsonl"
    line = json.dumps({"schema_version": 2, "type": "alarm", "alarm_id": "1/aoa1/5",
                       "monitor": "", "vehicle": 1,
                       "channel": {"kind": "aoa", "instance": 1, "axis": ""},
                       "channel_name": "aoa1", "state": "raised", "kind": "sensor_fault",
                       "fault_type": "bias", "confidence": 0.9, "magnitude": 0.05, "unit": "rad",
                       "residual_rms": 0.04, "threshold": 0.02, "t_us": 5, "vehicle_time_s": 5e-6,
                       "wall_time_s": 0.0, "wall_time": "x", "estimator": "voting",
                       "message": ""})
    path.write_text(line + "\n" + '{"schema_version": 2, "ty' + line + "\n")
    assert len(list(iter_journal(path))) == 2  # the reader copes (skips the fragment)
    j = AlarmJournal(path)
    j.close()
    assert j.repair.split_lines == 1 and j.repair.torn_bytes == 0
    assert path.read_text() == line + "\n" + line + "\n"
    assert (tmp_path / "alarms.jsonl.torn").read_text().splitlines()[1] == \
        '{"schema_version": 2, "ty'
