"""The documented payload schema: every key of the alarm, estimate and health payloads, its type
and meaning, in one place.

:func:`validate` checks a payload against it (unknown keys, missing keys, wrong types), so tests
hold real payloads -- alarms of a monitored flight, the health a ``gcs/<vehicle>/health``
queryable answers -- to what is documented; :func:`alarms_markdown` writes docs/alarms.md from it
(``python -m gcs_monitor.sinks.payload_spec > docs/alarms.md``), so the page cannot drift from the
payloads.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from gcs_monitor.sinks.schema import SCHEMA_VERSION

# -- the schema language ---------------------------------------------------------------------


@dataclass(frozen=True)
class Obj:
    """A JSON object with these keys (and no others)."""

    fields: tuple[F, ...]


@dataclass(frozen=True)
class ListOf:
    item: Any


@dataclass(frozen=True)
class MapOf:
    """An object whose keys are data (message names, family names); every value is ``value``."""

    key: str
    value: Any


@dataclass(frozen=True)
class F:
    """One key: name, type (``int``, ``float``, ``str``, ``bool``, ``any``, or an Obj / ListOf /
    MapOf), meaning; ``null``: may be null; ``optional``: may be absent."""

    name: str
    type: Any
    doc: str
    null: bool = False
    optional: bool = False


def _type_name(t: Any) -> str:
    if isinstance(t, str):
        return t
    if isinstance(t, Obj):
        return "object"
    if isinstance(t, ListOf):
        return f"list of {_type_name(t.item)}"
    if isinstance(t, MapOf):
        return f"object: {t.key} -> {_type_name(t.value)}"
    raise TypeError(t)


# -- alarm -------------------------------------------------------------------------------------

CHANNEL = Obj((
    F("kind", "str", "`aoa`, `cas`, `acc`, `gyro`, `actuator`, `link`, ..."),
    F("instance", "int", "instance number (-1: the whole redundant set)"),
    F("axis", "str", "`\"\"` for scalar channels, else `x`/`y`/`z`, `p`/`q`/`r`, a surface name, "
                     "or the link condition (`loss`, `crc`, `stale`, `reboot`, "
                     "`duplicate_sysid`, `signature`)"),
))

ALARM = Obj((
    F("schema_version", "int", f"payload schema version ({SCHEMA_VERSION})"),
    F("type", "str", "`\"alarm\"`"),
    F("alarm_id", "str", "stable id of the alarm this transition belongs to: "
                         "`<vehicle>/<channel>/<raise time in µs of vehicle time>`, the same on "
                         "the raise, every update and the clear; kept by a monitor that takes "
                         "the vehicle over or restarts (see *Alarm ids* below)", null=True),
    F("monitor", "str", "name of the monitor that published it (a fleet worker's id; `\"\"` for "
                        "a single `gcs-monitor live`)"),
    F("vehicle", "int", "MAVLink system id"),
    F("channel", CHANNEL, "the isolated channel"),
    F("channel_name", "str", "`str(ChannelId)`, e.g. `acc1.z`, `aoa2`"),
    F("state", "str", "`raised`, `updated` (the magnitude or type of an active alarm changed, or "
                      "a monitor that took over confirmed it) or `cleared`"),
    F("kind", "str", "`sensor_fault`, `actuator_fault`, `set_lost` (every instance of a "
                     "redundant set is faulty, Wan2018 Table I), `link`, `estimator`, "
                     "`monitor_degraded`"),
    F("fault_type", "str", "`unknown`, `bias`, `drift`, `oscillation`, `stuck`, `runaway`, "
                           "`loss_of_effectiveness` (an actuator that still moves but acts less; "
                           "`magnitude` is then the share of its effect lost, 0..1, 1 = engine "
                           "out), `noise`, `link`, `no_data`"),
    F("confidence", "float", "how sure `fault_type` is, in [0, 1] (below)", null=True),
    F("magnitude", "float", "estimated fault magnitude, signed, in `unit`, from the model of "
                            "the reported `fault_type` on the latest window; null where there is "
                            "none (a lost set, no data)", null=True),
    F("unit", "str", "SI unit of the channel (`rad`, `m/s`, `m/s^2`, `rad/s`, ...)"),
    F("residual_rms", "float", "residual RMS J at the transition (Wan2018 eq. 18)", null=True),
    F("threshold", "float", "threshold J_th in use", null=True),
    F("t_us", "int", "vehicle time of the transition, µs of the autopilot clock"),
    F("vehicle_time_s", "float", "the same in seconds"),
    F("wall_time_s", "float", "when the monitor handled it (POSIX seconds)", null=True),
    F("wall_time", "str", "the same, ISO-8601 UTC", null=True),
    F("estimator", "str", "which residual raised it (`voting` for the set-level reference, "
                          "`imu_ts`, `airdata`, `link`, ...)"),
    F("message", "str", "free text for humans"),
))

# -- estimate ----------------------------------------------------------------------------------

CHANNEL_VALUE = Obj(CHANNEL.fields + (F("value", "float", "SI value", null=True),))

ESTIMATE = Obj((
    F("schema_version", "int", f"payload schema version ({SCHEMA_VERSION})"),
    F("type", "str", "`\"estimate\"`"),
    F("vehicle", "int", "MAVLink system id"),
    F("name", "str", "estimator (`imu_ts`, `imu_hosm`, `airdata`, ...)"),
    F("t_us", "int", "vehicle time, µs"),
    F("vehicle_time_s", "float", "the same in seconds"),
    F("wall_time_s", "float", "POSIX seconds", null=True),
    F("available", "bool", "false when an input was missing"),
    F("reason", "str", "why not available"),
    F("numerics_ok", "bool", "false after a numerical failure (the estimator was reset)"),
    F("states", MapOf("state name with frame and unit suffix", "any"),
      "states, vectors as lists (`vel_ned_mps`, `euler_rad`, `wind_ned_mps`)"),
    F("faults", ListOf(CHANNEL_VALUE), "reconstructed faults per channel"),
    F("residuals", ListOf(CHANNEL_VALUE), "measurement minus prediction per channel"),
    F("virtual", ListOf(CHANNEL_VALUE), "corrected (virtual-sensor) values per channel"),
))

# -- health ------------------------------------------------------------------------------------

LINK_STATS = Obj((
    F("sysid", "int", "the sender's system id"),
    F("is_vehicle", "bool", "its HEARTBEAT says it is a vehicle (not a GCS, radio, companion)"),
    F("mav_type", "int", "MAV_TYPE of its HEARTBEAT (-1: none yet)"),
    F("autopilot", "int", "MAV_AUTOPILOT of its HEARTBEAT (-1: none yet)"),
    F("messages", "int", "packets decoded"),
    F("bytes", "int", "their wire bytes"),
    F("span_s", "float", "wall time between the first and last packet"),
    F("rate_hz", "float", "mean packet rate over the span"),
    F("bytes_per_s", "float", "mean byte rate over the span"),
    F("per_type", MapOf("message name", "int"), "packets per message type"),
    F("per_type_bytes", MapOf("message name", "int"), "bytes per message type"),
    F("rates_hz", MapOf("message name", "float"), "mean rate per type over the span"),
    F("recent_rates_hz", MapOf("message name", "float"),
      "rate per type over the last complete 5 s window"),
    F("lost", "int", "packets missing from the sequence numbers, bursts longer than 256 "
                     "included (`lost_wrapped`)"),
    F("loss_pct", "float", "lost / (received + lost), %"),
    F("lost_wrapped", "int", "packets of bursts longer than the 8-bit sequence space, found by "
                             "bounding the count with the sender's clock (`time_boot_ms`) and "
                             "its measured packet rate"),
    F("duplicates", "int", "exact repeats of the previous packet (dropped)"),
    F("reordered", "int", "packets that arrived after a later one"),
    F("duplicate_sysid", "bool", "two senders share this system id now"),
    F("duplicate_sysid_seen", "bool", "... at some time"),
    F("heartbeat_conflicts", "int", "HEARTBEATs whose type/autopilot changed on one component"),
    F("signature_failures", "int", "packets claiming this sender rejected by MAVLink 2 signing "
                                   "(the next three together)"),
    F("unsigned_rejected", "int", "... unsigned while signing is required"),
    F("wrong_key", "int", "... whose signature does not verify (forged, or another key)"),
    F("replayed", "int", "... validly signed but not newer than the stream's last timestamp"),
    F("signed_packets", "int", "packets whose signature verified"),
    F("unsigned_accepted", "int", "unsigned packets let through (signing not required)"),
    F("mav1_no_instance", MapOf("message name", "int"),
      "packets in MAVLink 1 framing whose instance id is a MAVLink 2 extension "
      "(HIGHRES_IMU `id`): every instance reads as 0"),
    F("mav1_instance_repeats", "int", "... whose time stamp repeated or stepped back: several "
                                      "instances merged into one (see `notes`)"),
    F("unknown_messages", "int", "well-framed packets whose id is not in the dialect"),
    F("bad_values", MapOf("MESSAGE.field", "int"), "values that were NaN/inf or impossible"),
    F("bad_values_total", "int", "their sum"),
    F("time_backwards", "int", "vehicle-time steps backwards that were no reboot (dropped)"),
    F("clock_conflicts", "int", "two vehicle clocks interleaving"),
    F("time_rejected", "int", "time stamps no vehicle clock can carry (dropped)"),
    F("time_jumps", "int", "confirmed forward jumps of the vehicle clock"),
    F("duplicates_dropped", "int", "same-timestamp samples dropped by the assembler"),
    F("imu_held", "int", "IMU samples that repeat their instance's previous six values "
                         "exactly (a held value, not a measurement: the earlier sample and "
                         "its time are kept)"),
    F("reboots", "int", "autopilot reboots (vehicle clock restarted)"),
    F("boot_count", "int", "the same"),
    F("primary_imu_switches", "int", "changes of the primary IMU"),
    F("last_vehicle_t_us", "int", "latest vehicle time seen, µs"),
))

LINK_WIDE = Obj((
    F("bytes_in", "int", "bytes read from the source"),
    F("chunks", "int", "reads (datagrams, TCP reads, tlog chunks, Zenoh samples)"),
    F("parse_errors", "int", "CRC failures and undecodable frames"),
    F("garbage_bytes", "int", "bytes between packets that are no MAVLink frame"),
    F("bad_signature", "int", "packets rejected by signing (the next three together)"),
    F("unsigned_rejected", "int", "... unsigned while signing is required"),
    F("wrong_key", "int", "... forged or signed with another key"),
    F("replayed", "int", "... replayed"),
    F("unknown_messages", "int", "well-framed packets with an unknown id"),
    F("duplicates", "int", "exact repeats dropped"),
    F("dropped_chunks", "int", "input chunks dropped by the monitor's bounded input queue"),
    F("dropped_bytes", "int", "their bytes"),
    F("resync_bytes", "int", "tlog bytes skipped to find the next record"),
    F("kernel_drops", "int", "datagrams the operating system dropped because the socket "
                             "buffer was full (`SO_RXQ_OVFL`); null where the source cannot "
                             "tell", null=True),
    F("truncated_bytes", "int", "bytes of a cut last tlog record", optional=True),
    F("foreign", "int", "messages of another system id on a stream that carries one vehicle "
                        "(a fleet worker's `mavlink/<sysid>/rx`): dropped"),
))

INPUTS = Obj((
    F("imu_instances", "int", "IMU instances seen"),
    F("imu_ids", ListOf("int"), "their instance ids"),
    F("imu_source", "str", "message carrying the IMU (`HIGHRES_IMU`, `SCALED_IMU`)", null=True),
    F("primary_imu", "int", "primary IMU instance", null=True),
    F("attitude", "bool", "ATTITUDE seen"),
    F("gps_velocity", "bool", "GLOBAL_POSITION_INT seen"),
    F("aoa_instances", "int", "AoA vanes seen"),
    F("aoa_ids", ListOf("int"), "their instance ids"),
    F("cas_instances", "int", "airspeed sensors seen"),
    F("cas_ids", ListOf("int"), "their instance ids"),
    F("ssa", "bool", "sideslip seen"),
    F("baro", "bool", "VFR_HUD seen"),
    F("static_pressure", "bool", "SCALED_PRESSURE seen"),
    F("surfaces", "bool", "surface feedback (DEBUG_FLOAT_ARRAY SURF) seen"),
    F("body_rates", "bool", "body rates seen (ATTITUDE rollspeed, pitchspeed, yawspeed)"),
    F("servo_outputs", "bool", "SERVO_OUTPUT_RAW seen"),
    F("nav_setpoints", "bool", "NAV_CONTROLLER_OUTPUT seen (commanded bank, pitch, heading)"),
    F("attitude_target", "bool", "ATTITUDE_TARGET seen"),
    F("throttle", "bool", "a throttle value seen (VFR_HUD.throttle)"),
    F("commands", "bool", "control commands seen (servo outputs or setpoints): what the "
                          "actuator family's aircraft level needs"),
    F("frames", "int", "Frames assembled"),
))

FAMILY_ROW = Obj((
    F("title", "str", "the family's title"),
    F("state", "str", "`judging`, `degraded`, `starting`, `unavailable` or `disabled`"),
    F("reason", "str", "why it does not judge (`\"\"` while judging)"),
    F("coverage_recent", "float", "share of the last coverage window it judged", null=True),
    F("coverage_overall", "float", "share of the flight it judged", null=True),
))

ACTIVE_ALARM = Obj((
    F("alarm_id", "str", "the alarm's id (as in its alarm payloads)"),
    F("channel", "str", "channel name (`aoa1`, `acc0.x`, `link1.loss`)"),
    F("kind", "str", "alarm kind"),
    F("fault_type", "str", "fault type held now"),
    F("confidence", "float", "its confidence", null=True),
    F("magnitude", "float", "latest magnitude, SI", null=True),
    F("since_t_us", "int", "raise time, vehicle µs", null=True),
    F("last_t_us", "int", "vehicle time of its latest transition, µs"),
))

HANDOVER = Obj((
    F("reason", "str", "`takeover` (a fleet worker took the vehicle over), `restart` (alarms "
                       "inherited from the journal) or `reboot` (autopilot reboot)"),
    F("source", "str", "the previous owner (fleet worker id), if known"),
    F("wall_time_s", "float", "when", null=True),
    F("watermark_us", "int", "vehicle time up to which the previous owner had published: "
                             "events up to it are not published again", null=True),
    F("inherited", "int", "active alarms taken over"),
    F("confirmed", "int", "... that the new pipeline raised again (published as `updated`)"),
    F("cleared_unconfirmed", "int", "... not confirmed within the grace time: cleared"),
    F("suppressed", "int", "events at or before the watermark, not published again"),
    F("warmup_raised", "int", "alarms raised during the warm-up and still active after the "
                              "grace time: published then"),
    F("resumed_t_us", "int", "first vehicle time judged after the watermark", null=True),
))

SINK_ROW = Obj((
    F("sink", "str", "sink class"),
    F("active", "bool", "its session is open", optional=True),
    F("n_published", "int", "payloads published", optional=True),
    F("n_dropped", "int", "payloads dropped (full queue, closed session)", optional=True),
    F("n_errors", "int", "network or disk errors", optional=True),
))

FLEET = Obj((
    F("worker", "str", "this worker's id"),
    F("group", "str", "its fleet group"),
    F("workers", ListOf("str"), "live workers of the group, as this worker sees them"),
    F("owned_since_wall_s", "float", "when this worker took the vehicle"),
    F("takeover_s", "float", "seconds from the previous owner's disappearance to the first "
                             "Frame judged here", null=True),
))

VEHICLE_HEALTH = Obj((
    F("monitor", "str", "the monitor's name (fleet worker id, `\"\"` for `live`)"),
    F("vehicle_time_s", "float", "latest vehicle time judged"),
    F("link", LINK_STATS, "this sender's link statistics"),
    F("link_wide", LINK_WIDE, "counters of the link (or of the vehicle's stream on a worker) "
                              "that belong to no sender"),
    F("notes", ListOf("str"), "warnings an operator must see (a MAVLink 1 link merging IMU "
                              "instances)"),
    F("inputs", INPUTS, "which telemetry inputs the vehicle sends"),
    F("families", MapOf("family name (one per registered family)", FAMILY_ROW),
      "each family's state and coverage"),
    F("alarms", ListOf(ACTIVE_ALARM), "the active (published) alarms"),
    F("handover", HANDOVER, "how monitoring started over, if it did", null=True),
    F("sinks", ListOf(SINK_ROW), "the vehicle's outputs"),
    F("fleet", FLEET, "fleet worker only: ownership of the vehicle", optional=True),
))

HEALTH = Obj((
    F("schema_version", "int", f"payload schema version ({SCHEMA_VERSION})"),
    F("type", "str", "`\"health\"`"),
    F("vehicle", "int", "MAVLink system id"),
    F("wall_time_s", "float", "when the health was taken (POSIX seconds)", null=True),
    F("wall_time", "str", "the same, ISO-8601 UTC", null=True),
    F("health", VEHICLE_HEALTH, "the vehicle's health (`Monitor.vehicle_health`)"),
))

PAYLOADS: dict[str, Obj] = {"alarm": ALARM, "estimate": ESTIMATE, "health": HEALTH}

# -- validation --------------------------------------------------------------------------------


def _check(value: Any, t: Any, path: str, null: bool, errors: list[str]) -> None:
    if value is None:
        if not null:
            errors.append(f"{path}: null, expected {_type_name(t)}")
        return
    if t == "any":
        return
    if t == "int":
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif t == "float":
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    elif t == "str":
        ok = isinstance(value, str)
    elif t == "bool":
        ok = isinstance(value, bool)
    elif isinstance(t, Obj):
        if not isinstance(value, Mapping):
            errors.append(f"{path}: expected an object, got {type(value).__name__}")
            return
        _check_obj(value, t, path, errors)
        return
    elif isinstance(t, ListOf):
        if not isinstance(value, list):
            errors.append(f"{path}: expected a list, got {type(value).__name__}")
            return
        for i, item in enumerate(value):
            _check(item, t.item, f"{path}[{i}]", False, errors)
        return
    elif isinstance(t, MapOf):
        if not isinstance(value, Mapping):
            errors.append(f"{path}: expected an object, got {type(value).__name__}")
            return
        for k, item in value.items():
            _check(item, t.value, f"{path}.{k}", False, errors)
        return
    else:
        raise TypeError(t)
    if not ok:
        errors.append(f"{path}: expected {t}, got {type(value).__name__} {value!r}")


def _check_obj(d: Mapping[str, Any], spec: Obj, path: str, errors: list[str]) -> None:
    names = {f.name for f in spec.fields}
    for k in d:
        if k not in names:
            errors.append(f"{path}.{k}: not documented (add it to gcs_monitor/sinks/"
                          f"payload_spec.py and regenerate docs/alarms.md)")
    for f in spec.fields:
        if f.name not in d:
            if not f.optional:
                errors.append(f"{path}.{f.name}: missing")
            continue
        _check(d[f.name], f.type, f"{path}.{f.name}", f.null, errors)


def validate(payload: Mapping[str, Any]) -> list[str]:
    """Every way ``payload`` differs from its documented schema (empty: it matches)."""
    t = payload.get("type")
    spec = PAYLOADS.get(str(t))
    if spec is None:
        return [f"type {t!r}: expected one of {sorted(PAYLOADS)}"]
    errors: list[str] = []
    _check_obj(payload, spec, str(t), errors)
    return errors


# -- documentation -----------------------------------------------------------------------------


def _rows(spec: Obj, prefix: str = "") -> list[str]:
    out = []
    for f in spec.fields:
        key = f"{prefix}{f.name}"
        t = _type_name(f.type) + (" or null" if f.null else "") + (
            ", optional" if f.optional else "")
        out.append(f"| `{key}` | {t} | {f.doc} |")
        sub = f.type
        if isinstance(sub, ListOf) and isinstance(sub.item, Obj):
            out += _rows(sub.item, f"{key}[].")
        elif isinstance(sub, MapOf) and isinstance(sub.value, Obj):
            out += _rows(sub.value, f"{key}.<{sub.key}>.")
        elif isinstance(sub, Obj):
            out += _rows(sub, f"{key}.")
    return out


def table(spec: Obj) -> str:
    """The Markdown table of a payload (nested keys dotted)."""
    return "\n".join(["| key | type | meaning |", "|---|---|---|", *_rows(spec)])


def example_alarm() -> dict[str, Any]:
    """The documented example: a bias on AoA vane 2, isolated by the voting stage."""
    from gcs_monitor.core.types import ChannelId
    from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState, FaultType
    from gcs_monitor.sinks.schema import alarm_id, alarm_to_dict

    ch = ChannelId("aoa", 2)
    ev = AlarmEvent(12_150_000, ch, AlarmState.RAISED, AlarmKind.SENSOR_FAULT, FaultType.BIAS,
                    0.0351, 0.0208, 0.014, "voting", "vane 2 disagrees with the fused AoA",
                    vehicle=1, confidence=0.93, alarm_id=alarm_id(1, ch, 12_150_000))
    return alarm_to_dict(ev, wall_time_s=1767225600.125, monitor="")


PAGE_HEAD = f"""# Alarm, estimate and health payloads (schema version {SCHEMA_VERSION})

