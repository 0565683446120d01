"""Console lines for an operator: display units, channel names, the per-channel summary."""

from __future__ import annotations

import math

from gcs_monitor.console import display_value, format_event, summarise_alarms
from gcs_monitor.core.types import ChannelId
from gcs_monitor.fdi.events import SET_INSTANCE, AlarmEvent, AlarmKind, AlarmState, FaultType


def _ev(t_s: float, ch: ChannelId, state: AlarmState, magnitude: float,
        fault: FaultType = FaultType.BIAS, kind: AlarmKind = AlarmKind.SENSOR_FAULT,
        confidence: float = 0.9) -> AlarmEvent:
    return AlarmEvent(round(t_s * 1e6), ch, state, kind, fault, magnitude,
                      0.1, 0.05, "voting", "msg", confidence=confidence)


def test_display_units() -> None:
    assert display_value("aoa", math.pi / 180) == (1.0, "deg")
    assert display_value("cas", 1852 / 3600) == (1.0, "kt")
    assert display_value("gyro", math.pi) == (180.0, "deg/s")
    assert display_value("acc", 0.5) == (0.5, "m/s²")
    assert display_value("other", 2.0) == (2.0, "")


def test_format_event_line() -> None:
    line = format_event(_ev(12.5, ChannelId("aoa", 2), AlarmState.RAISED, math.radians(2.0)))
    assert line == ("v1   t=   12.50s  RAISED   aoa2         sensor_fault   bias (0.90)        "
                    "+2 deg         (voting) msg")
    line = format_event(_ev(1.0, ChannelId("acc", 0, "x"), AlarmState.CLEARED, math.nan))
    assert " acc0.x " in line and " CLEARED " in line and " -  " in line
    assert " aoa[set] " in format_event(_ev(1.0, ChannelId("aoa", SET_INSTANCE),
                                            AlarmState.RAISED, 0.0))


def test_summary_first_raise_and_final_state() -> None:
    aoa, cas, aoa_set = ChannelId("aoa", 1), ChannelId("cas", 0), ChannelId("aoa", SET_INSTANCE)
    rows = summarise_alarms([
        _ev(10.0, aoa, AlarmState.RAISED, math.radians(1.0)),
        _ev(20.0, cas, AlarmState.RAISED, 1852 / 3600 * 3.0, FaultType.DRIFT),
        _ev(25.0, aoa_set, AlarmState.RAISED, math.nan, FaultType.UNKNOWN, AlarmKind.SET_LOST,
            0.0),
        _ev(30.0, aoa, AlarmState.CLEARED, math.radians(0.5)),
        _ev(35.0, cas, AlarmState.UPDATED, 1852 / 3600 * 9.0, FaultType.RUNAWAY),
    ])
    assert len(rows) == 3
    assert "nan" not in "".join(rows).lower()
    first, final = rows[0].split(" | ")
    assert first.startswith("v1   aoa1 ") and "first raise t=  10.00s bias (0.90)" in first
    assert "+1 deg" in first
    assert final == "final (t=  30.00s): cleared bias (0.90)        +0.5 deg"
    first, final = rows[1].split(" | ")
    assert "drift (0.90)" in first and "+3 kt" in first
    assert final.startswith("final (t=  35.00s): active  runaway (0.90)") and "+9 kt" in final
    # a lost set: its own name, no magnitude
    assert rows[2].startswith("v1   aoa[set] ") and "aoa-1" not in rows[2]
    first, final = rows[2].split(" | ")
    assert first.rstrip().endswith("unknown            -") and final.rstrip().endswith("-")


def test_summary_counts_raises_again() -> None:
    aoa = ChannelId("aoa", 1)
    rows = summarise_alarms([_ev(1.0, aoa, AlarmState.RAISED, 0.01),
                             _ev(2.0, aoa, AlarmState.CLEARED, 0.01),
                             _ev(3.0, aoa, AlarmState.RAISED, 0.02)])
    assert rows[0].endswith("raised 2 times") and "first raise t=   1.00s" in rows[0]


def test_every_line_names_its_vehicle_and_vehicles_are_not_merged() -> None:
    aoa = ChannelId("aoa", 1)
    e1 = _ev(10.0, aoa, AlarmState.RAISED, 0.01)
    e2 = AlarmEvent(round(12e6), aoa, AlarmState.RAISED, AlarmKind.SENSOR_FAULT, FaultType.BIAS,
                    0.02, 0.1, 0.05, "voting", "msg", vehicle=2, confidence=0.9)
    assert format_event(e1).startswith("v1 ") and format_event(e2).startswith("v2 ")
    rows = summarise_alarms([e2, e1, _ev(20.0, aoa, AlarmState.CLEARED, 0.0)])
    assert [r.split()[0] for r in rows] == ["v1", "v2"]  # one row per vehicle's aoa1
    assert "cleared" in rows[0] and "active" in rows[1]
