"""Zenoh sink: alarm stream, decimated estimates and a health queryable per vehicle.

Key expressions come from :func:`keyexpr` only:

- ``gcs/<vehicle>/alarm``             one JSON object per AlarmEvent transition
- ``gcs/<vehicle>/estimate/<name>``   decimated estimates (``estimate_rate_hz``, 5 Hz default)
- ``gcs/<vehicle>/health``            queryable answering the vehicle's latest health

**No alarm lost.** Alarms go out on a ``zenoh.ext`` advanced publisher: it keeps the last
``alarm_history`` (256) alarms of the vehicle, announces itself, and sends sequence-number
heartbeats. An :class:`AlarmSubscriber` (an advanced subscriber) fetches that history when it
starts or when a publisher appears (a restarted monitor, a fleet worker that took the vehicle
over), recovers alarms it missed while paused or disconnected, and reports those it could not
recover (older than the history) as *missed*: ``gcs-monitor alarms`` catches up and says so.

Sessions come from :func:`gcs_monitor.link.zenoh_bus.open_bus` (loopback, scouting off, TLS and
access control from options). Several sinks share one session: pass ``bus``. The live path never
waits on the network: ``publish`` serialises to JSON and hands the payload to a bounded queue
drained by one worker thread that owns the ``put`` calls; a full queue drops the payload and
counts it (``n_dropped``). A sink that opens its own session raises
:class:`~gcs_monitor.link.zenoh_bus.ZenohError` when it cannot (a port in use): the monitor
stops with that message instead of running on without its outputs.

Pitfall: the process hangs at exit if a session with a callback queryable/subscriber is not
closed, so :meth:`ZenohSink.close` always undeclares what it declared and closes a session it
opened; sessions are also closed by ``atexit``.
"""

from __future__ import annotations

import atexit
import json
import logging
import queue
import sys
import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Sequence
from typing import Any, TextIO

import zenoh

from gcs_monitor.fdi.records import StepOutput
from gcs_monitor.link.zenoh_bus import (
    DEFAULT_ENDPOINT,
    RoleDefaults,
    ZenohBus,
    ZenohOptions,
    open_bus,
)
from gcs_monitor.sinks.schema import (
    alarm_to_dict,
    dumps,
    estimate_to_dict,
    health_to_dict,
)
from gcs_monitor.telemetry.frame import Frame

log = logging.getLogger(__name__)

KEY_PREFIX = "gcs"
DEFAULT_LISTEN = (DEFAULT_ENDPOINT,)
ALARM_HISTORY = 256  # alarms kept per vehicle for late and recovering subscribers
ALARM_HEARTBEAT_S = 1.0  # sequence-number heartbeat: a missed last alarm is noticed
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


def make_config(listen: Sequence[str] = (), connect: Sequence[str] = ()) -> zenoh.Config:
    """Peer-mode config with scouting off and explicit endpoints (stack-notes section 3)."""
    from gcs_monitor.link.zenoh_bus import make_config as _make

    return _make(ZenohOptions(listen=tuple(listen), connect=tuple(connect)))