<!-- Generated by `python -m gcs_monitor.sinks.payload_spec > docs/alarms.md` from
gcs_monitor/sinks/payload_spec.py; tests/gcs_monitor/sinks/test_payload_spec.py checks that this
page is current and that real payloads match it. Edit the module, not this page. -->

The monitor publishes the same versioned JSON payloads on Zenoh and in the alarm journal.
`gcs_monitor/sinks/schema.py` is the only place that builds or reads them:
`alarm_to_dict` / `alarm_from_dict`, `estimate_to_dict` / `estimate_from_dict`, `health_to_dict`.
`gcs_monitor/sinks/payload_spec.py` declares every key below and `validate(payload)` checks a
payload against it.

Every payload has these two keys:

- `schema_version` (int). This is bumped on any incompatible change, such as a renamed or retyped
  key or a key whose meaning changed. Adding a key alone is a compatible change and keeps the
  version. Readers reject a newer version than they know. Version 2: `fault_type` is the type
  decided at the raise and held by the label hysteresis (below), where version 1 gave the latest
  re-classification, and the alarm carries its `confidence`. Version 1 payloads are still read
  (`confidence` comes back as NaN). Added since, compatibly: `alarm_id` and `monitor` on alarms;
  the health payload holds one vehicle's health.
- `type`. One of `"alarm"`, `"estimate"` or `"health"`.

