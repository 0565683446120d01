"""A fleet worker: its share of the vehicles on ``mavlink/<sysid>/rx``, the full pipeline per
vehicle, the one alarm stream and health; failover by liveliness.

What a worker does, on one Zenoh session (:class:`gcs_monitor.link.zenoh_bus.ZenohBus`):

* announces itself with a liveliness token ``gcs/fleet/<group>/worker/<id>`` and publishes its
  status on ``gcs/fleet/<group>/status/<id>`` (2 Hz, and at once when it changes; also a
  queryable): its scope and shard, the vehicles it owns, and per vehicle the vehicle time it has
  published up to (the *watermark*);
* watches the other workers' tokens and statuses; the live workers decide, by the same pure
  function everywhere (:func:`gcs_monitor.fleet.ownership.owner`), who owns each vehicle;
* subscribes to its scope of raw frames (``mavlink/*/rx`` by default). Frames of vehicles it owns
  go through that vehicle's own :class:`~gcs_monitor.monitor.Monitor` (decoder with signing, the
  default families, sinks: Zenoh alarm stream and health, the journal); frames of the other
  vehicles in its scope are kept for ``buffer_s`` seconds, so that it can take one over without
  a gap;
* follows the alarm stream of the whole group (``gcs/*/alarm``, with history), so it knows every
  alarm that is active and who published it.

**Takeover.** When a worker's token disappears (its process ended: at once; its host vanished:
after the Zenoh lease), each of its vehicles moves to the live worker that now scores best for
it. That worker builds the vehicle's pipeline, hands it the alarms the previous owner published as
active and the previous owner's watermark (:meth:`Monitor.adopt`), and feeds it the buffered
frames, then the live ones: events up to the watermark are not published again, a re-raise of an
inherited alarm is published as an update with the same alarm id, an inherited alarm the new
pipeline does not confirm within ``grace_s`` is cleared (:class:`gcs_monitor.monitor.AlarmBook`).
When a worker joins, the vehicles it now owns are handed over in order: the previous owner
releases them (its status says up to which vehicle time) before the new one starts.

The health of each vehicle (``gcs/<vehicle>/health``) says which worker owns it, since when, how
long the takeover took and what was inherited (``fleet`` and ``handover``).
"""

from __future__ import annotations

import collections
import json
import logging
import os
import queue
import socket
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gcs_monitor.config import MonitorConfig
from gcs_monitor.fdi.events import AlarmEvent, AlarmState
from gcs_monitor.fleet.ownership import Member, owner
from gcs_monitor.link.decode import Decoder
from gcs_monitor.link.zenoh_bus import (
    RAW_PREFIX,
    ZenohBus,
    keyexpr_includes,
    raw_key,
    sysid_of_raw_key,
)
from gcs_monitor.monitor import Monitor
from gcs_monitor.sinks import SharedSink
from gcs_monitor.sinks.journal import AlarmJournal
from gcs_monitor.sinks.schema import alarm_from_dict
from gcs_monitor.sinks.zenoh_sink import ZenohSink

log = logging.getLogger(__name__)

FLEET_PREFIX = "gcs/fleet"
MAX_RAW_QUEUE = 200_000  # raw samples waiting for the worker loop; beyond: dropped, counted
RAW_ROUND_ITEMS = 256  # raw samples taken per round of the loop (each vehicle's fed as one chunk)


def default_worker_id() -> str:
    return f"{socket.gethostname()}-{os.getpid()}"


@dataclass
class WorkerOptions:
    """A worker's place in the fleet.

    Attributes
    ----------
    group : fleet group (workers of one group share the vehicles)
    worker_id : unique name (default ``<host>-<pid>``)
    scope : key expression of the raw frames it may monitor (``mavlink/*/rx``: any vehicle)
    shard : primary share ``(i, n)``: the system ids with ``sysid % n == i``
    buffer_s : seconds of raw frames kept per vehicle it does not own (takeover without a gap)
    grace_s : vehicle time within which an inherited alarm must be confirmed
    release_wait_s : how long a worker waits for a live previous owner to release a vehicle
    settle_s : after start, how long it learns the fleet before it owns anything
    status_period_s : status publication period
    signing_key, require_signing : MAVLink 2 signing of every vehicle's stream
    journal : the alarm journal (shared by the worker's vehicles); its active alarms are
        inherited at a restart
    estimate_rate_hz : estimates published on Zenoh
    """

    group: str = "default"
    worker_id: str = field(default_factory=default_worker_id)
    scope: str = f"{RAW_PREFIX}/*/rx"
    shard: tuple[int, int] | None = None
    buffer_s: float = 15.0
    grace_s: float = 20.0
    release_wait_s: float = 2.0
    settle_s: float = 1.0
    status_period_s: float = 0.5
    signing_key: bytes | None = None
    require_signing: bool = False
    journal: Path | None = None
    estimate_rate_hz: float = 5.0


