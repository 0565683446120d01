"""An in-process fleet for tests: a router session, a feeder that publishes vehicles' raw frames
on ``mavlink/<sysid>/rx`` at a pace, workers on threads (each with its own Zenoh session, as
separate processes would have), and an alarm subscriber. ``crash(worker)`` ends a worker the
way a killed process does: its session goes away without a release."""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gcs_monitor.config import MonitorConfig
from gcs_monitor.fleet.worker import Worker, WorkerOptions
from gcs_monitor.link.zenoh_bus import ZenohBus, ZenohOptions, open_bus, raw_key
from gcs_monitor.sinks.zenoh_sink import AlarmSubscriber
from tests.helpers.fleet import Packet, free_port


@dataclass
class InprocFleet:
    endpoint: str = field(default_factory=lambda: f"tcp/127.0.0.1:{free_port()}")
    router: ZenohBus | None = None
    workers: dict[str, tuple[Worker, threading.Thread]] = field(default_factory=dict)
    alarms: list[dict[str, Any]] = field(default_factory=list)
    sub: AlarmSubscriber | None = None
    feeder_bus: ZenohBus | None = None
    fed_until_us: int = 0

    def start(self) -> InprocFleet:
        self.router = open_bus(ZenohOptions(mode="router", listen=(self.endpoint,)))
        self.feeder_bus = self.client()
        self.sub = AlarmSubscriber("gcs/*/alarm", options=ZenohOptions(
            mode="client", connect=(self.endpoint,)), callback=self.alarms.append)
        return self

    def client(self) -> ZenohBus:
        return open_bus(ZenohOptions(mode="client", connect=(self.endpoint,)))

    def worker(self, name: str, *, journal: Path | None = None, **opts: Any) -> Worker:
        w = Worker(MonitorConfig(), WorkerOptions(worker_id=name, journal=journal, **opts),
                   self.client())
        th = threading.Thread(target=w.run, name=f"worker-{name}", daemon=True)
        th.start()
        self.workers[name] = (w, th)
        return w

    def crash(self, name: str) -> None:
        """The worker's process dies: no release, no last status; its session ends."""
        w, th = self.workers.pop(name)
        w.stop()
        th.join(timeout=30)
        w.bus.close()

    def feed(self, packets: Sequence[Packet], *, speed: float, batch_us: int = 20_000,
             until_us: int | None = None, start_us: int = 0) -> None:
        """Publish packets from ``start_us`` up to ``until_us`` (vehicle time), ``speed`` x
        real time, each vehicle's packets of ``batch_us`` as one sample (as the bridge does)."""
        assert self.feeder_bus is not None
        pubs: dict[int, Any] = {}
        t0 = time.monotonic()
        batch: dict[int, list[bytes]] = {}
        edge = start_us + batch_us
        for t, p in packets:
            if t < start_us:
                continue
            if until_us is not None and t >= until_us:
                break
            if t >= edge:
                for s, parts in batch.items():
                    pub = pubs.get(s)
                    if pub is None:
                        pub = pubs[s] = self.feeder_bus.publisher(raw_key(s), json_=False,
                                                                  block=True)
                    pub.put(b"".join(parts))
                batch = {}
                edge = t + batch_us
                wait = t0 + (t - start_us) * 1e-6 / speed - time.monotonic()
                if wait > 0:
                    time.sleep(wait)
            batch.setdefault(p[5], []).append(p)
            self.fed_until_us = t
        for s, parts in batch.items():
            pubs.setdefault(s, self.feeder_bus.publisher(raw_key(s), json_=False)).put(
                b"".join(parts))

    def close(self) -> None:
        for name in list(self.workers):
            w, th = self.workers.pop(name)
            w.stop()
            th.join(timeout=30)
            w.close()
            w.bus.close()
        for b in (self.sub, self.feeder_bus, self.router):
            if b is not None:
                b.close()
