"""Scoring of the Chen2020 experiments: the observer's detection is its first confirmation on the
channel, also when the Monitor publishes it as an update of another estimator's alarm."""

from __future__ import annotations

from gcs_monitor.core.types import ChannelId
from gcs_monitor.evaluation.papers.chen2020 import EST, observer_alarms
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState, FaultType

R = ChannelId("gyro", 0, "r")


def _ev(t_s: float, estimator: str, state: AlarmState, channel: ChannelId = R,
        kind: AlarmKind = AlarmKind.SENSOR_FAULT) -> AlarmEvent:
    return AlarmEvent(round(t_s * 1e6), channel, state, kind, FaultType.DRIFT, 0.0, 0.0, 0.0,
                      estimator)


def test_the_observers_confirmation_behind_an_imu_ts_alarm_counts() -> None:
    # the transport's fast drift from 30 s (measured): imu_ts raises gyro0.r at 31.68 s, the
    # observer confirms at 32.89 s and the Monitor publishes that as an update of the same alarm
    events = [_ev(31.68, "imu_ts", AlarmState.RAISED),
              _ev(32.0, EST, AlarmState.RAISED, ChannelId("gyro", 0, "p")),
              _ev(32.5, EST, AlarmState.RAISED, R, AlarmKind.MONITOR_DEGRADED),
              _ev(32.89, EST, AlarmState.UPDATED),
              _ev(33.18, "imu_ts", AlarmState.UPDATED),
              _ev(40.0, EST, AlarmState.CLEARED)]
    found = observer_alarms(events, R)
    assert [e.t_us for e in found] == [32_890_000]
    assert observer_alarms(events[:1], R) == []  # imu_ts alone is not the observer's detection