All values are in SI units and radians. JSON has no NaN, so a non-finite number (unknown
magnitude, infinite age) is written as `null`.

## Key expressions (Zenoh)

These come from `gcs_monitor.sinks.zenoh_sink.keyexpr(vehicle, topic, name=None)` and
`gcs_monitor.link.zenoh_bus.raw_key`:

| key expression | what | rate |
|---|---|---|
| `gcs/<vehicle>/alarm` | one `alarm` payload per AlarmEvent transition (raised / updated / cleared); an advanced publisher that keeps the vehicle's last 256 alarms | on each event |
| `gcs/<vehicle>/estimate/<name>` | one `estimate` payload per estimator (`imu_ts`, `airdata`, ...) | decimated, 5 Hz default |
| `gcs/<vehicle>/health` | **queryable**: answers `get()` with the vehicle's latest `health` payload | on request |
| `mavlink/<vehicle>/rx` | raw MAVLink frames of one vehicle (`gcs-monitor bridge` publishes, `worker` and the `zenoh:` source read) | batched, 20 ms at most (`--flush-ms`) |
| `gcs/fleet/<group>/worker/<id>` | liveliness token of a fleet worker | while it lives |
| `gcs/fleet/<group>/status/<id>` | a worker's status (JSON: vehicles owned, vehicle time reached, active alarms); also a queryable | 2 Hz |

