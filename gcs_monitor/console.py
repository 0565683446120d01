"""Console formatting of alarm events for an operator: units they read, one line per event.

Shared by ``gcs-monitor`` (:mod:`gcs_monitor.cli`) and the demo (:mod:`gcs_monitor.demo`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from gcs_monitor.core.types import ChannelId
from gcs_monitor.core.units import MPS2KT, RAD2DEG
from gcs_monitor.fdi.events import OBSERVED_TYPES, AlarmEvent, AlarmState, FaultType


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


def channel_label(ch: ChannelId) -> str:
    """An operator's name of a channel: ``aoa1``, ``acc0.x``, ``aoa[set]`` for a whole set."""
    if ch.instance < 0:
        return f"{ch.kind}[set]{'.' + ch.axis if ch.axis else ''}"
    return f"{ch.kind}{ch.instance}{'.' + ch.axis if ch.axis else ''}"


def magnitude_text(kind: str, value_si: float) -> str:
    """A magnitude in display units, ``-`` when there is none (NaN: a lost set, no data)."""
    mag, unit = display_value(kind, value_si)
    return f"{mag:+.3g} {unit}".rstrip() if math.isfinite(mag) else "-"


def type_text(ev: AlarmEvent) -> str:
    """The fault type, with its confidence when it was inferred by the classifier."""
    ft = ev.fault_type
    if ft is FaultType.UNKNOWN or ft in OBSERVED_TYPES or not math.isfinite(ev.confidence):
        return ft.value
    return f"{ft.value} ({ev.confidence:.2f})"


def vehicle_label(vehicle: int) -> str:
    """The vehicle column of every line: ``v<sysid>``."""
    return f"v{vehicle}"


def format_event(ev: AlarmEvent) -> str:
    """One line per alarm event: vehicle, vehicle time, state, channel, kind, fault type (and
    its confidence), magnitude in display units, estimator and message."""
    name = channel_label(ev.channel)
    mag_s = magnitude_text(ev.channel.kind, ev.magnitude)
    return (f"{vehicle_label(ev.vehicle):4s} t={ev.t_us / 1e6:8.2f}s  "
            f"{ev.state.value.upper():8s} {name:12s} {ev.kind.value:14s} "
            f"{type_text(ev):18s} {mag_s:14s} ({ev.estimator}) {ev.message}")


def family_line(name: str, fam: dict[str, Any]) -> str:
    """One family's state and coverage for the summary."""
    cov = ""
    if math.isfinite(fam["coverage_overall"]):
        cov = (f", coverage {100 * fam['coverage_overall']:.1f} % of the flight, "
               f"{100 * fam['coverage_recent']:.0f} % of the last window")
    why = f"; not judged: {fam['reason']}" if fam["reason"] else ""
    return f"{name:9s} {fam['state']}{cov}{why}  [{fam['title']}]"


def first_and_final(events: Sequence[AlarmEvent]) -> list[tuple[AlarmEvent, AlarmEvent, int]]:
    """Per vehicle and channel that raised, in order of the vehicle then its first raise:
    (first RAISED event, the channel's last event, how many times it was raised). Two vehicles'
    ``aoa1`` are two rows."""
    first: dict[tuple[int, ChannelId], AlarmEvent] = {}
    last: dict[tuple[int, ChannelId], AlarmEvent] = {}
    raised: dict[tuple[int, ChannelId], int] = {}
    for ev in events:
        k = (ev.vehicle, ev.channel)
        if ev.state is AlarmState.RAISED:
            first.setdefault(k, ev)
            raised[k] = raised.get(k, 0) + 1
        if k in first:
            last[k] = ev
    return [(ev, last[k], raised[k])
            for k, ev in sorted(first.items(), key=lambda kv: (kv[0][0], kv[1].t_us))]


def final_state(ev: AlarmEvent) -> str:
    return "cleared" if ev.state is AlarmState.CLEARED else "active"


def summarise_alarms(events: Sequence[AlarmEvent]) -> list[str]:
    """One line per vehicle and channel that raised (the line starts with the vehicle, ``v1``),
    in order of vehicle and first raise: the first raise (time,
    fault type, magnitude) and, separately, the final state (active or cleared, since when, and
    the type and magnitude it ended with). Magnitudes in display units; ``-`` where there is none
    (a lost set, no data). The final state is the channel's last event: its time, active or
    cleared, and the type and magnitude it reported."""
    out = []
    for first, last, n in first_and_final(events):
        kind = first.channel.kind
        again = f", raised {n} times" if n > 1 else ""
        out.append(
            f"{vehicle_label(first.vehicle):4s} {channel_label(first.channel):12s} "
            f"{first.kind.value:16s} "
            f"first raise t={first.t_us / 1e6:7.2f}s {type_text(first):18s} "
            f"{magnitude_text(kind, first.magnitude):12s} | final (t={last.t_us / 1e6:7.2f}s): "
            f"{final_state(last):7s} {type_text(last):18s} "
            f"{magnitude_text(kind, last.magnitude)}{again}")
    return out
