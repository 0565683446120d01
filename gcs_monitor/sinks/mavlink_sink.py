"""Alarms into the operator's ground station: every raise and clear as MAVLink ``STATUSTEXT``.

QGroundControl, Mission Planner and MAVProxy show a vehicle's STATUSTEXT messages in their
message panes; sent with the vehicle's system id and the monitor's own component id
(``MAV_COMP_ID_ONBOARD_COMPUTER`` = 191 by default, as a companion computer would), the
monitor's alarms appear there next to the autopilot's own messages, each line starting with
``FDI``. ``sysid`` may be set instead (255 is a GCS's id; QGroundControl shows only messages of
system ids it has seen a vehicle HEARTBEAT from).

Severity (MAV_SEVERITY): ``actuator_fault`` ALERT, ``set_lost`` CRITICAL, ``sensor_fault`` and
``link`` WARNING, ``monitor_degraded`` and ``estimator`` NOTICE, any clear INFO. Updates of an
active alarm are not sent. Texts longer than the 50 characters of one STATUSTEXT go as
MAVLink 2 chunks: the same non-zero ``id``, ``chunk_seq`` 0, 1, ..., the last chunk shorter
than 50 (an empty one when the text fills the chunks exactly).

Optionally (``named_values``) the fused value of each redundant set goes out as
``NAMED_VALUE_FLOAT`` (``<set>_fused``, SI) at ``value_rate_hz``.

The sink never blocks the pipeline: ``publish`` only formats and appends to a bounded queue
(oldest dropped and counted when full); a thread sends. URLs: ``udpout:HOST:PORT`` (or
``udp:``) and ``tcp:HOST:PORT``.
"""

from __future__ import annotations

import collections
import itertools
import logging
import math
import socket
import threading
from typing import Any

from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState
from gcs_monitor.fdi.records import StepOutput
from gcs_monitor.link.mav import mavlink
from gcs_monitor.telemetry.frame import Frame

log = logging.getLogger(__name__)

COMPID_DEFAULT = mavlink.MAV_COMP_ID_ONBOARD_COMPUTER  # 191
STATUSTEXT_LEN = 50
PREFIX = "FDI"
SEVERITY: dict[AlarmKind, int] = {
    AlarmKind.ACTUATOR_FAULT: mavlink.MAV_SEVERITY_ALERT,
    AlarmKind.SET_LOST: mavlink.MAV_SEVERITY_CRITICAL,
    AlarmKind.SENSOR_FAULT: mavlink.MAV_SEVERITY_WARNING,
    AlarmKind.LINK: mavlink.MAV_SEVERITY_WARNING,
    AlarmKind.MONITOR_DEGRADED: mavlink.MAV_SEVERITY_NOTICE,
    AlarmKind.ESTIMATOR: mavlink.MAV_SEVERITY_NOTICE,
}
CLEARED_SEVERITY: int = mavlink.MAV_SEVERITY_INFO
DEFAULT_SEVERITY: int = mavlink.MAV_SEVERITY_WARNING
DEFAULT_QUEUE = 1000


def severity(ev: AlarmEvent) -> int:
    """MAV_SEVERITY of an alarm transition (module docstring)."""
    if ev.state == AlarmState.CLEARED:
        return CLEARED_SEVERITY
    return SEVERITY.get(ev.kind, DEFAULT_SEVERITY)


def channel_name(ev: AlarmEvent) -> str:
    ch = ev.channel
    if ch.instance < 0:
        return f"{ch.kind}[set]"
    return f"{ch.kind}{ch.instance}{'.' + ch.axis if ch.axis else ''}"


def alarm_text(ev: AlarmEvent) -> str:
    """The operator's line: ``FDI raised acc0.z sensor_fault bias +1.86 (imu_ts)``."""
    mag = f" {ev.magnitude:+.3g}" if math.isfinite(ev.magnitude) else ""
    fault = "" if ev.fault_type.value == "unknown" else f" {ev.fault_type.value}"
    text = (f"{PREFIX} {ev.state.value} {channel_name(ev)} {ev.kind.value}{fault}{mag} "
            f"({ev.estimator})")
    if ev.message:
        text += f": {ev.message}"
    return text


def chunks(text: str, chunk_id: int) -> list[tuple[int, bytes, int]]:
    """(id, text bytes, chunk_seq) of each STATUSTEXT carrying ``text`` (MAVLink 2 chunking)."""
    raw = text.encode("utf-8", errors="replace")
    if len(raw) <= STATUSTEXT_LEN:
        return [(0, raw, 0)]
    parts = [raw[i:i + STATUSTEXT_LEN] for i in range(0, len(raw), STATUSTEXT_LEN)]
    if len(parts[-1]) == STATUSTEXT_LEN:
        parts.append(b"")  # the receiver knows the text ended from a short chunk
    return [(chunk_id, p, k) for k, p in enumerate(parts)]