`<vehicle>` is the MAVLink system id. Subscribe with wildcards, for example `gcs/*/alarm` (all
vehicles) or `gcs/3/estimate/*`.

Zenoh runs with multicast and gossip scouting off and explicit endpoints; every listen endpoint
defaults to loopback (`tcp/127.0.0.1:7447`). `--zenoh-config FILE` (Zenoh's JSON5) adds TLS and
access control; `--zenoh-ca/--zenoh-cert/--zenoh-key` set TLS from the command line. See
docs/architecture.md, *Fleet*, for routers and a site with `zenohd`.

**No alarm lost.** The alarm publisher keeps the last 256 alarms of its vehicle and sends
sequence-number heartbeats; a subscriber opened with `subscribe_alarms` (or `gcs-monitor alarms`)
gets that history when it starts or when a publisher appears (a restarted monitor, a worker that
took the vehicle over), recovers what it missed during a pause or a disconnection, and reports
what it could not recover (`!! missed N alarms from publisher ...`). A line that arrives late says
so (`(caught up: published 42.0 s earlier)`). Query `gcs/<vehicle>/health` for the active
alarms.

```python
from gcs_monitor.sinks.zenoh_sink import run_alarm_printer, subscribe_alarms
run_alarm_printer("gcs/*/alarm", ["tcp/127.0.0.1:7447"])          # what `gcs-monitor alarms` runs
with subscribe_alarms("gcs/1/alarm", connect=["tcp/127.0.0.1:7447"]) as sub:
    payload = sub.get(timeout=5.0)                               # dict or None
```
"""  # noqa: E501 - Markdown table rows

ALARM_PROSE = """### Alarm ids

`alarm_id` is `<vehicle>/<channel>/<raise time>` (for example `1/aoa1/20150000`: vehicle 1, vane 1,
raised at 20.15 s of vehicle time). It is the same on every transition of one alarm, and the same
bytes give the same ids. A monitor that starts over keeps the ids of the alarms it inherits:

- **fleet takeover**: the worker that takes a vehicle over inherits the alarms the previous owner
  published as active; it does not publish again what the previous owner published (events up
  to the previous owner's last vehicle time, the *watermark*); a raise of an inherited alarm's
  channel is published as `updated` with the inherited id (no duplicate raise); an inherited
  alarm not confirmed within the grace time (20 s of vehicle time) is cleared with a message that
  says so;
- **restart**: a monitor that finds active alarms in its journal inherits them the same way, and
  the journal never writes a transition twice;
- **autopilot reboot**: the rebuilt families must confirm the active alarms the same way.

The health payload's `handover` says what happened (inherited, confirmed, cleared, suppressed).

### Link alarms

`kind` `link` alarms use `axis` = `loss` (packet loss from sequence gaps over the last
`link.loss_window_s`, 10 s; raised above 5 %, cleared below 2 %; bursts longer than the 8-bit
sequence are bounded by the sender's clock), `crc` (CRC/parse errors; cleared 5 s of vehicle time
after the last one), `stale` (no data), `reboot` (vehicle clock restarted; cleared 5 s into the new
clock), `duplicate_sysid` (two senders share the system id; cleared once only one is heard),
`signature` (packets claiming this vehicle rejected by MAVLink 2 signing: unsigned while signing
is required, a wrong key, or replayed; cleared 5 s after the last one). Every link alarm clears
when its condition ends; the holds run on the new clock after a reboot. Rejected packets never
reach the families.

`fault_type` `no_data`: an AoA/CAS instance has delivered no valid value for
`fdi.<set>.no_data_window_s` while a peer does (silent, or out of range at the MAVLink boundary).

### Fault type and confidence

`gcs_monitor/fdi/classify.py` classifies the residual window of a channel (`fdi.<set>.history_s`)
when its alarm is raised and every `reclassify_s` while it is active. It fits each fault's model
— a step (bias), a level followed by a ramp or a ramp followed by a level (drift or runaway, by
the rate; a runaway that reached its limit stays a ramp), a sinusoid on the better of these
(oscillation; it must be periodic and carry most of the fault's power, so a ripple on a bias is
no oscillation) — and decides in a fixed order. Each test taken on the way has a margin,
`|ln(statistic / threshold)| / ln(classifier.certain_ratio)` capped at 1; the confidence is the
smallest, so a step that fits barely better than a ramp, or a drift near the runaway rate, says
so. For a classified type the confidence is that margin; 1 for an observed type (`link`,
`no_data`, and `stuck` raised by the frozen-signal check); 0 for `unknown`; null only in a
version 1 payload.

The type is **decided at the raise** and changed only on **decisive evidence**: a different type
must win every re-classification over `classifier.relabel_windows` windows of new data (with the
default 10 s windows re-classified every 2.5 s: 5 in a row), each one decisively — the held
type's model leaves at least `classifier.relabel_fit_ratio` times the squared residual of the
new type's model on the same window; between drift and runaway the window must show a ramp whose
rate is `classifier.relabel_rate_ratio` beyond the runaway rate. A window that disagrees without
being decisive restarts the count; while a rival is winning, the reported confidence falls in
proportion. So a bias with one oscillation-looking window stays a bias, a drift that accelerates
past the runaway rate becomes a runaway once, and a runaway at its limit (a level the ramp
explains as well as a step) stays a runaway. `no_data` is an observation and is taken at once.
A new raise of a channel (after a clear) decides afresh.

An `estimator` event on channel `estimator0.<name>` (e.g. `estimator0.imu_ts`) is a notice, never
a fault: the IMU estimator re-anchored its states (a GPS velocity or attitude step the IMU cannot
explain, or an input gap; `gcs_monitor/families/imu/gating.py`) and keeps its fault estimates; it
is `raised` when fault channels that were being judged stop being judged (`message` says why and
for how long) and `cleared` when they are judged again. Metrics never count it.

Vehicle time (`t_us`) is what makes a replay deterministic. Two replays of a tlog give the same
alarms with the same `t_us` and `alarm_id`, and only `wall_time*` differs.
"""

ESTIMATE_PROSE = """Each state name carries its frame and unit (`vel_ned_mps`, `euler_rad`,
`wind_ned_mps`), and vectors are lists. `faults` holds the reconstructed faults, `residuals` the
measurement minus the prediction, and `virtual` the corrected (virtual-sensor) values. All three
are per channel, in SI units. When `available` is false, `reason` says which input was missing.
"""

HEALTH_PROSE = """`gcs/<vehicle>/health` answers with one vehicle's health: exactly what
`Monitor.vehicle_health(sysid)` returns (and what `Monitor.health()["vehicles"]` holds per vehicle),
converted to JSON (numpy arrays become lists, NaN and inf `null`). A fleet worker adds `fleet`.
The `link` object is the vehicle's sender statistics; `link_wide` the counters that belong to no
sender (garbage, signing rejections of unknown senders, kernel and queue drops).
"""

JOURNAL_PROSE = """## Alarm journal

`gcs_monitor.sinks.journal.AlarmJournal(path, fsync=False, monitor="")` appends one alarm payload
per line in the format above. Each line is flushed to the OS as soon as it is written, so a
crashed monitor loses no alarm. With `fsync=True` a line also survives a power loss.

Opening a journal repairs what a crash left: a torn last line is moved aside to `<journal>.torn`
(with the time and offset it was found at), the journal is cut back to its last complete line
(atomically), `AlarmJournal.repair` says what was done and `gcs-monitor` prints it; appends then
start on a fresh line. A line an older monitor appended onto a torn fragment is split the same
way. A transition already in the journal (same `alarm_id`, `state`, `t_us`) is not written again,
and `AlarmJournal.active_alarms()` gives the alarms still active, which a restarted monitor
inherits. `read_journal(path)` returns the AlarmEvents; it skips a torn last line and raises on a
corrupt earlier line.

## Rerun entity paths

These come from `gcs_monitor.sinks.rerun_sink.entity_path`. The recording has one stream per
vehicle, the application id `gcs_monitor`, and the timeline `vehicle_time`.

```
/<v>/sets/<set>/measured/<i> | fused | reference | rms/<i> | threshold | weight/<i>
/<v>/channels/<kind>/<instance>[/<axis>]/value | rms | threshold | measured | corrected | fault/<estimator> | true_fault
/<v>/estimates/<estimator>/<state>
/<v>/alarms            TextLog: raised/updated = WARN (ERROR for set_lost), cleared = INFO
/<v>/health            TextDocument (latest health payload)
/<v>/world/track, /<v>/world/vehicle/{body,axes}   local NED (right-handed, z down), attitude quaternion
```

The blueprint (`dashboards/blueprints.py`) is built from the dashboards the enabled families
declare (`FamilyViews` in `gcs_monitor/families/<family>/views.py`): an overview tab with every
family's overview plots and one tab per family, plus the 3-D track/attitude view and the alarm
log. `default_blueprint(vehicle, family_views(cfg))` is embedded in each `.rrd` the monitor
writes. The web viewer (`--web`) listens on 127.0.0.1 unless `--web-bind` says otherwise.

![dashboard](img/dashboard.png)
"""  # noqa: E501 - the entity-path listing


def alarms_markdown() -> str:
    """docs/alarms.md, generated from the schema above."""
    parts = [
        PAGE_HEAD,
        "## Alarm\n",
        "An example: a bias on AoA vane 2, isolated by the voting stage.\n",
        "```json\n" + json.dumps(example_alarm(), indent=2, ensure_ascii=False) + "\n```\n",
        table(ALARM) + "\n",
        ALARM_PROSE,
        "## Estimate\n",
        table(ESTIMATE) + "\n",
        ESTIMATE_PROSE,
        "## Health\n",
        HEALTH_PROSE,
        table(HEALTH) + "\n",
        JOURNAL_PROSE,
    ]
    return "\n".join(parts)


def _main(argv: Sequence[str]) -> int:
    sys.stdout.write(alarms_markdown())
    return 0


if __name__ == "__main__":
    raise SystemExit(_main(sys.argv[1:]))


__all__ = ["ALARM", "ESTIMATE", "F", "HEALTH", "ListOf", "MapOf", "Obj", "PAYLOADS",
           "alarms_markdown", "field", "table", "validate"]
