"""The fleet bridge's batching (gcs_monitor/fleet/bridge.py): per vehicle, one Zenoh sample
per ``flush_s`` of frames; a ticking source lets the last batch go without further data; a
source that cannot tick is flushed when its queue is empty; ground-station frames stay home."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from gcs_monitor.fleet import bridge as bridge_mod
from gcs_monitor.fleet.bridge import Bridge
from gcs_monitor.link.zenoh_bus import raw_key
from tests.helpers.fleet import resysid, template

FLUSH_S = 0.02


class _Bus:
    """What the bridge uses of a ZenohBus: publishers that record their samples."""

    def __init__(self) -> None:
        self.samples: list[tuple[str, bytes, float]] = []
        self.clock: list[float] = [0.0]

    def queryable(self, key: str, answer: Any) -> None:
        return None

    def publisher(self, key: str, **_: Any) -> Any:
        bus = self

        class _Pub:
            def put(self, payload: bytes) -> None:
                bus.samples.append((key, payload, bus.clock[0]))

        return _Pub()


class _Source:
    """Scripted chunks at given monotonic times; ``tick_s`` present (a live source) or not."""

    def __init__(self, script: list[tuple[float, bytes]], clock: list[float], *,
                 ticks: bool) -> None:
        self.script = script
        self.clock = clock
        if ticks:
            self.tick_s: float | None = None
        self._queue: list[int] = []  # empty: the bridge's idle rule applies without ticks

    def __iter__(self) -> Iterator[tuple[bytes, float]]:
        for t, data in self.script:
            self.clock[0] = t
            yield data, t


@pytest.fixture(scope="module")
def packets() -> list[bytes]:
    return [p for _, p in template(1.0, 1, None)[:40]]


def _run(script: list[tuple[float, bytes]], *, ticks: bool,
         monkeypatch: pytest.MonkeyPatch) -> tuple[_Bus, Bridge, _Source]:
    bus = _Bus()
    src = _Source(script, bus.clock, ticks=ticks)
    monkeypatch.setattr(bridge_mod.time, "monotonic", lambda: bus.clock[0])
    br = Bridge(src, bus, flush_s=FLUSH_S)  # type: ignore[arg-type]
    br.run()
    return bus, br, src


def test_frames_wait_for_flush_s_and_a_tick_lets_the_last_batch_go(
        packets: list[bytes], monkeypatch: pytest.MonkeyPatch) -> None:
    # one datagram every 5 ms from vehicles 1 and 2 (and a GCS heartbeat source, 255), then
    # silence with ticks: every frame leaves, in batches no older than flush_s
    script: list[tuple[float, bytes]] = []
    for k, p in enumerate(packets[:20]):
        t = 0.005 * k
        script.append((t, resysid(p, 1) + resysid(p, 2) + resysid(p, 255)))
    script += [(0.1 + 0.01 * k, b"") for k in range(4)]  # ticks after the last datagram
    bus, br, src = _run(script, ticks=True, monkeypatch=monkeypatch)
    assert src.tick_s == pytest.approx(FLUSH_S / 2)  # the bridge asked its source to tick
    keys = {k for k, _, _ in bus.samples}
    assert keys == {raw_key(1), raw_key(2)}  # ground station (255) frames are not forwarded
    for sysid in (1, 2):
        mine = [(p, t) for k, p, t in bus.samples if k == raw_key(sysid)]
        assert b"".join(p for p, _ in mine) == b"".join(resysid(p, sysid) for p in packets[:20])
        # 20 datagrams 5 ms apart, a batch leaving once its first is 20 ms old: 4 samples of
        # 5 datagrams each, not 20 (the last one on a tick, 15-25 ms after its last datagram)
        assert len(mine) == 4
        assert mine[-1][1] <= 0.095 + FLUSH_S + 0.01  # the last batch left on a tick
    assert br.stats.frames == 40 and br.stats.samples == 8
    assert br.stats.chunks == 20  # ticks are not chunks


def test_a_source_that_cannot_tick_is_flushed_when_its_queue_is_empty(
        packets: list[bytes], monkeypatch: pytest.MonkeyPatch) -> None:
    script = [(0.005 * k, resysid(p, 3)) for k, p in enumerate(packets[:6])]
    bus, br, _ = _run(script, ticks=False, monkeypatch=monkeypatch)
    assert [t for _, _, t in bus.samples] == [t for t, _ in script]  # each at once
    assert br.stats.samples == 6