@dataclass
class _Owned:
    monitor: Monitor
    since_wall_s: float
    lost_wall_s: float | None  # when the previous owner disappeared (takeover), else None
    source: str
    takeover_s: float | None = None
    frames_at_start: int = 0



class Worker:
    """One fleet worker (module docstring). ``run()`` until ``stop()`` or ``duration_s``.

    Parameters
    ----------
    cfg : monitor configuration (families, thresholds)
    opts : the worker's place in the fleet
    bus : its Zenoh session
    on_event : called with every alarm event it publishes (console)
    extra_sinks : more sinks per vehicle (tests)
    """

    def __init__(self, cfg: MonitorConfig, opts: WorkerOptions, bus: ZenohBus, *,
                 on_event: Callable[[AlarmEvent], None] | None = None,
                 extra_sinks: Callable[[int], Sequence[Any]] | None = None) -> None:
        self.cfg = cfg
        self.opts = opts
        self.bus = bus
        self.wid = opts.worker_id
        if "/" in self.wid or "*" in self.wid:
            raise ValueError(f"worker id {self.wid!r}: no '/' or '*'")
        self.on_event = on_event
        self.extra_sinks = extra_sinks
        self.prefix = f"{FLEET_PREFIX}/{opts.group}"
        self.owned: dict[int, _Owned] = {}
        self.buffers: dict[int, collections.deque[tuple[float, bytes]]] = {}
        self.seen: set[int] = set()
        self.tokens: dict[str, bool] = {}
        self.lost_at: dict[str, float] = {}  # wid -> wall time its token disappeared
        self.statuses: dict[str, dict[str, Any]] = {}
        self.pending: dict[int, float] = {}  # vehicle -> deadline to wait for its release
        self.released: dict[int, int] = {}  # vehicle -> watermark when this worker let it go
        self.alarms: dict[int, dict[str, dict[str, Any]]] = {}  # vehicle -> channel -> payload
        self.alarm_t_us: dict[int, int] = {}  # vehicle -> latest alarm vehicle time published
        self.events: list[AlarmEvent] = []
        self.n_raw_dropped = 0
        self.n_foreign_key = 0
        self.handovers: list[dict[str, Any]] = []
        self._scope_cache: dict[int, bool] = {}
        self._control: queue.Queue[tuple[Any, ...]] = queue.Queue()
        self._raw: queue.Queue[tuple[int, bytes, float]] = queue.Queue(MAX_RAW_QUEUE)
        self._stop = threading.Event()
        self._dirty = True
        self._status_changed = True
        self._started_wall = time.time()
        self._started = time.monotonic()
        self.journal: AlarmJournal | None = None
        self._inherit: dict[int, list[AlarmEvent]] = {}
        if opts.journal is not None:
            self.journal = AlarmJournal(opts.journal, monitor=self.wid)
            self._inherit = self.journal.active_alarms()
        self._status_pub = bus.publisher(f"{self.prefix}/status/{self.wid}", reliable=True)
        bus.queryable(f"{self.prefix}/status/{self.wid}", lambda _k: json.dumps(self.status()))
        bus.subscribe(f"{self.prefix}/status/*", self._on_status)
        bus.watch_tokens(f"{self.prefix}/worker/*", self._on_token)
        bus.subscribe_history("gcs/*/alarm", self._on_alarm, history=256)
        for _, payload in bus.get(f"{self.prefix}/status/*", timeout_s=1.0):
            self._on_status("", payload)
        bus.subscribe(opts.scope, self._on_raw)
        self._token = bus.token(f"{self.prefix}/worker/{self.wid}")
        self.tokens[self.wid] = True

    # -- zenoh callbacks (zenoh threads): hand over to the loop --------------------------------
    def _on_raw(self, key: str, payload: bytes) -> None:
        sysid = sysid_of_raw_key(key)
        if sysid is None:
            self.n_foreign_key += 1
            return
        try:
            self._raw.put_nowait((sysid, payload, time.time()))
        except queue.Full:
            self.n_raw_dropped += 1

    def _on_token(self, key: str, alive: bool) -> None:
        self._control.put(("token", key.rpartition("/")[2], alive, time.time()))

    def _on_status(self, key: str, payload: bytes) -> None:
        try:
            d = json.loads(payload)
        except ValueError:
            return
        if isinstance(d, dict) and d.get("type") == "fleet_status":
            self._control.put(("status", d))

    def _on_alarm(self, key: str, payload: bytes) -> None:
        try:
            d = json.loads(payload)
        except ValueError:
            return
        self._control.put(("alarm", d))

    # -- the loop ----------------------------------------------------------------------------
    def stop(self) -> None:
        self._stop.set()

    def run(self, duration_s: float | None = None) -> None:
        """Process until :meth:`stop` (another thread, a signal) or ``duration_s``."""
        t_end = None if duration_s is None else time.monotonic() + duration_s
        next_status = 0.0
        next_health = time.monotonic() + 1.0
        while not self._stop.is_set():
            now = time.monotonic()
            if t_end is not None and now >= t_end:
                break
            self._drain_control()
            if self._dirty and now - self._started >= self.opts.settle_s:
                self._dirty = False
                self._rebalance()
            if self.pending:
                self._check_pending()
            if now >= next_status or self._status_changed:
                self._status_changed = False
                next_status = now + self.opts.status_period_s
                self._publish_status()
            if now >= next_health:
                next_health = now + 1.0
                self._publish_health()
            self._drain_raw(max_items=RAW_ROUND_ITEMS)

    def _drain_control(self) -> None:
        while True:
            try:
                item = self._control.get_nowait()
            except queue.Empty:
                return
            kind = item[0]
            if kind == "token":
                _, wid, alive, wall = item
                if wid == self.wid:
                    continue
                was = self.tokens.get(wid, False)
                self.tokens[wid] = alive
                if not alive and was:
                    self.lost_at[wid] = wall
                    log.info("worker %s: %s disappeared", self.wid, wid)
                self._dirty = True
            elif kind == "status":
                d = item[1]
                wid = str(d.get("worker"))
                if wid == self.wid:
                    continue
                new = wid not in self.statuses
                self.statuses[wid] = d
                for s in d.get("owned", []):
                    self._see(int(s))
                if new:
                    self._dirty = True
            elif kind == "alarm":
                self._track_alarm(item[1])

    def _track_alarm(self, d: dict[str, Any]) -> None:
        try:
            v = int(d["vehicle"])
            ch = str(d["channel_name"])
            t = int(d["t_us"])
        except (KeyError, TypeError, ValueError):
            return
        per = self.alarms.setdefault(v, {})
        if d.get("state") == AlarmState.CLEARED.value:
            per.pop(ch, None)
        else:
            per[ch] = d
        self.alarm_t_us[v] = max(self.alarm_t_us.get(v, t), t)

    def _drain_raw(self, max_items: int) -> None:
        """Feed what the bus delivered, for up to 50 ms: each round takes the first sample
        (waiting briefly), then whatever else is queued by then (``max_items`` in all), and
        hands each vehicle its part as one chunk, in arrival order. Under load the rounds grow,
        so the per-chunk costs (``Monitor.feed``, the decoder, the link statistics) are paid per
        round and vehicle, not per Zenoh sample (docs/results.md, Fleet, Load)."""
        deadline = time.monotonic() + 0.05
        while True:
            try:
                first = self._raw.get(timeout=0.005 if not self.owned else 0.002)
            except queue.Empty:
                return
            parts: dict[int, list[bytes]] = {first[0]: [first[1]]}
            walls = {first[0]: first[2]}
            for _ in range(max_items - 1):
                try:
                    sysid, data, wall = self._raw.get_nowait()
                except queue.Empty:
                    break
                parts.setdefault(sysid, []).append(data)
                walls[sysid] = wall  # the chunk's receipt: its last sample's
            for sysid, chunks in parts.items():
                self._take_raw(sysid, b"".join(chunks), walls[sysid])
            if time.monotonic() > deadline:
                return

    def _take_raw(self, sysid: int, data: bytes, wall: float) -> None:
        """One vehicle's frames: fed to its monitor when owned, else kept ``buffer_s``."""
        self._see(sysid)
        o = self.owned.get(sysid)
        if o is not None:
            self._feed(sysid, o, data, wall)
        elif self._in_scope(sysid):
            buf = self.buffers.setdefault(sysid, collections.deque())
            buf.append((wall, data))
            horizon = wall - self.opts.buffer_s
            while buf and buf[0][0] < horizon:
                buf.popleft()

    def _feed(self, sysid: int, o: _Owned, data: bytes, wall: float) -> None:
        for ev in o.monitor.feed(data, wall):
            self.events.append(ev)
            if self.on_event is not None:
                self.on_event(ev)
        if o.takeover_s is None and o.lost_wall_s is not None:
            v = o.monitor.vehicles.get(sysid)
            if v is not None and v.book.handover is not None and \
                    v.book.handover.resumed_t_us is not None:
                o.takeover_s = time.time() - o.lost_wall_s

    def _see(self, sysid: int) -> None:
        if sysid not in self.seen:
            self.seen.add(sysid)
            self._dirty = True

    def _in_scope(self, sysid: int) -> bool:
        ok = self._scope_cache.get(sysid)
        if ok is None:
            ok = self._scope_cache[sysid] = keyexpr_includes(self.opts.scope, raw_key(sysid))
        return ok

    # -- membership and ownership ----------------------------------------------------------
    def members(self) -> list[Member]:
        out = [Member(self.wid, self.opts.scope, self.opts.shard)]
        for wid, alive in self.tokens.items():
            st = self.statuses.get(wid)
            if wid == self.wid or not alive or st is None:
                continue
            shard = st.get("shard")
            out.append(Member(wid, str(st.get("scope", f"{RAW_PREFIX}/*/rx")),
                              (int(shard[0]), int(shard[1])) if shard else None))
        return out

    def _rebalance(self) -> None:
        members = self.members()
        desired = {s for s in self.seen
                   if owner(s, members, lambda scope, s_: keyexpr_includes(
                       scope, raw_key(s_))) == self.wid}
        for s in sorted(set(self.owned) - desired):
            self._release(s)
        for s in sorted(desired - set(self.owned)):
            if s in self.pending:
                continue
            prev = self._previous_owner(s)
            if prev is not None and self.tokens.get(prev, False):
                # a live owner hands over: wait until its status says it let the vehicle go
                self.pending[s] = time.monotonic() + self.opts.release_wait_s
            else:
                self._take(s, prev)
        for s in list(self.pending):
            if s not in desired:
                del self.pending[s]

    def _previous_owner(self, sysid: int) -> str | None:
        best: tuple[float, str] | None = None
        for wid, st in self.statuses.items():
            if sysid in st.get("owned", []) or str(sysid) in st.get("released", {}):
                t = float(st.get("wall_time_s", 0.0))
                if best is None or t > best[0]:
                    best = (t, wid)
        return best[1] if best is not None else None

    def _check_pending(self) -> None:
        now = time.monotonic()
        for s, deadline in list(self.pending.items()):
            prev = self._previous_owner(s)
            st = self.statuses.get(prev) if prev is not None else None
            released = st is not None and sysid_in(st.get("released", {}), s) and \
                s not in st.get("owned", [])
            if released or now >= deadline or prev is None or not self.tokens.get(prev, False):
                del self.pending[s]
                self._take(s, prev)

    def _watermark(self, sysid: int, prev: str | None) -> int | None:
        marks = []
        st = self.statuses.get(prev) if prev is not None else None
        if st is not None:
            for key in ("watermarks", "released"):
                w = st.get(key, {}).get(str(sysid))
                if w is not None:
                    marks.append(int(w))
        if sysid in self.alarm_t_us and prev is not None:
            marks.append(self.alarm_t_us[sysid])
        return max(marks) if marks else None

    def _take(self, sysid: int, prev: str | None) -> None:
        wall = time.time()
        mon = self._new_monitor(sysid)
        active = self._inherited(sysid)
        watermark = self._watermark(sysid, prev)
        lost = self.lost_at.get(prev) if prev is not None else None
        if prev is not None or active:
            mon.adopt(sysid, active, watermark_us=watermark, source=prev or "",
                      wall_time_s=wall, reason="takeover")
        o = _Owned(mon, wall, lost if lost is not None else (wall if prev else None),
                   prev or "")
        self.owned[sysid] = o
        self.released.pop(sysid, None)
        self._status_changed = True
        info = {"vehicle": sysid, "from": prev, "wall_time_s": wall, "watermark_us": watermark,
                "inherited": len(active), "buffered_s": self._buffered_s(sysid)}
        self.handovers.append(info)
        log.info("worker %s: takes vehicle %d from %s (watermark %s, %d active alarms, "
                 "%.1f s buffered)", self.wid, sysid, prev, watermark, len(active),
                 info["buffered_s"])
        buf = self.buffers.pop(sysid, None)
        if buf:
            for w, data in buf:
                self._feed(sysid, o, data, w)

    def _buffered_s(self, sysid: int) -> float:
        buf = self.buffers.get(sysid)
        return buf[-1][0] - buf[0][0] if buf else 0.0

    def _inherited(self, sysid: int) -> list[AlarmEvent]:
        out: dict[str, AlarmEvent] = {}
        for ev in self._inherit.pop(sysid, []):  # the journal (a restart)
            out[str(ev.channel)] = ev
        for ch, d in self.alarms.get(sysid, {}).items():  # the alarm stream (newer)
            try:
                out[ch] = alarm_from_dict(d)
            except (ValueError, KeyError):
                continue
        return list(out.values())

    def _release(self, sysid: int) -> None:
        o = self.owned.pop(sysid)
        v = o.monitor.vehicles.get(sysid)
        mark = v.last_t_us if v is not None else 0
        o.monitor.close()
        self.released[sysid] = mark
        self._status_changed = True
        log.info("worker %s: releases vehicle %d at t=%d us", self.wid, sysid, mark)

    def _new_monitor(self, sysid: int) -> Monitor:
        dec = Decoder(signing_key=self.opts.signing_key,
                      require_signing=self.opts.require_signing)
        return Monitor(self.cfg, sinks_for=self._sinks, decoder=dec, only_sysid=sysid,
                       grace_s=self.opts.grace_s, name=self.wid)

    def _sinks(self, sysid: int) -> list[Any]:
        sinks: list[Any] = [ZenohSink(sysid, bus=self.bus, monitor=self.wid,
                                      estimate_rate_hz=self.opts.estimate_rate_hz)]
        if self.journal is not None:
            sinks.append(SharedSink(self.journal))
        if self.extra_sinks is not None:
            sinks += list(self.extra_sinks(sysid))
        return sinks

    # -- status and health -----------------------------------------------------------------
    def status(self) -> dict[str, Any]:
        watermarks = {}
        for s, o in self.owned.items():
            v = o.monitor.vehicles.get(s)
            if v is not None:
                watermarks[str(s)] = v.last_t_us
        return {"type": "fleet_status", "worker": self.wid, "group": self.opts.group,
                "scope": self.opts.scope,
                "shard": list(self.opts.shard) if self.opts.shard else None,
                "owned": sorted(self.owned), "watermarks": watermarks,
                "released": {str(k): v for k, v in self.released.items()},
                "pending": sorted(self.pending), "seen": sorted(self.seen),
                "workers": sorted(m.wid for m in self.members()),
                "wall_time_s": time.time(), "started_wall_s": self._started_wall,
                "raw_dropped": self.n_raw_dropped}

    def _publish_status(self) -> None:
        try:
            self._status_pub.put(json.dumps(self.status()))
        except Exception:  # noqa: BLE001 - a status is re-sent at the next period
            log.debug("status put failed", exc_info=True)

    def fleet_health(self, sysid: int) -> dict[str, Any]:
        o = self.owned[sysid]
        return {"worker": self.wid, "group": self.opts.group,
                "workers": sorted(m.wid for m in self.members()),
                "owned_since_wall_s": o.since_wall_s, "takeover_s": o.takeover_s}

    def _publish_health(self) -> None:
        for s, o in self.owned.items():
            if s in o.monitor.vehicles:
                o.monitor.publish_health(extra={"fleet": self.fleet_health(s)})

    def close(self) -> None:
        """Release every vehicle's sinks (the bus is the caller's)."""
        self._publish_status()
        for o in self.owned.values():
            o.monitor.close()
        self.owned.clear()
        if self.journal is not None:
            self.journal.close()


def sysid_in(mapping: dict[str, Any], sysid: int) -> bool:
    return str(sysid) in mapping
