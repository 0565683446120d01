"""Scoring of the robustness experiments against the simulator's truth: a sensor fault and an
actuator fault are found by an alarm on their own channel; anything else is a false alarm."""

from __future__ import annotations

import math

from gcs_monitor.core.types import ChannelId
from gcs_monitor.evaluation.papers.robustness import score
from gcs_monitor.evaluation.scenarios import preset
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState, FaultType


def _raise(t_s: float, ch: ChannelId, kind: AlarmKind) -> AlarmEvent:
    return AlarmEvent(round(t_s * 1e6), ch, AlarmState.RAISED, kind, FaultType.UNKNOWN,
                      math.nan, math.nan, math.nan, "test")


def test_actuator_faults_are_truth_and_other_surfaces_are_false_alarms():
    sc = preset("uav_rudder_stuck")  # rudder (actuator 2) jammed at 30 s
    events = [
        _raise(30.4, ChannelId("actuator", 2, "rudder"), AlarmKind.ACTUATOR_FAULT),
        _raise(31.0, ChannelId("surface", 2, "output"), AlarmKind.ACTUATOR_FAULT),
        _raise(31.0, ChannelId("surface", 0, "output"), AlarmKind.ACTUATOR_FAULT),
        _raise(40.0, ChannelId("monitor", 0, "imu"), AlarmKind.MONITOR_DEGRADED),
    ]
    out = score(sc.name, sc, events, {})
    assert (out.faults, out.detected) == (1, 1)
    assert math.isclose(out.delays_s[0], 0.4, abs_tol=1e-9)
    assert out.false_alarms == ["surface0.output"] and out.air_false == 0
    assert out.degraded == {"imu": 1}


def test_an_alarm_before_the_onset_is_false_and_finds_nothing():
    sc = preset("uav_rudder_stuck")
    out = score(sc.name, sc, [_raise(10.0, ChannelId("aoa", 1), AlarmKind.SENSOR_FAULT)], {})
    assert (out.faults, out.detected) == (1, 0)
    assert out.false_alarms == ["aoa1"] and out.air_false == 1
