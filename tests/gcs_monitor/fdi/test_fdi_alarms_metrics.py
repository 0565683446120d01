"""Alarm state machine, link alarms, Wan2018 Table IV metrics, baseline interface."""

from __future__ import annotations

import math

import pytest

from gcs_monitor.core.types import ChannelId
from gcs_monitor.fdi.alarms import AlarmParams, AlarmStateMachine, ChannelAlarm, LinkAlarmMonitor
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState, FaultType
from gcs_monitor.fdi.metrics import evaluate_run, format_table, metrics_table

CH = ChannelId("aoa", 1)


def test_alarm_transitions_and_rate_limit() -> None:
    sm = AlarmStateMachine(CH, AlarmKind.SENSOR_FAULT, "voting",
                           params=AlarmParams(update_rel_change=0.25, min_update_interval_us=100))
    assert sm.step(0, False) == []
    ev = sm.step(10, True, fault_type=FaultType.BIAS, magnitude=1.0)
    assert [e.state for e in ev] == [AlarmState.RAISED] and sm.state is ChannelAlarm.ACTIVE
    assert sm.step(20, True, fault_type=FaultType.BIAS, magnitude=2.0) == []  # rate-limited
    assert sm.step(200, True, fault_type=FaultType.BIAS, magnitude=1.2) == []  # < 25 %
    ev = sm.step(300, True, fault_type=FaultType.BIAS, magnitude=1.3)  # +30 % vs 1.0
    assert ev[0].state is AlarmState.UPDATED and ev[0].magnitude == 1.3
    ev = sm.step(500, True, fault_type=FaultType.DRIFT, magnitude=1.3)  # type change
    assert ev[0].state is AlarmState.UPDATED and ev[0].fault_type is FaultType.DRIFT
    ev = sm.step(510, False)
    assert ev[0].state is AlarmState.CLEARED and sm.state is ChannelAlarm.NORMAL


def test_link_alarms_never_sensor_faults() -> None:
    mon = LinkAlarmMonitor(vehicle=3)
    ev = mon.step(0, {"loss_pct": 1.0, "crc_errors": 0, "stream_age_s": 0.1, "boot_count": 0})
    assert ev == []
    ev = mon.step(1_000_000, {"loss_pct": 8.0, "crc_errors": 2, "stream_age_s": 2.0,
                              "boot_count": 1})
    assert {e.channel.axis for e in ev} == {"loss", "crc", "stale", "reboot"}
    assert all(e.kind is AlarmKind.LINK and e.fault_type is FaultType.LINK for e in ev)
    assert all(e.channel.kind == "link" and e.vehicle == 3 for e in ev)
    # loss hysteresis: 3 % is below the raise level but above the clear level
    ev = mon.step(2_000_000, {"loss_pct": 3.0})
    assert [e.state for e in ev] == [AlarmState.UPDATED]  # still active, magnitude 8 -> 3 %
    ev = mon.step(3_000_000, {"loss_pct": 1.0, "crc_errors": 2, "stream_age_s": 0.0})
    assert {e.channel.axis for e in ev} == {"loss", "stale"}
    ev = mon.step(7_000_000, {"crc_errors": 2, "boot_count": 1})  # holds of 5 s expired
    assert {e.channel.axis for e in ev} == {"crc", "reboot"}
    assert all(e.state is AlarmState.CLEARED for e in ev)


def _raise(ch: ChannelId, t_us: int, kind: AlarmKind = AlarmKind.SENSOR_FAULT) -> AlarmEvent:
    return AlarmEvent(t_us=t_us, channel=ch, state=AlarmState.RAISED, kind=kind,
                      fault_type=FaultType.UNKNOWN, magnitude=math.nan, residual_rms=1.0,
                      threshold=1.0, estimator="voting")


