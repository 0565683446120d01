"""Versioned JSON payloads shared by every sink (documented in docs/alarms.md).

Every payload is a plain dict with ``schema_version`` and ``type`` keys, produced here and
nowhere else, so Zenoh consumers, the alarm journal and tests agree on one format.

JSON has no NaN: non-finite floats are written as ``null`` and read back as NaN.
Bump :data:`SCHEMA_VERSION` on any incompatible change (renamed or retyped key, or a key whose
meaning changed); adding a key alone is compatible and keeps the version.

Version 2: an alarm's ``fault_type`` is the type decided at the raise and held by hysteresis
(:class:`gcs_monitor.fdi.classify.LabelHysteresis`), no longer the latest window's guess, and
``confidence`` says how sure it is. Version 1 payloads are still read (``confidence`` NaN).
Added since (compatible): ``alarm_id`` and ``monitor`` on alarms; the health payload carries one
vehicle's health (:meth:`gcs_monitor.monitor.Monitor.vehicle_health`).

The keys, types and meanings of every payload are declared in
:mod:`gcs_monitor.sinks.payload_spec`, which validates payloads and writes docs/alarms.md.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from datetime import UTC, datetime
from typing import Any

import numpy as np

from gcs_monitor.core.types import ChannelId
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState, FaultType
from gcs_monitor.fdi.records import Estimate

SCHEMA_VERSION = 2

US_PER_S = 1_000_000

# SI unit of each channel kind, so a consumer can label the magnitude without guessing.
CHANNEL_UNITS: Mapping[str, str] = {
    "acc": "m/s^2",
    "gyro": "rad/s",
    "aoa": "rad",
    "ssa": "rad",
    "cas": "m/s",
    "tas": "m/s",
    "baro": "m",
    "alt": "m",
    "climb": "m/s",
    "gps_vel": "m/s",
    "attitude": "rad",
    "actuator": "rad",
    "rod": "m",
    "pressure": "Pa",
    "link": "",
}


def channel_unit(channel: ChannelId) -> str:
    """SI unit of a channel's value (``""`` when the kind is unknown or unitless)."""
    return CHANNEL_UNITS.get(channel.kind, "")


def _num(x: float) -> float | None:
    """JSON-safe float: NaN/inf become ``None``."""
    xf = float(x)
    return xf if math.isfinite(xf) else None


def _unnum(x: float | None) -> float:
    return float("nan") if x is None else float(x)


def channel_to_dict(channel: ChannelId) -> dict[str, Any]:
    return {"kind": channel.kind, "instance": int(channel.instance), "axis": channel.axis}


def channel_from_dict(d: Mapping[str, Any]) -> ChannelId:
    return ChannelId(kind=str(d["kind"]), instance=int(d["instance"]), axis=str(d.get("axis", "")))


def alarm_id(vehicle: int, channel: ChannelId, raised_t_us: int) -> str:
    """The stable id of an alarm: ``<vehicle>/<channel>/<raise time, µs of vehicle time>``,
    e.g. ``1/aoa1/20150000``. Every transition of the alarm (raise, updates, clear) carries it;
    a monitor that takes over or restarts keeps the ids of the alarms it inherits, and the same
    bytes give the same ids."""
    return f"{int(vehicle)}/{channel}/{int(raised_t_us)}"


def raised_t_us_of(alarm_id_: str) -> int | None:
    """The raise time in an alarm id (None if it has another form)."""
    tail = alarm_id_.rpartition("/")[2]
    return int(tail) if tail.lstrip("-").isdigit() else None


def wall_time_iso(wall_time_s: float) -> str | None:
    """UTC ISO-8601 with milliseconds, e.g. ``2025-01-31T12:00:00.123Z``; None if not finite."""
    if not math.isfinite(wall_time_s):
        return None
    dt = datetime.fromtimestamp(wall_time_s, tz=UTC)
    return dt.isoformat(timespec="milliseconds").replace("+00:00", "Z")


def alarm_to_dict(event: AlarmEvent, *, wall_time_s: float,
                  monitor: str = "") -> dict[str, Any]:
    """The alarm payload: one per AlarmEvent transition (raised / updated / cleared).

    Parameters
    ----------
    event : the transition
    wall_time_s : POSIX wall time (s) at which the sink handled the event
    monitor : the name of the monitor that published it (a fleet worker's id; ``""``)
    """
    aid = event.alarm_id or (alarm_id(event.vehicle, event.channel, event.t_us)
                             if event.state is AlarmState.RAISED else None)
    return {
        "schema_version": SCHEMA_VERSION,
        "type": "alarm",
        "alarm_id": aid,
        "monitor": monitor,
        "vehicle": int(event.vehicle),
        "channel": channel_to_dict(event.channel),
        "channel_name": str(event.channel),
        "state": event.state.value,
        "kind": event.kind.value,
        "fault_type": event.fault_type.value,
        "confidence": _num(event.confidence),
        "magnitude": _num(event.magnitude),
        "unit": channel_unit(event.channel),
        "residual_rms": _num(event.residual_rms),
        "threshold": _num(event.threshold),
        "t_us": int(event.t_us),
        "vehicle_time_s": event.t_us / US_PER_S,
        "wall_time_s": _num(wall_time_s),
        "wall_time": wall_time_iso(wall_time_s),
        "estimator": event.estimator,
        "message": event.message,
    }


