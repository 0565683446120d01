"""Helpers of the end-to-end tests: a fault-free simulated stream, a Monitor runner, repacking."""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass, field
from typing import Any

from gcs_monitor.families.base import FamilyContext
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind
from gcs_monitor.link.mav import mavlink
from gcs_monitor.monitor import Monitor
from gcs_monitor.pipeline import build_families

BASE_PRESET = "lu2016_calm"  # calm level flight; its Table 2 IMU faults are removed
BASE_DURATION_S = 8.0
SENSOR_KINDS = frozenset({AlarmKind.SENSOR_FAULT, AlarmKind.ACTUATOR_FAULT, AlarmKind.SET_LOST})


@functools.cache
def clean_packets(duration_s: float) -> list[tuple[int, bytes]]:
    """A fault-free simulated flight of ``duration_s`` as (t_us, packet), every contract
    message (``BASE_PRESET`` with its faults removed)."""
    from sim_vehicle.run import iter_packets
    from sim_vehicle.scenario import load_scenario

    sc = load_scenario(BASE_PRESET)
    sc = dataclasses.replace(sc, faults=(), duration_s=duration_s)
    return list(iter_packets(sc))


def base_packets() -> list[tuple[int, bytes]]:
    """The fault-free base flight (``BASE_DURATION_S``)."""
    return clean_packets(BASE_DURATION_S)


@dataclass
class MonitorRun:
    monitor: Monitor
    events: list[AlarmEvent]
    health: dict[str, Any]
    builds: list[list[str]] = field(default_factory=list)  # family names of every build

    @property
    def sensor_alarms(self) -> list[AlarmEvent]:
        return [e for e in self.events if e.kind in SENSOR_KINDS]

    def link_alarms(self, name: str) -> list[AlarmEvent]:
        """Raised LINK alarms on ``ChannelId("link", vehicle, name)``."""
        return [e for e in self.events if e.kind == AlarmKind.LINK
                and e.channel.axis == name and e.state.value == "raised"]


def run_monitor(data: bytes, *, chunk: int = 4096, **kw: Any) -> MonitorRun:
    """Feed ``data`` through a default Monitor in chunks; record every family build (a vehicle's
    families are built when it first sends frames and again after an autopilot reboot)."""
    m0 = Monitor()
    builds: list[list[str]] = []

    def families_for(ctx: FamilyContext) -> list[Any]:
        fams = build_families(dict(m0.cfg.families), ctx)
        builds.append([f.name for f in fams])
        return fams

    m = Monitor(families_for=families_for, **kw)
    for i in range(0, len(data), chunk):
        m.feed(data[i:i + chunk])
    m.finish()
    return MonitorRun(m, list(m.events), m.health(), builds)


def repack(packet: bytes, **fields: Any) -> bytes:
    """The same MAVLink 2 packet (sender, sequence number) with some fields replaced."""
    msg = mavlink.MAVLink(None).decode(bytearray(packet))
    seq = fields.pop("_seq", packet[4])
    for k, v in fields.items():
        setattr(msg, k, v)
    mav = mavlink.MAVLink(None, srcSystem=packet[5], srcComponent=packet[6])
    mav.seq = seq
    return bytes(msg.pack(mav, force_mavlink1=False))


def resequence(packets: list[bytes]) -> list[bytes]:
    """The same packets with consecutive sequence numbers per sender, as an autopilot that
    simply stopped sending one stream would number them (dropping packets alone would look
    like link loss)."""
    seq: dict[tuple[int, int], int] = {}
    out = []
    for p in packets:
        key = (p[5], p[6])
        n = seq.get(key, p[4])
        seq[key] = (n + 1) % 256
        out.append(p if p[4] == n else repack(p, _seq=n))
    return out


def msg_name(packet: bytes) -> str:
    cls = mavlink.mavlink_map.get(packet[7] | packet[8] << 8 | packet[9] << 16)
    return cls.msgname if cls is not None else "?"