class MavlinkAlarmSink:
    """Alarm transitions as STATUSTEXT to a ground station (see the module docstring).

    Parameters
    ----------
    url : ``udpout:HOST:PORT`` / ``udp:HOST:PORT`` or ``tcp:HOST:PORT``
    vehicle : the monitored vehicle's sysid (sent as the source system unless ``sysid``)
    sysid : source system id to send as instead of the vehicle's
    compid : source component id (default 191, MAV_COMP_ID_ONBOARD_COMPUTER)
    named_values : also send each set's fused value as NAMED_VALUE_FLOAT
    value_rate_hz : rate of those values (vehicle time)
    queue_size : messages held for the sender thread at most (oldest dropped, counted)
    """

    _ids = itertools.count(1)

    def __init__(self, url: str, *, vehicle: int = 1, sysid: int | None = None,
                 compid: int = COMPID_DEFAULT, named_values: bool = False,
                 value_rate_hz: float = 2.0, queue_size: int = DEFAULT_QUEUE) -> None:
        scheme, _, rest = url.partition(":")
        host, _, port_s = rest.rpartition(":")
        if scheme not in ("udpout", "udp", "tcp") or not host or not port_s.isdigit():
            raise ValueError(f"--mavlink-alarms {url!r}: expected udpout:HOST:PORT or "
                             "tcp:HOST:PORT")
        self.url = url
        self._addr = (host, int(port_s))
        self._tcp = scheme == "tcp"
        self._mav = mavlink.MAVLink(None, srcSystem=sysid if sysid is not None else vehicle,
                                    srcComponent=compid)
        self.named_values = named_values
        self._value_period_us = int(1e6 / value_rate_hz) if value_rate_hz > 0 else 0
        self._next_value_us = 0
        self._q: collections.deque[bytes] = collections.deque()
        self._max = queue_size
        self._cv = threading.Condition()
        self._closed = False
        self.n_published = 0
        self.n_dropped = 0
        self.n_errors = 0
        self.active = True
        self._sock: socket.socket | None = None
        self._thread = threading.Thread(target=self._run, daemon=True,
                                        name=f"mavlink-alarms-{vehicle}")
        self._thread.start()

    # -- pipeline side (never blocks) -----------------------------------------------------------
    def publish(self, frame: Frame, out: StepOutput) -> None:
        for ev in out.events:
            if ev.state == AlarmState.UPDATED:
                continue
            self.send_text(alarm_text(ev), severity(ev))
        if self.named_values and out.sets and frame.t_us >= self._next_value_us:
            self._next_value_us = frame.t_us + self._value_period_us
            for s in out.sets:
                if math.isfinite(s.fused):
                    name = f"{s.name}_fused"[:10].encode()
                    msg = mavlink.MAVLink_named_value_float_message(
                        (frame.t_us // 1000) & 0xFFFFFFFF, name, float(s.fused))
                    self._put(bytes(msg.pack(self._mav)))

    def send_text(self, text: str, sev: int) -> None:
        """One text as STATUSTEXT (chunked when longer than 50 characters)."""
        cid = next(self._ids) % 65535 or 1
        for chunk_id, part, seq in chunks(text, cid):
            msg = mavlink.MAVLink_statustext_message(sev, part, chunk_id, seq)
            self._put(bytes(msg.pack(self._mav)))

    def _put(self, packet: bytes) -> None:
        with self._cv:
            self._q.append(packet)
            while len(self._q) > self._max:
                self._q.popleft()
                self.n_dropped += 1
            self._cv.notify()

    def update_health(self, health: dict[str, Any]) -> None:
        pass

    # -- sender thread ---------------------------------------------------------------------------
    def _connect(self) -> socket.socket | None:
        try:
            if self._tcp:
                return socket.create_connection(self._addr, timeout=2.0)
            return socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        except OSError as exc:
            self.n_errors += 1
            log.warning("mavlink alarms: cannot connect to %s: %s", self.url, exc)
            return None

    def _run(self) -> None:
        while True:
            with self._cv:
                while not self._q and not self._closed:
                    self._cv.wait(0.5)
                if not self._q and self._closed:
                    return
                batch = list(self._q)
                self._q.clear()
            sock = self._sock
            if sock is None:
                sock = self._sock = self._connect()
                if sock is None:
                    self.n_dropped += len(batch)
                    continue
            for i, packet in enumerate(batch):
                try:
                    if self._tcp:
                        sock.sendall(packet)
                    else:
                        sock.sendto(packet, self._addr)
                    self.n_published += 1
                except OSError:
                    self.n_errors += 1
                    self.n_dropped += 1
                    if self._tcp:  # the connection is gone: drop the rest of the batch,
                        sock.close()  # reconnect for the next one
                        self._sock = None
                        self.n_dropped += len(batch) - i - 1
                        break

    def close(self) -> None:
        with self._cv:
            if self._closed:
                return
            self._closed = True
            self._cv.notify()
        self._thread.join(timeout=2.0)
        if self._sock is not None:
            self._sock.close()
