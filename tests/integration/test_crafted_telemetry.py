"""Crafted telemetry, one case each: a sensor instance that goes quiet mid-flight gives exactly
the expected alarms and nothing else (issue 15, "silent and dying sensors").

The flight: the first 22 s of the demo preset with its faults removed (three IMUs, triplex AoA
and CAS, calm transport cruise), through MAVLink bytes and the default monitor. One message
stream is cut at 12 s (after the IMU estimator's 5 s warm-up).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable

from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState, FaultType
from gcs_monitor.monitor import Monitor
from tests.integration.support import msg_name, resequence

DURATION_S = 22.0
CUT_US = 12_000_000


@functools.cache
def _packets() -> list[tuple[int, bytes]]:
    from sim_vehicle.run import iter_packets
    from sim_vehicle.scenario import load_scenario

    sc = dataclasses.replace(load_scenario("demo_airdata_faults"), faults=(),
                             duration_s=DURATION_S)
    return list(iter_packets(sc))


def _instance(pkt: bytes) -> int | None:
    """The instance id of HIGHRES_IMU / AIRSPEED, the vane of NAMED_VALUE_FLOAT AOA1/AOA2."""
    from pymavlink.dialects.v20 import ardupilotmega as mavlink

    m = mavlink.MAVLink(None).decode(bytearray(pkt))
    if m.get_type() == "NAMED_VALUE_FLOAT":
        name = m.name if isinstance(m.name, str) else m.name.decode()
        return {"AOA1": 1, "AOA2": 2}.get(name.rstrip("\x00"))
    return int(m.id) if hasattr(m, "id") else None


def _run(drop: Callable[[int, bytes], bool]) -> list[AlarmEvent]:
    mon = Monitor()
    mon.feed(b"".join(resequence([p for t, p in _packets() if not drop(t, p)])))
    mon.finish()
    return list(mon.events)


def _silent(name: str, instance: int) -> Callable[[int, bytes], bool]:
    def drop(t_us: int, pkt: bytes) -> bool:
        return t_us >= CUT_US and msg_name(pkt) == name and _instance(pkt) == instance
    return drop


def _summary(events: list[AlarmEvent]) -> list[tuple[str, str, str, str]]:
    return [(str(e.channel), e.state.value, e.kind.value, e.fault_type.value) for e in events]


def _no_data_only(events: list[AlarmEvent], channel: str) -> None:
    raised = [e for e in events if e.state is AlarmState.RAISED]
    assert [(str(e.channel), e.kind, e.fault_type) for e in raised] == [
        (channel, AlarmKind.SENSOR_FAULT, FaultType.NO_DATA)], _summary(events)
    assert raised[0].t_us >= CUT_US


def test_the_fault_free_flight_is_silent() -> None:
    assert _run(lambda t, p: False) == []


def test_imu1_silent_raises_no_data_on_it_only() -> None:
    events = _run(_silent("HIGHRES_IMU", 1))
    _no_data_only(events, "imu1")
    assert "2 of 3 IMUs deliver" in events[0].message


def test_imu0_silent_switches_the_primary_without_sensor_alarms() -> None:
    events = _run(_silent("HIGHRES_IMU", 0))
    sensor = [e for e in events if e.kind is AlarmKind.SENSOR_FAULT]
    assert [(str(e.channel), e.state.value, e.fault_type) for e in sensor] == [
        ("imu0", "raised", FaultType.NO_DATA)], _summary(events)
    # the estimators restart on IMU 1: an operator notice, raised and cleared, and the IMU
    # family says it was blind for the restart (monitor_degraded), never a sensor fault
    others = {(str(e.channel), e.kind) for e in events if e.kind is not AlarmKind.SENSOR_FAULT}
    assert others <= {("estimator0.imu_ts", AlarmKind.ESTIMATOR),
                      ("monitor0.imu", AlarmKind.MONITOR_DEGRADED)}, _summary(events)
    notice = [e for e in events if e.kind is AlarmKind.ESTIMATOR]
    assert notice and "primary IMU switched from 0 to 1" in notice[0].message


def test_one_vane_silent_raises_no_data_on_it_only() -> None:
    _no_data_only(_run(_silent("NAMED_VALUE_FLOAT", 1)), "aoa1")


def test_one_pitot_silent_raises_no_data_on_it_only() -> None:
    _no_data_only(_run(_silent("AIRSPEED", 2)), "cas2")
