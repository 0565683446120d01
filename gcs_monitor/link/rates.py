"""Ask an autopilot for the message rates the families need, as ground stations do.

``MAV_CMD_SET_MESSAGE_INTERVAL`` (COMMAND_LONG, param1 = message id, param2 = interval µs) per
message; a message the autopilot does not ACCEPT within ``ack_timeout_s`` (or no COMMAND_ACK
at all: old firmware) falls back to ``REQUEST_DATA_STREAM`` for the stream group that carries
it (ArduPilot's SRx_ groups: RAW_SENSORS, EXTRA1, EXTRA2, EXTRA3, POSITION, RC_CHANNELS). After
``measure_s`` the measured rate of every requested message is reported (counted from the
first request on), so the operator sees what the vehicle actually sends.

Pure bookkeeping: the caller passes wall time and a ``write(bytes)`` of the link.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from gcs_monitor.link.mav import mavlink

GCS_SYSID = 255
GCS_COMPID = 190  # MAV_COMP_ID_MISSIONPLANNER, what ground stations send as

# message -> rate the families need (Hz): the contract's default rates (docs/telemetry.md)
FAMILY_RATES_HZ: dict[str, float] = {
    "HIGHRES_IMU": 50.0, "RAW_IMU": 50.0, "SCALED_IMU2": 50.0, "ATTITUDE": 50.0,
    "GLOBAL_POSITION_INT": 10.0, "GPS_RAW_INT": 5.0, "VFR_HUD": 20.0, "AIRSPEED": 20.0,
    "AOA_SSA": 20.0, "SCALED_PRESSURE": 10.0, "SERVO_OUTPUT_RAW": 10.0,
    "NAV_CONTROLLER_OUTPUT": 10.0, "ATTITUDE_TARGET": 10.0,
}
# the REQUEST_DATA_STREAM group carrying each message (ArduPilot GCS_Common stream lists)
STREAM_OF = {
    "RAW_IMU": mavlink.MAV_DATA_STREAM_RAW_SENSORS,
    "SCALED_IMU2": mavlink.MAV_DATA_STREAM_RAW_SENSORS,
    "SCALED_PRESSURE": mavlink.MAV_DATA_STREAM_RAW_SENSORS,
    "HIGHRES_IMU": mavlink.MAV_DATA_STREAM_RAW_SENSORS,
    "ATTITUDE": mavlink.MAV_DATA_STREAM_EXTRA1,
    "VFR_HUD": mavlink.MAV_DATA_STREAM_EXTRA2,
    "AIRSPEED": mavlink.MAV_DATA_STREAM_EXTRA3,
    "AOA_SSA": mavlink.MAV_DATA_STREAM_EXTRA3,
    "GLOBAL_POSITION_INT": mavlink.MAV_DATA_STREAM_POSITION,
    "GPS_RAW_INT": mavlink.MAV_DATA_STREAM_EXTENDED_STATUS,
    "NAV_CONTROLLER_OUTPUT": mavlink.MAV_DATA_STREAM_EXTENDED_STATUS,
    "SERVO_OUTPUT_RAW": mavlink.MAV_DATA_STREAM_RC_CHANNELS,
    "ATTITUDE_TARGET": mavlink.MAV_DATA_STREAM_EXTRA1,
}


def message_id(name: str) -> int:
    return int(getattr(mavlink, f"MAVLINK_MSG_ID_{name}"))


@dataclass
class RateResult:
    """One message: what was asked, how the autopilot answered, what arrived."""

    name: str
    requested_hz: float
    ack: str = "no answer"  # ACCEPTED, UNSUPPORTED, DENIED, ... or "no answer"
    fallback_stream: str = ""  # the REQUEST_DATA_STREAM group used instead
    count: int = 0
    measured_hz: float = 0.0


@dataclass
class RateRequester:
    """The request state machine (module docstring); feed it messages and wall time."""

    write: Callable[[bytes], None]
    rates_hz: dict[str, float] = field(default_factory=lambda: dict(FAMILY_RATES_HZ))
    ack_timeout_s: float = 1.5
    measure_s: float = 5.0
    target: tuple[int, int] | None = None
    results: dict[str, RateResult] = field(default_factory=dict)
    t_request: float | None = None
    done: bool = False
    _fallback_sent: bool = False
    _by_id: dict[int, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self._mav = mavlink.MAVLink(None, srcSystem=GCS_SYSID, srcComponent=GCS_COMPID)
        self.results = {n: RateResult(n, hz) for n, hz in self.rates_hz.items()}
        self._by_id = {message_id(n): n for n in self.rates_hz}

    def _send(self, msg: Any) -> None:
        self.write(bytes(msg.pack(self._mav)))

    def on_message(self, m: Any) -> None:
        """Every decoded message of the link (any sender)."""
        typ = m.get_type()
        if self.target is None:
            if typ == "HEARTBEAT" and m.type != mavlink.MAV_TYPE_GCS and \
                    m.autopilot != mavlink.MAV_AUTOPILOT_INVALID:
                self.target = (m.get_srcSystem(), m.get_srcComponent())
            return
        if m.get_srcSystem() != self.target[0]:
            return
        if typ == "COMMAND_ACK" and m.command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL:
            # the ACK does not say which message: take the oldest one still unanswered
            for r in self.results.values():
                if r.ack == "pending":
                    r.ack = mavlink.enums["MAV_RESULT"][m.result].name.removeprefix(
                        "MAV_RESULT_")
                    break
            return
        res = self.results.get(typ)
        if res is not None and self.t_request is not None and not self.done:
            res.count += 1

    def poll(self, now_s: float) -> list[RateResult] | None:
        """Send what is due; return the results once measured (once)."""
        if self.target is None or self.done:
            return None
        if self.t_request is None:
            self.t_request = now_s
            sysid, compid = self.target
            for name, hz in self.rates_hz.items():
                self.results[name].ack = "pending"
                self._send(mavlink.MAVLink_command_long_message(
                    sysid, compid, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                    message_id(name), 1e6 / hz, 0, 0, 0, 0, 0))
            return None
        if not self._fallback_sent and now_s - self.t_request >= self.ack_timeout_s:
            self._fallback_sent = True
            streams: dict[int, float] = {}
            for r in self.results.values():
                if r.ack != "ACCEPTED" and r.name in STREAM_OF:
                    s = STREAM_OF[r.name]
                    streams[s] = max(streams.get(s, 0.0), r.requested_hz)
                    r.fallback_stream = mavlink.enums["MAV_DATA_STREAM"][s].name.removeprefix(
                        "MAV_DATA_STREAM_")
                if r.ack == "pending":
                    r.ack = "no answer"
            sysid, compid = self.target
            for s, hz in streams.items():
                self._send(mavlink.MAVLink_request_data_stream_message(
                    sysid, compid, s, int(round(hz)), 1))
            return None
        if now_s - self.t_request >= self.measure_s:
            span = now_s - self.t_request
            for r in self.results.values():
                r.measured_hz = r.count / span if span > 0 else 0.0
            self.done = True
            return list(self.results.values())
        return None


def rates_table(results: list[RateResult]) -> str:
    """The operator's table of requested and measured rates."""
    lines = [f"{'message':24s} {'asked':>6s} {'answer':12s} {'fallback':14s} {'got':>7s}"]
    for r in results:
        lines.append(f"{r.name:24s} {r.requested_hz:5.0f}  {r.ack:12s} "
                     f"{r.fallback_stream or '-':14s} {r.measured_hz:6.1f} Hz")
    return "\n".join(lines)