def alarm_from_dict(d: Mapping[str, Any]) -> AlarmEvent:
    """Inverse of :func:`alarm_to_dict` (wall time and derived keys are dropped).

    Raises
    ------
    ValueError
        if the payload is not an alarm or has a newer schema version than this code knows.
    """
    check_payload(d, "alarm")
    return AlarmEvent(
        t_us=int(d["t_us"]),
        channel=channel_from_dict(d["channel"]),
        state=AlarmState(d["state"]),
        kind=AlarmKind(d["kind"]),
        fault_type=FaultType(d["fault_type"]),
        magnitude=_unnum(d["magnitude"]),
        residual_rms=_unnum(d["residual_rms"]),
        threshold=_unnum(d["threshold"]),
        estimator=str(d["estimator"]),
        message=str(d.get("message", "")),
        vehicle=int(d["vehicle"]),
        confidence=_unnum(d.get("confidence")),  # absent before schema version 2
        alarm_id=str(d.get("alarm_id") or ""),
    )


def check_payload(d: Mapping[str, Any], expected_type: str) -> None:
    """Raise ValueError unless ``d`` is a payload of ``expected_type`` we can read."""
    version = d.get("schema_version")
    if not isinstance(version, int) or version > SCHEMA_VERSION or version < 1:
        raise ValueError(
            f"unsupported schema_version {version!r} (this code reads <= {SCHEMA_VERSION})"
        )
    if d.get("type") != expected_type:
        raise ValueError(f"payload type {d.get('type')!r}, expected {expected_type!r}")


def _channel_values(values: Mapping[ChannelId, float]) -> list[dict[str, Any]]:
    return [{**channel_to_dict(ch), "value": _num(v)} for ch, v in sorted(values.items())]


def _channel_values_from(items: list[Mapping[str, Any]]) -> dict[ChannelId, float]:
    return {channel_from_dict(it): _unnum(it["value"]) for it in items}


def estimate_to_dict(estimate: Estimate, *, vehicle: int, wall_time_s: float) -> dict[str, Any]:
    """The estimate payload (published decimated on ``gcs/<vehicle>/estimate/<name>``).

    States keep their names and SI units (the unit is in the name suffix, e.g. ``vel_ned_mps``);
    vectors are lists.
    """
    return {
        "schema_version": SCHEMA_VERSION,
        "type": "estimate",
        "vehicle": int(vehicle),
        "name": estimate.name,
        "t_us": int(estimate.t_us),
        "vehicle_time_s": estimate.t_us / US_PER_S,
        "wall_time_s": _num(wall_time_s),
        "available": bool(estimate.available),
        "reason": estimate.reason,
        "numerics_ok": bool(estimate.numerics_ok),
        "states": {k: to_jsonable(v) for k, v in estimate.states.items()},
        "faults": _channel_values(estimate.faults),
        "residuals": _channel_values(estimate.residuals),
        "virtual": _channel_values(estimate.virtual),
    }


def estimate_from_dict(d: Mapping[str, Any]) -> Estimate:
    """Inverse of :func:`estimate_to_dict` (states come back as float64 arrays)."""
    check_payload(d, "estimate")
    return Estimate(
        name=str(d["name"]),
        t_us=int(d["t_us"]),
        available=bool(d["available"]),
        reason=str(d.get("reason", "")),
        states={
            k: np.array(
                [_unnum(x) for x in np.atleast_1d(np.asarray(v, dtype=object))], dtype=np.float64
            )
            for k, v in d["states"].items()
        },
        faults=_channel_values_from(d["faults"]),
        residuals=_channel_values_from(d["residuals"]),
        virtual=_channel_values_from(d["virtual"]),
        numerics_ok=bool(d["numerics_ok"]),
    )


def health_to_dict(
    health: Mapping[str, Any], *, vehicle: int, wall_time_s: float
) -> dict[str, Any]:
    """The health payload (answered by the ``gcs/<vehicle>/health`` queryable).

    ``health`` comes from the pipeline (current alarms, link statistics, estimator availability);
    its keys are kept as given under ``"health"`` after conversion to JSON-able values.
    """
    return {
        "schema_version": SCHEMA_VERSION,
        "type": "health",
        "vehicle": int(vehicle),
        "wall_time_s": _num(wall_time_s),
        "wall_time": wall_time_iso(wall_time_s),
        "health": to_jsonable(dict(health)),
    }


def to_jsonable(x: Any) -> Any:
    """Recursively convert numpy arrays/scalars, enums, ChannelIds and NaN to JSON values."""
    if isinstance(x, Mapping):
        return {str(k): to_jsonable(v) for k, v in x.items()}
    if isinstance(x, ChannelId):
        return channel_to_dict(x)
    if isinstance(x, AlarmEvent):
        return alarm_to_dict(x, wall_time_s=float("nan"))
    if isinstance(x, np.ndarray):
        return [to_jsonable(v) for v in x.tolist()]
    if isinstance(x, (list, tuple, set, frozenset)):
        return [to_jsonable(v) for v in x]
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return _num(float(x))
    if hasattr(x, "value") and isinstance(x.value, str):  # str Enums
        return x.value
    if x is None or isinstance(x, str):
        return x
    return str(x)


def dumps(payload: Mapping[str, Any]) -> str:
    """Compact JSON, strict (no NaN tokens), one line."""
    return json.dumps(to_jsonable(payload), separators=(",", ":"), allow_nan=False)