def test_metrics_wan2018_definitions() -> None:
    a0, a1, a2 = (ChannelId("aoa", i) for i in range(3))
    c0 = ChannelId("cas", 0)
    runs = [
        # fault-free run, clean (link alarms never count)
        evaluate_run([_raise(ChannelId("link", 1, "loss"), 5, AlarmKind.LINK)], {},
                     groups=("aoa", "cas")),
        # fault-free run with a false alarm on aoa
        evaluate_run([_raise(a2, 7)], {}, groups=("aoa", "cas")),
        # faulty aoa run: a0 at 1 s detected after 0.5 s, a1 at 2 s after 1.5 s
        evaluate_run([_raise(a0, 1_500_000), _raise(a1, 3_500_000)],
                     {a0: [(1_000_000, None)], a1: [(2_000_000, None)]}, groups=("cas",)),
        # faulty run: a0 missed, a2 (healthy) isolated; cas fault detected after 0.25 s
        evaluate_run([_raise(a2, 2_000_000), _raise(c0, 1_250_000)],
                     {a0: [(1_000_000, None)], c0: [(1_000_000, 3_000_000)]}),
    ]
    rows = {r.group: r for r in metrics_table(runs)}
    aoa, cas = rows["aoa"], rows["cas"]
    assert (aoa.n_fault_free, aoa.n_faulty) == (2, 2)
    assert aoa.far_pct == pytest.approx(50.0)
    assert aoa.mdr_pct == pytest.approx(50.0)
    assert aoa.fir_pct == pytest.approx(50.0)
    assert aoa.delay_max_s == pytest.approx(1.5)  # run delay = slowest of its faults
    assert aoa.delay_mean_s == pytest.approx(1.5)  # the run with a miss detected nothing
    assert (cas.n_fault_free, cas.n_faulty) == (3, 1)
    assert (cas.far_pct, cas.mdr_pct, cas.fir_pct) == (0.0, 0.0, 0.0)
    assert cas.delay_max_s == pytest.approx(0.25)
    assert "| aoa | 2 | 2 | 50.00" in format_table(list(rows.values()))


def test_metrics_raise_outside_interval_is_false_isolation() -> None:
    a0 = ChannelId("aoa", 0)
    out = evaluate_run([_raise(a0, 500)], {a0: [(1000, 2000)]})["aoa"]
    assert out.false_isolation and out.missed
    out = evaluate_run([_raise(a0, 2100)], {a0: [(1000, 2000)]}, grace_us=200)["aoa"]
    assert not out.false_isolation and not out.missed


def test_link_loss_is_measured_over_a_sliding_window() -> None:
    """Cumulative counters in, loss of the last ``loss_window_s`` out: 30 % loss for 3 s, then
    a clean link; the alarm clears once the lossy seconds have left the 10 s window."""
    mon = LinkAlarmMonitor()
    msgs = lost = 0.0
    states = []
    for k in range(20):
        lossy = k < 3
        msgs += 70.0 if lossy else 100.0
        lost += 30.0 if lossy else 0.0
        states += [(k, e.state) for e in mon.step(k * 1_000_000, {"messages": msgs,
                                                                   "lost": lost})]
    assert states[0] == (1, AlarmState.RAISED)
    assert states[-1] == (12, AlarmState.CLEARED)  # the window starts after the lossy seconds


def test_link_holds_restart_when_the_vehicle_clock_steps_back() -> None:
    """A reboot seen at an old-clock time, then the new clock from 0.1 s: the reboot (and CRC)
    holds run on the new clock and the alarms clear 5 s into it, not when it passes the old."""
    mon = LinkAlarmMonitor()
    mon.step(7_000_000, {"boot_count": 0, "crc_errors": 0})
    ev = mon.step(8_000_000, {"boot_count": 1, "crc_errors": 3})
    assert {(e.channel.axis, e.state) for e in ev} == {("reboot", AlarmState.RAISED),
                                                       ("crc", AlarmState.RAISED)}
    cleared = []
    for k in range(8):
        t_us = 100_000 + k * 1_000_000
        cleared += [(t_us, e.channel.axis) for e in mon.step(t_us, {"boot_count": 1,
                                                                    "crc_errors": 3})
                    if e.state is AlarmState.CLEARED]
    assert cleared == [(5_100_000, "crc"), (5_100_000, "reboot")]


def test_duplicate_sysid_alarm_follows_the_flag() -> None:
    mon = LinkAlarmMonitor()
    assert mon.step(0, {"duplicate_sysid": 1.0})[0].state is AlarmState.RAISED
    assert mon.step(1_000_000, {"duplicate_sysid": 0.0})[0].state is AlarmState.CLEARED


def test_alarm_events_carry_the_confidence_in_their_type() -> None:
    ch = ChannelId("aoa", 1)
    sm = AlarmStateMachine(ch, AlarmKind.SENSOR_FAULT, "voting")
    ev = sm.step(0, True, fault_type=FaultType.BIAS, magnitude=1.0, confidence=0.8)
    assert ev[0].confidence == 0.8
    assert sm.step(1_000_000, True, fault_type=FaultType.BIAS, magnitude=1.0,
                   confidence=0.3) == []  # a confidence change alone is no event ...
    ev = sm.step(2_000_000, False)
    assert ev[0].state is AlarmState.CLEARED and ev[0].confidence == 0.3  # ... the next has it
    # without a stated confidence: observed types are certain, unknown is not a decision
    link = AlarmStateMachine(ChannelId("link", 1, "loss"), AlarmKind.LINK, "link")
    assert link.step(0, True, fault_type=FaultType.LINK)[0].confidence == 1.0
    lost = AlarmStateMachine(ChannelId("aoa", -1), AlarmKind.SET_LOST, "voting")
    assert lost.step(0, True)[0].confidence == 0.0
