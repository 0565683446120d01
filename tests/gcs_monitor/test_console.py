"""Console lines for an operator: display units, channel names, the per-channel summary."""

from __future__ import annotations

import math

from gcs_monitor.console import display_value, format_event, summarise_alarms
from gcs_monitor.core.types import ChannelId
from gcs_monitor.fdi.events import SET_INSTANCE, AlarmEvent, AlarmKind, AlarmState, FaultType


def _ev(t_s: float, ch: ChannelId, state: AlarmState, magnitude: float,
        fault: FaultType = FaultType.BIAS) -> AlarmEvent:
    return AlarmEvent(round(t_s * 1e6), ch, state, AlarmKind.SENSOR_FAULT, fault, magnitude,
                      0.1, 0.05, "voting", "msg")


def test_display_units() -> None:
    assert display_value("aoa", math.pi / 180) == (1.0, "deg")
    assert display_value("cas", 1852 / 3600) == (1.0, "kt")
    assert display_value("gyro", math.pi) == (180.0, "deg/s")
    assert display_value("acc", 0.5) == (0.5, "m/s²")
    assert display_value("other", 2.0) == (2.0, "")


def test_format_event_line() -> None:
    line = format_event(_ev(12.5, ChannelId("aoa", 2), AlarmState.RAISED, math.radians(2.0)))
    assert line == ("t=   12.50s  RAISED   aoa2         sensor_fault   bias        +2 deg"
                    "         (voting) msg")
    line = format_event(_ev(1.0, ChannelId("acc", 0, "x"), AlarmState.CLEARED, math.nan))
    assert " acc0.x " in line and " CLEARED " in line and " -  " in line
    assert " aoa[set] " in format_event(_ev(1.0, ChannelId("aoa", SET_INSTANCE),
                                            AlarmState.RAISED, 0.0))


def test_summary_first_raise_latest_state() -> None:
    aoa, cas = ChannelId("aoa", 1), ChannelId("cas", 0)
    rows = summarise_alarms([
        _ev(20.0, cas, AlarmState.RAISED, 1852 / 3600 * 3.0, FaultType.DRIFT),
        _ev(10.0, aoa, AlarmState.RAISED, math.radians(1.0)),
        _ev(30.0, aoa, AlarmState.CLEARED, math.radians(0.5)),
    ])
    assert len(rows) == 2
    assert rows[0].startswith("aoa1") and "raised t=  10.00s" in rows[0]
    assert rows[0].endswith("cleared") and "+0.5 deg" in rows[0]
    assert rows[1].startswith("cas0") and "drift" in rows[1] and rows[1].endswith("active")
