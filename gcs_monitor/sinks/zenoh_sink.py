"""Zenoh sink: alarm stream, decimated estimates and a health queryable per vehicle.

Key expressions come from :func:`keyexpr` only:

- ``gcs/<vehicle>/alarm``             one JSON object per AlarmEvent transition
- ``gcs/<vehicle>/estimate/<name>``   decimated estimates (``estimate_rate_hz``, 5 Hz default)
- ``gcs/<vehicle>/health``            queryable answering the latest health dict

Peer mode, multicast and gossip scouting off, explicit endpoints (stack-notes section 3).
The live path never waits on the network: ``publish`` serialises to JSON and hands the payload to
a bounded queue drained by one worker thread that owns the ``put`` calls; a full queue drops the
payload and counts it (``n_dropped``). Session errors (a port in use, an address that cannot be
bound) are logged and counted (``n_errors``); the sink then drops everything instead of raising.
An unreachable ``connect`` endpoint only delays opening by ~0.5 s: zenoh retries in the
background.

Pitfall: the process hangs at exit if a session with a callback queryable/subscriber is not
closed, so :meth:`ZenohSink.close` always closes it and is also registered with ``atexit``.
"""

from __future__ import annotations

import atexit
import json
import logging
import queue
import sys
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from typing import Any, TextIO

import zenoh

from gcs_monitor.fdi.records import StepOutput
from gcs_monitor.sinks.schema import (
    alarm_to_dict,
    dumps,
    estimate_to_dict,
    health_to_dict,
)
from gcs_monitor.telemetry.frame import Frame

log = logging.getLogger(__name__)

KEY_PREFIX = "gcs"
DEFAULT_LISTEN = ("tcp/127.0.0.1:7447",)
US_PER_S = 1_000_000
_STOP = object()


def keyexpr(
    vehicle: int | str, topic: str, name: str | None = None, *, prefix: str = KEY_PREFIX
) -> str:
    """The one builder of key expressions: ``gcs/<vehicle>/<topic>[/<name>]``.

    ``vehicle`` may be ``"*"`` to build subscription wildcards (``gcs/*/alarm``).
    """
    if topic not in ("alarm", "estimate", "health"):
        raise ValueError(f"unknown topic {topic!r}")
    key = f"{prefix}/{vehicle}/{topic}"
    return f"{key}/{name}" if name else key


def make_config(listen: Iterable[str] = (), connect: Iterable[str] = ()) -> zenoh.Config:
    """Peer-mode config with scouting off and explicit endpoints (stack-notes section 3)."""
    c = zenoh.Config()
    c.insert_json5("mode", '"peer"')
    c.insert_json5("scouting/multicast/enabled", "false")
    c.insert_json5("scouting/gossip/enabled", "false")
    c.insert_json5("listen/endpoints", json.dumps(list(listen)))
    c.insert_json5("connect/endpoints", json.dumps(list(connect)))
    return c


