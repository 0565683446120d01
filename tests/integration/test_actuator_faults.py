"""End to end, simulator -> MAVLink bytes -> Monitor: the actuator family raises
``actuator_fault`` on the surface that failed, with its class, and nothing in a fault-free
manoeuvring flight in turbulence (issue 17)."""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path

from gcs_monitor.config.loader import load_config
from gcs_monitor.core.types import ChannelId
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState, FaultType
from gcs_monitor.monitor import Monitor


@functools.cache
def _events(preset: str, duration_s: float, faults: bool) -> tuple[AlarmEvent, ...]:
    from sim_vehicle.run import iter_packets
    from sim_vehicle.scenario import load_scenario

    sc = load_scenario(preset)
    sc = dataclasses.replace(sc, duration_s=duration_s,
                             actuator_faults=sc.actuator_faults if faults else ())
    # the actuator family with its default configuration (both tiers); the sensor families do
    # not take part
    # not take part; the servo level with the UAV's lever (configs/uav.toml)
    uav = Path(__file__).resolve().parents[2] / "configs" / "uav.toml"
    cfg = load_config(uav).with_family("imu", enabled=False).with_family(
        "airdata", enabled=False).with_family("yaw_rate", enabled=False)
    mon = Monitor(cfg)
    data = b"".join(p for _, p in iter_packets(sc))
    for i in range(0, len(data), 8192):
        mon.feed(data[i:i + 8192])
    mon.finish()
    return tuple(mon.events)


def _raised(events: tuple[AlarmEvent, ...], kind: str = "actuator") -> list[AlarmEvent]:
    """Raised actuator alarms of one tier: ``actuator`` (aircraft level) or ``surface`` (servo
    level, where SURF feedback exists)."""
    return [e for e in events if e.kind is AlarmKind.ACTUATOR_FAULT
            and e.state is AlarmState.RAISED and e.channel.kind == kind]


def test_stuck_elevator_is_raised_on_the_elevator_as_stuck_at_zero() -> None:
    # demo preset: S-turn in 1.5 m/s turbulence, elevator stuck at zero at 25 s
    events = _events("demo_actuator_faults", 35.0, True)
    raised = _raised(events)
    assert [e.channel for e in raised] == [ChannelId("actuator", 1, "elevator")]
    assert 25.0 <= raised[0].t_us * 1e-6 <= 27.0  # within 2 s of the jam
    last = [e for e in events if e.channel == raised[0].channel][-1]
    assert last.fault_type is FaultType.STUCK and "stuck at zero" in last.message
    assert not [e for e in events if e.kind is AlarmKind.MONITOR_DEGRADED]
    # the servo level, which sees the surface position, names the same surface
    assert {e.channel.instance for e in _raised(events, "surface")} <= {1}


def test_engine_out_is_raised_on_the_engine() -> None:
    raised = _raised(_events("uav_engine_out", 36.0, True))
    assert [e.channel.axis for e in raised] == ["engine"]
    assert raised[0].fault_type is FaultType.LOSS_OF_EFFECTIVENESS
    assert 30.0 <= raised[0].t_us * 1e-6 <= 33.0


def test_fault_free_manoeuvring_flight_raises_nothing() -> None:
    # the demo flight without its fault: S-turns in turbulence for 60 s
    events = _events("demo_actuator_faults", 60.0, False)
    assert _raised(events) == [] and _raised(events, "surface") == []
    assert not [e for e in events if e.kind is AlarmKind.MONITOR_DEGRADED]