class ZenohSink:
    """Zenoh output for one vehicle (Sink protocol).

    Parameters
    ----------
    vehicle : MAVLink system id
    bus : a shared session (:class:`ZenohBus`); None: open one from ``listen``/``connect``/
        ``options`` (``tcp/127.0.0.1:7447`` listen by default)
    estimate_rate_hz : publication rate of each estimate (vehicle time)
    queue_size : bounded hand-off queue between ``publish`` and the network thread
    prefix : first key segment (``gcs``)
    alarm_history : alarms kept for late and recovering subscribers (0: a plain publisher)
    monitor : this monitor's name, written in every alarm payload
    """

    def __init__(
        self,
        vehicle: int,
        *,
        bus: ZenohBus | None = None,
        listen: Sequence[str] = DEFAULT_LISTEN,
        connect: Sequence[str] = (),
        options: ZenohOptions | None = None,
        estimate_rate_hz: float = 5.0,
        queue_size: int = 1024,
        prefix: str = KEY_PREFIX,
        alarm_history: int = ALARM_HISTORY,
        monitor: str = "",
    ) -> None:
        if estimate_rate_hz <= 0:
            raise ValueError("estimate_rate_hz must be > 0")
        self.vehicle = int(vehicle)
        self.prefix = prefix
        self.monitor = monitor
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
        self._own_bus = bus is None
        if bus is None:
            opts = options or ZenohOptions()
            bus = open_bus(opts, what=f"zenoh sink of vehicle {self.vehicle}",
                           defaults=RoleDefaults(listen=tuple(listen), connect=tuple(connect)))
        self._bus: ZenohBus | None = bus
        self._publishers: dict[str, Any] = {}
        self._declared: list[Any] = []
        try:
            self._publishers[self.alarm_key] = self._declare(bus.publisher(
                self.alarm_key, reliable=True,
                # Alarms must arrive: the worker thread may wait for the network, the live
                # path not.
                block=True, history=alarm_history, heartbeat_s=ALARM_HEARTBEAT_S))
            self._declare(bus.queryable(self.health_key, self._on_health_query))
        except zenoh.ZError:
            self._close_session()
            raise
        self._worker = threading.Thread(
            target=self._run, name=f"zenoh-sink-{self.vehicle}", daemon=True
        )
        self._worker.start()
        atexit.register(self.close)

    def _declare(self, obj: Any) -> Any:
        self._declared.append(obj)
        return obj

    @property
    def active(self) -> bool:
        """True while the session is open."""
        return self._bus is not None and not self._closed

    # ----------------------------------------------------------------- Sink protocol
    def publish(self, frame: Frame, out: StepOutput) -> None:
        estimates, events = out.estimates, out.events
        if self._closed:
            return
        wall = time.time() if (events or estimates) else 0.0
        for ev in events:
            self._enqueue(self.alarm_key,
                          dumps(alarm_to_dict(ev, wall_time_s=wall, monitor=self.monitor)))
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
        """Drain the queue (bounded wait), undeclare, close an own session; idempotent."""
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
        if self._bus is None:
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
            bus = self._bus
            if bus is None:
                self.n_dropped += 1
                continue
            try:
                pub = self._publishers.get(key)
                if pub is None:
                    pub = self._publishers[key] = self._declare(
                        bus.publisher(key, reliable=True, block=False))
                pub.put(payload)
                self.n_published += 1
            except zenoh.ZError:
                self.n_errors += 1
                log.warning("zenoh put on %s failed", key, exc_info=True)

    def _on_health_query(self, key: str) -> str:
        # Runs on a zenoh thread.
        with self._lock:
            self.n_health_queries += 1
            return self._health_json

    def _close_session(self) -> None:
        bus, self._bus = self._bus, None
        if bus is None:
            return
        for obj in reversed(self._declared):
            bus.forget(obj)
        self._declared.clear()
        self._publishers.clear()
        if self._own_bus:
            bus.close()


# --------------------------------------------------------------------- consumer side
class AlarmSubscriber:
    """Receives alarm payloads (dicts) on a key expression; use as a context manager.

    An advanced subscriber (module docstring): the publishers' recent history first, then live
    alarms; alarms missed while paused or disconnected are recovered from the publishers'
    history, and those that could not be are counted in ``n_missed`` (``missed``: per
    publisher). A transition seen twice (same id, state and vehicle time) is delivered once.

    Parameters
    ----------
    keyexpr : e.g. ``gcs/*/alarm`` or ``gcs/1/alarm``
    connect, listen : zenoh endpoints (``options`` may set TLS, a config file, a timeout)
    callback : called with each decoded payload on a zenoh thread; when None, payloads are
        queued and read with :meth:`get`
    history : alarms fetched per publisher when it is found (0: live only, plain subscriber)
    on_miss : called with (publisher, count) when alarms could not be recovered
    """

    def __init__(
        self,
        keyexpr: str = "gcs/*/alarm",
        *,
        connect: Sequence[str] | None = None,
        listen: Sequence[str] = (),
        callback: Callable[[dict[str, Any]], None] | None = None,
        queue_size: int = 4096,
        options: ZenohOptions | None = None,
        history: int = ALARM_HISTORY,
        on_miss: Callable[[str, int], None] | None = None,
    ) -> None:
        self.keyexpr = keyexpr
        self._queue: queue.Queue[dict[str, Any]] = queue.Queue(maxsize=queue_size)
        self._callback = callback
        self._on_miss_cb = on_miss
        self.n_received = 0
        self.n_bad = 0
        self.n_dropped = 0
        self.n_repeats = 0
        self.n_missed = 0
        self.missed: dict[str, int] = {}
        self._seen: OrderedDict[tuple[Any, ...], None] = OrderedDict()
        self._lock = threading.Lock()
        self._closed = False
        opts = options or ZenohOptions()
        self._bus = open_bus(opts, what="alarm subscriber", defaults=RoleDefaults(
            mode="client" if not listen else "peer", listen=tuple(listen),
            connect=tuple(connect) if connect is not None else (DEFAULT_ENDPOINT,)))
        try:
            if history > 0:
                self._bus.subscribe_history(keyexpr, self._on_sample, history=history,
                                            on_miss=self._on_miss)
            else:
                self._bus.subscribe(keyexpr, self._on_sample)
        except BaseException:
            self._bus.close()
            raise
        atexit.register(self.close)

    def _on_miss(self, source: str, n: int) -> None:
        with self._lock:
            self.n_missed += n
            self.missed[source] = self.missed.get(source, 0) + n
        if self._on_miss_cb is not None:
            self._on_miss_cb(source, n)

    def _on_sample(self, key: str, payload: bytes) -> None:
        try:
            d = json.loads(payload)
        except (ValueError, UnicodeDecodeError):
            self.n_bad += 1
            return
        k = (d.get("alarm_id"), d.get("state"), d.get("t_us"), d.get("vehicle"),
             d.get("channel_name"))
        with self._lock:
            if k in self._seen:
                self.n_repeats += 1
                return
            self._seen[k] = None
            if len(self._seen) > 50_000:
                self._seen.popitem(last=False)
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
        self._bus.close()

    def __enter__(self) -> AlarmSubscriber:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def subscribe_alarms(
    keyexpr: str = "gcs/*/alarm",
    *,
    connect: Sequence[str] | None = None,
    listen: Sequence[str] = (),
    callback: Callable[[dict[str, Any]], None] | None = None,
    options: ZenohOptions | None = None,
    history: int = ALARM_HISTORY,
    on_miss: Callable[[str, int], None] | None = None,
) -> AlarmSubscriber:
    """Open an :class:`AlarmSubscriber` (close it, or use it in a ``with`` block)."""
    return AlarmSubscriber(keyexpr, connect=connect, listen=listen, callback=callback,
                           options=options, history=history, on_miss=on_miss)


