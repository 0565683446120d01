"""Console formatting of alarm events for an operator: units they read, one line per event.

Shared by ``gcs-monitor`` (:mod:`gcs_monitor.cli`) and the demo (:mod:`gcs_monitor.demo`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from gcs_monitor.core.units import MPS2KT, RAD2DEG
from gcs_monitor.fdi.events import AlarmEvent


def display_value(kind: str, value_si: float) -> tuple[float, str]:
    """Value in the unit an operator reads for a channel kind."""
    if kind == "aoa" or kind == "euler":
        return value_si * RAD2DEG, "deg"
    if kind == "cas":
        return value_si * MPS2KT, "kt"
    if kind == "gyro":
        return value_si * RAD2DEG, "deg/s"
    if kind == "acc":
        return value_si, "m/s²"
    return value_si, ""


def format_event(ev: AlarmEvent) -> str:
    """One line per alarm event: vehicle time, state, channel, kind, fault type, magnitude in
    display units, estimator and message."""
    ch = ev.channel
    name = f"{ch.kind}{'' if ch.instance < 0 else ch.instance}{'.' + ch.axis if ch.axis else ''}"
    if ch.instance < 0:
        name = f"{ch.kind}[set]"
    mag, unit = display_value(ch.kind, ev.magnitude)
    mag_s = f"{mag:+.3g} {unit}" if math.isfinite(mag) else "-"
    return (f"t={ev.t_us / 1e6:8.2f}s  {ev.state.value.upper():8s} {name:12s} {ev.kind.value:14s} "
            f"{ev.fault_type.value:11s} {mag_s:14s} ({ev.estimator}) {ev.message}")


def family_line(name: str, fam: dict[str, Any]) -> str:
    """One family's state and coverage for the summary."""
    cov = ""
    if math.isfinite(fam["coverage_overall"]):
        cov = (f", coverage {100 * fam['coverage_overall']:.1f} % of the flight, "
               f"{100 * fam['coverage_recent']:.0f} % of the last window")
    why = f"; not judged: {fam['reason']}" if fam["reason"] else ""
    return f"{name:9s} {fam['state']}{cov}{why}  [{fam['title']}]"


def summarise_alarms(events: Sequence[AlarmEvent]) -> list[str]:
    """One line per channel that raised, in order of the first raise: its kind and time, and the
    channel's latest fault type, magnitude (display units) and state (active or cleared)."""
    first: dict[Any, AlarmEvent] = {}
    last: dict[Any, AlarmEvent] = {}
    for ev in events:
        if ev.state.value == "raised" and ev.channel not in first:
            first[ev.channel] = ev
        last[ev.channel] = ev
    out = []
    for ch, ev in sorted(first.items(), key=lambda kv: kv[1].t_us):
        latest = last[ch]
        mag, unit = display_value(ch.kind, latest.magnitude)
        state = "cleared" if latest.state.value == "cleared" else "active"
        out.append(f"{str(ch):12s} {ev.kind.value:14s} raised t={ev.t_us / 1e6:7.2f}s  "
                   f"{latest.fault_type.value:11s} {mag:+9.3g} {unit:6s} {state}")
    return out