class ZenohSink:
    """Zenoh output for one vehicle (Sink protocol).

    Parameters
    ----------
    vehicle : MAVLink system id
    listen, connect : zenoh endpoints (``tcp/127.0.0.1:7447`` listen by default)
    estimate_rate_hz : publication rate of each estimate (vehicle time)
    queue_size : bounded hand-off queue between ``publish`` and the network thread
    prefix : first key segment (``gcs``)
    """

    def __init__(
        self,
        vehicle: int,
        *,
        listen: Sequence[str] = DEFAULT_LISTEN,
        connect: Sequence[str] = (),
        estimate_rate_hz: float = 5.0,
        queue_size: int = 1024,
        prefix: str = KEY_PREFIX,
    ) -> None:
        if estimate_rate_hz <= 0:
            raise ValueError("estimate_rate_hz must be > 0")
        self.vehicle = int(vehicle)
        self.prefix = prefix
        self.alarm_key = keyexpr(self.vehicle, "alarm", prefix=prefix)
        self.health_key = keyexpr(self.vehicle, "health", prefix=prefix)
        self._estimate_period_us = round(US_PER_S / estimate_rate_hz)
        self._last_estimate_us: dict[str, int] = {}
        self._lock = threading.Lock()
        self._health_json = dumps(health_to_dict({}, vehicle=self.vehicle, wall_time_s=time.time()))
        self._queue: queue.Queue[Any] = queue.Queue(maxsize=queue_size)
        self.n_published = 0
        self.n_dropped = 0
        self.n_errors = 0
        self.n_health_queries = 0
        self._closed = False
        self._session: zenoh.Session | None = None
        self._publishers: dict[str, zenoh.Publisher] = {}
        self._queryable: zenoh.Queryable[Any] | None = None
        try:
            self._session = zenoh.open(make_config(listen, connect))
            self._publishers[self.alarm_key] = self._session.declare_publisher(
                self.alarm_key,
                encoding=zenoh.Encoding.APPLICATION_JSON,
                # Alarms must arrive: the worker thread may wait for the network, the live path not.
                congestion_control=zenoh.CongestionControl.BLOCK,
                reliability=zenoh.Reliability.RELIABLE,
            )
            self._queryable = self._session.declare_queryable(
                self.health_key, self._on_health_query
            )
        except zenoh.ZError:
            self.n_errors += 1
            log.exception("zenoh sink for vehicle %d disabled: session failed", self.vehicle)
            self._close_session()
        self._worker = threading.Thread(
            target=self._run, name=f"zenoh-sink-{self.vehicle}", daemon=True
        )
        self._worker.start()
        atexit.register(self.close)

    @property
    def active(self) -> bool:
        """True while the session is open."""
        return self._session is not None and not self._closed

    # ----------------------------------------------------------------- Sink protocol
    def publish(self, frame: Frame, out: StepOutput) -> None:
        estimates, events = out.estimates, out.events
        if self._closed:
            return
        wall = time.time() if (events or estimates) else 0.0
        for ev in events:
            self._enqueue(self.alarm_key, dumps(alarm_to_dict(ev, wall_time_s=wall)))
        t_us = int(frame.t_us)
        for est in estimates:
            last = self._last_estimate_us.get(est.name)
            if last is not None and 0 <= t_us - last < self._estimate_period_us:
                continue
            self._last_estimate_us[est.name] = t_us
            key = keyexpr(self.vehicle, "estimate", est.name, prefix=self.prefix)
            self._enqueue(key, dumps(estimate_to_dict(est, vehicle=self.vehicle, wall_time_s=wall)))

    def update_health(self, health: dict[str, Any]) -> None:
        payload = dumps(health_to_dict(health, vehicle=self.vehicle, wall_time_s=time.time()))
        with self._lock:
            self._health_json = payload

    def close(self) -> None:
        """Drain the queue (bounded wait), close the session; idempotent."""
        if self._closed:
            return
        self._closed = True
        atexit.unregister(self.close)
        try:
            self._queue.put(_STOP, timeout=1.0)
        except queue.Full:
            pass
        self._worker.join(timeout=2.0)
        self._close_session()

    def __enter__(self) -> ZenohSink:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ----------------------------------------------------------------- internals
    def _enqueue(self, key: str, payload: str) -> None:
        if self._session is None:
            self.n_dropped += 1
            return
        try:
            self._queue.put_nowait((key, payload))
        except queue.Full:
            self.n_dropped += 1

    def _run(self) -> None:
        while True:
            item = self._queue.get()
            if item is _STOP:
                return
            key, payload = item
            session = self._session
            if session is None:
                self.n_dropped += 1
                continue
            try:
                pub = self._publishers.get(key)
                if pub is None:
                    pub = self._publishers[key] = session.declare_publisher(
                        key,
                        encoding=zenoh.Encoding.APPLICATION_JSON,
                        congestion_control=zenoh.CongestionControl.DROP,
                    )
                pub.put(payload)
                self.n_published += 1
            except zenoh.ZError:
                self.n_errors += 1
                log.warning("zenoh put on %s failed", key, exc_info=True)

    def _on_health_query(self, query: zenoh.Query) -> None:
        # Runs on a zenoh thread.
        with self._lock:
            payload = self._health_json
            self.n_health_queries += 1
        try:
            query.reply(self.health_key, payload, encoding=zenoh.Encoding.APPLICATION_JSON)
        except zenoh.ZError:
            self.n_errors += 1

    def _close_session(self) -> None:
        s, self._session = self._session, None
        if s is None:
            return
        try:
            if self._queryable is not None:
                self._queryable.undeclare()
            for p in self._publishers.values():
                p.undeclare()
        except zenoh.ZError:
            self.n_errors += 1
        finally:
            self._queryable = None
            self._publishers.clear()
            s.close()