def format_alarm(d: dict[str, Any], *, late_s: float | None = None) -> str:
    """One human-readable line for an alarm payload; ``late_s``: it arrived this long after it
    was published (history or recovery), said at the end of the line."""
    mag = d.get("magnitude")
    mag_s = "n/a" if mag is None else f"{mag:+.4g} {d.get('unit', '')}".rstrip()
    rms, th = d.get("residual_rms"), d.get("threshold")
    rms_s = "n/a" if rms is None else f"{rms:.4g}"
    th_s = "n/a" if th is None else f"{th:.4g}"
    msg = f" {d['message']}" if d.get("message") else ""
    conf = d.get("confidence")
    conf_s = "" if conf is None else f" conf={conf:.2f}"
    t_s = d.get("vehicle_time_s", float("nan"))
    late = f"  (caught up: published {late_s:.1f} s earlier)" if late_s is not None else ""
    return (
        f"{d.get('wall_time', '?')} v{d.get('vehicle')} t={t_s:.3f}s "
        f"{str(d.get('state', '?')).upper():7s} {d.get('kind')} {d.get('channel_name')} "
        f"{d.get('fault_type')} mag={mag_s}{conf_s} J={rms_s} J_th={th_s} "
        f"[{d.get('estimator')}]{msg}{late}"
    )


def run_alarm_printer(
    keyexpr: str = "gcs/*/alarm",
    connect: Sequence[str] | None = None,
    *,
    duration_s: float | None = None,
    max_alarms: int | None = None,
    json_lines: bool = False,
    out: TextIO = sys.stdout,
    options: ZenohOptions | None = None,
    history: int = ALARM_HISTORY,
    late_after_s: float = 2.0,
) -> int:
    """Print alarms as they arrive, as a second tool would (``gcs-monitor alarms [KEYEXPR]``).

    Catches up: the publishers' recent alarms first (a restart of this tool), alarms recovered
    after a pause; a line that arrives more than ``late_after_s`` after it was published says
    so, and alarms that could not be recovered are reported (``!! missed N alarms ...``).
    Returns after ``duration_s`` seconds, after ``max_alarms`` alarms, or on Ctrl-C; returns the
    number printed. ``json_lines`` prints the raw payloads instead of formatted lines.
    """
    n = 0
    misses: queue.Queue[tuple[str, int]] = queue.Queue()
    deadline = None if duration_s is None else time.monotonic() + duration_s
    with subscribe_alarms(keyexpr, connect=connect, options=options, history=history,
                          on_miss=lambda src, k: misses.put((src, k))) as sub:
        try:
            while (deadline is None or time.monotonic() < deadline) and (
                max_alarms is None or n < max_alarms
            ):
                while not misses.empty():
                    src, k = misses.get()
                    line = (json.dumps({"type": "missed", "publisher": src, "count": k})
                            if json_lines else
                            f"!! missed {k} alarm{'s' * (k != 1)} from publisher {src}: older "
                            f"than its history, not recoverable (query gcs/<vehicle>/health "
                            f"for the active alarms)")
                    out.write(line + "\n")
                    out.flush()
                wait = 0.2 if deadline is None else max(0.0, min(0.2, deadline - time.monotonic()))
                d = sub.get(timeout=wait)
                if d is None:
                    continue
                wall = d.get("wall_time_s")
                late = time.time() - wall if isinstance(wall, (int, float)) else None
                late = late if late is not None and late > late_after_s else None
                out.write((json.dumps(d) if json_lines else format_alarm(d, late_s=late)) + "\n")
                out.flush()
                n += 1
        except KeyboardInterrupt:
            pass
    return n
