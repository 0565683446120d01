"""``gcs-monitor bridge``: the raw MAVLink frames of a link onto ``mavlink/<sysid>/rx``.

The bridge decodes what it reads with the monitor's decoder (so CRC errors, garbage, duplicates,
kernel drops and, with a key, unsigned, forged and replayed packets are counted and never
forwarded), groups the accepted frames by sender and publishes each sender's frames as one
Zenoh sample when ``flush_s`` (20 ms) has passed since the first one waiting or ``max_batch``
bytes are waiting; a live source ticks when no data comes, so the last frames never wait
longer. Batching is what lets a worker keep up: a paced vehicle's datagrams arrive a few
milliseconds apart, and publishing each at once (the earlier rule, "at once when nothing else
is queued") gave a worker 145 samples per vehicle-second, each a Zenoh callback, a queue item
and a GIL hand-over, and cost it a quarter more CPU than 20 ms batches (docs/results.md,
Fleet, Load). A queued source that cannot tick is flushed whenever its queue is empty; a file
by age and size, and at its end.
Frames of a ground station (system id 255) are not forwarded. Publication is reliable
and, when the network is slower than the link, blocks the bridge: the backlog then shows as
counted input drops, never as silent loss on the bus. A queryable ``mavlink/bridge/<name>/health``
answers the bridge's counters.
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from gcs_monitor.link.decode import Decoder
from gcs_monitor.link.transports import Source
from gcs_monitor.link.zenoh_bus import RAW_PREFIX, ZenohBus, raw_key

log = logging.getLogger(__name__)

GCS_SYSIDS = frozenset({255})


@dataclass
class BridgeStats:
    chunks: int = 0
    frames: int = 0
    samples: int = 0
    per_sysid: dict[int, int] = field(default_factory=dict)


class Bridge:
    """Forward a byte source's frames to Zenoh, per vehicle (module docstring)."""

    def __init__(self, source: Source, bus: ZenohBus, *, decoder: Decoder | None = None,
                 name: str = "bridge", flush_s: float = 0.02, max_batch: int = 8192) -> None:
        self.source = source
        self.bus = bus
        self.decoder = decoder or Decoder()
        self.name = name
        self.flush_s = flush_s
        self.max_batch = max_batch
        self.stats = BridgeStats()
        self._pubs: dict[int, Any] = {}
        self._batch: dict[int, list[bytes]] = {}
        self._size: dict[int, int] = {}
        self._since: dict[int, float] = {}
        bus.queryable(f"{RAW_PREFIX}/bridge/{name}/health", lambda _k: json.dumps(self.health()))

    def health(self) -> dict[str, Any]:
        self.decoder.note_source(self.source)
        return {"type": "bridge_health", "bridge": self.name, "frames": self.stats.frames,
                "samples": self.stats.samples,
                "per_sysid": {str(k): v for k, v in sorted(self.stats.per_sysid.items())},
                **self.decoder.health()}

    def _publish(self, sysid: int) -> None:
        parts = self._batch.pop(sysid, None)
        self._size.pop(sysid, None)
        self._since.pop(sysid, None)
        if not parts:
            return
        pub = self._pubs.get(sysid)
        if pub is None:
            pub = self._pubs[sysid] = self.bus.publisher(raw_key(sysid), reliable=True,
                                                         block=True, json_=False)
        pub.put(b"".join(parts))
        self.stats.samples += 1

    def flush(self) -> None:
        for sysid in list(self._batch):
            self._publish(sysid)

    def run(self, *, duration_s: float | None = None,
            on_tick: Callable[[Bridge], None] | None = None) -> BridgeStats:
        """Forward until the source ends, ``duration_s`` passes or Ctrl-C."""
        t_end = None if duration_s is None else time.monotonic() + duration_s
        st = self.stats
        queue_len = getattr(self.source, "_queue", None)
        ticks = hasattr(self.source, "tick_s")
        if ticks:  # empty chunks while no data comes: waiting batches still leave on time
            self.source.tick_s = max(self.flush_s / 2.0, 0.001)  # type: ignore[attr-defined]
        try:
            for data, wall in self.source:
                now = time.monotonic()
                if data:  # else a tick: only the waiting batches' ages are checked
                    st.chunks += 1
                for m in self.decoder.feed(data, wall) if data else ():
                    sysid = m._header.srcSystem
                    if sysid in GCS_SYSIDS:
                        continue
                    buf = bytes(m.get_msgbuf())
                    parts = self._batch.get(sysid)
                    if parts is None:
                        parts = self._batch[sysid] = []
                        self._size[sysid] = 0
                        self._since[sysid] = now
                    parts.append(buf)
                    self._size[sysid] += len(buf)
                    st.frames += 1
                    st.per_sysid[sysid] = st.per_sysid.get(sysid, 0) + 1
                idle = not ticks and queue_len is not None and len(queue_len) == 0
                for sysid in list(self._batch):
                    if idle or self._size[sysid] >= self.max_batch or \
                            now - self._since[sysid] >= self.flush_s:
                        self._publish(sysid)
                if on_tick is not None:
                    on_tick(self)
                if t_end is not None and now >= t_end:
                    break
            for m in self.decoder.flush():
                sysid = m._header.srcSystem
                if sysid not in GCS_SYSIDS:
                    self._batch.setdefault(sysid, []).append(bytes(m.get_msgbuf()))
        except KeyboardInterrupt:
            pass
        finally:
            self.flush()
            self.decoder.note_source(self.source)
        return st