# --------------------------------------------------------------------- consumer side
class AlarmSubscriber:
    """Receives alarm payloads (dicts) on a key expression; use as a context manager.

    Parameters
    ----------
    keyexpr : e.g. ``gcs/*/alarm`` or ``gcs/1/alarm``
    connect, listen : zenoh endpoints
    callback : called with each decoded payload on a zenoh thread; when None, payloads are
        queued and read with :meth:`get`
    """

    def __init__(
        self,
        keyexpr: str = "gcs/*/alarm",
        *,
        connect: Sequence[str] = ("tcp/127.0.0.1:7447",),
        listen: Sequence[str] = (),
        callback: Callable[[dict[str, Any]], None] | None = None,
        queue_size: int = 4096,
    ) -> None:
        self.keyexpr = keyexpr
        self._queue: queue.Queue[dict[str, Any]] = queue.Queue(maxsize=queue_size)
        self._callback = callback
        self.n_received = 0
        self.n_bad = 0
        self.n_dropped = 0
        self._closed = False
        self._session = zenoh.open(make_config(listen, connect))
        try:
            self._sub = self._session.declare_subscriber(keyexpr, self._on_sample)
        except BaseException:
            self._session.close()
            raise
        atexit.register(self.close)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        try:
            d = json.loads(sample.payload.to_string())
        except (ValueError, UnicodeDecodeError):
            self.n_bad += 1
            return
        self.n_received += 1
        if self._callback is not None:
            self._callback(d)
            return
        try:
            self._queue.put_nowait(d)
        except queue.Full:
            self.n_dropped += 1

    def get(self, timeout: float | None = None) -> dict[str, Any] | None:
        """Next queued alarm payload, or None after ``timeout`` seconds."""
        try:
            return self._queue.get(timeout=timeout)
        except queue.Empty:
            return None

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        atexit.unregister(self.close)
        try:
            self._sub.undeclare()
        finally:
            self._session.close()

    def __enter__(self) -> AlarmSubscriber:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def subscribe_alarms(
    keyexpr: str = "gcs/*/alarm",
    *,
    connect: Sequence[str] = ("tcp/127.0.0.1:7447",),
    listen: Sequence[str] = (),
    callback: Callable[[dict[str, Any]], None] | None = None,
) -> AlarmSubscriber:
    """Open an :class:`AlarmSubscriber` (close it, or use it in a ``with`` block)."""
    return AlarmSubscriber(keyexpr, connect=connect, listen=listen, callback=callback)


def format_alarm(d: dict[str, Any]) -> str:
    """One human-readable line for an alarm payload."""
    mag = d.get("magnitude")
    mag_s = "n/a" if mag is None else f"{mag:+.4g} {d.get('unit', '')}".rstrip()
    rms, th = d.get("residual_rms"), d.get("threshold")
    rms_s = "n/a" if rms is None else f"{rms:.4g}"
    th_s = "n/a" if th is None else f"{th:.4g}"
    msg = f" {d['message']}" if d.get("message") else ""
    conf = d.get("confidence")
    conf_s = "" if conf is None else f" conf={conf:.2f}"
    t_s = d.get("vehicle_time_s", float("nan"))
    return (
        f"{d.get('wall_time', '?')} v{d.get('vehicle')} t={t_s:.3f}s "
        f"{str(d.get('state', '?')).upper():7s} {d.get('kind')} {d.get('channel_name')} "
        f"{d.get('fault_type')} mag={mag_s}{conf_s} J={rms_s} J_th={th_s} "
        f"[{d.get('estimator')}]{msg}"
    )


def run_alarm_printer(
    keyexpr: str = "gcs/*/alarm",
    connect: Sequence[str] = ("tcp/127.0.0.1:7447",),
    *,
    duration_s: float | None = None,
    max_alarms: int | None = None,
    json_lines: bool = False,
    out: TextIO = sys.stdout,
) -> int:
    """Print alarms as they arrive, as a second tool would (``gcs-monitor alarms [KEYEXPR]``).

    Returns after ``duration_s`` seconds, after ``max_alarms`` alarms, or on Ctrl-C; returns the
    number printed. ``json_lines`` prints the raw payloads instead of formatted lines.
    """
    n = 0
    deadline = None if duration_s is None else time.monotonic() + duration_s
    with subscribe_alarms(keyexpr, connect=connect) as sub:
        try:
            while (deadline is None or time.monotonic() < deadline) and (
                max_alarms is None or n < max_alarms
            ):
                wait = 0.2 if deadline is None else max(0.0, min(0.2, deadline - time.monotonic()))
                d = sub.get(timeout=wait)
                if d is None:
                    continue
                out.write((json.dumps(d) if json_lines else format_alarm(d)) + "\n")
                out.flush()
                n += 1
        except KeyboardInterrupt:
            pass
    return n
