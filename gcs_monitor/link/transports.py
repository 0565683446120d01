"""Byte sources from a URL: udpin/udpout/tcp/serial, a .tlog file, or Zenoh raw frames.

Every source is an iterator of ``(bytes, wall_time_s)`` chunks. Live sources read on a thread
into a bounded queue: when input arrives faster than it is processed the oldest chunks are
dropped and counted (``dropped_chunks``), so memory stays bounded.

UDP sources also count what the operating system dropped before the monitor could read it
(``kernel_drops``: the socket's receive-queue overflow counter, ``SO_RXQ_OVFL``, on Linux; None
where the platform has none), so a flood that overflows the socket buffer is reported, not
silent.
"""

from __future__ import annotations

import collections
import mmap
import socket
import struct
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

TLOG_HEADER = struct.Struct(">Q")
MAV1_MAGIC = 0xFE
MAV2_MAGIC = 0xFD
MAV2_SIGNED = 0x01
MAV1_OVERHEAD = 8  # header 6 + CRC 2
MAV2_OVERHEAD = 12  # header 10 + CRC 2
MAV2_SIGNATURE = 13
DEFAULT_MAX_QUEUE_CHUNKS = 20_000
DEFAULT_MAX_QUEUE_BYTES = 16 << 20  # 16 MiB of unprocessed input at most
DEFAULT_SERIAL_BAUD = 57_600
GCS_SYSID = 255
GCS_COMPID = 190
SO_RXQ_OVFL = getattr(socket, "SO_RXQ_OVFL", 40)  # Linux: drop counter as ancillary data
_U32 = struct.Struct("=I")
DEFAULT_UDP_RCVBUF = 4 << 20


class SourceError(ValueError):
    """A source URL cannot be opened; the message says why and what is expected."""


class _BoundedQueue:
    """Thread-safe drop-oldest queue of chunks with counted drops, bounded in chunks and bytes."""

    def __init__(self, max_chunks: int, max_bytes: int = DEFAULT_MAX_QUEUE_BYTES) -> None:
        self._q: collections.deque[tuple[bytes, float]] = collections.deque()
        self._max = max_chunks
        self._max_bytes = max_bytes
        self._bytes = 0
        self._cv = threading.Condition()
        self.dropped_chunks = 0
        self.dropped_bytes = 0
        self.high_water = 0

    def put(self, item: tuple[bytes, float]) -> None:
        with self._cv:
            self._q.append(item)
            self._bytes += len(item[0])
            while len(self._q) > self._max or (self._bytes > self._max_bytes and len(self._q) > 1):
                old = self._q.popleft()
                self._bytes -= len(old[0])
                self.dropped_chunks += 1
                self.dropped_bytes += len(old[0])
            self.high_water = max(self.high_water, len(self._q))
            self._cv.notify()

    def get(self, timeout: float) -> tuple[bytes, float] | None:
        with self._cv:
            if not self._q and not self._cv.wait_for(lambda: bool(self._q), timeout):
                return None
            item = self._q.popleft()
            self._bytes -= len(item[0])
            return item

    def __len__(self) -> int:
        return len(self._q)


class Source:
    """Base: iterate chunks; ``close()`` stops the reader; drop counters for health."""

    dropped_chunks = 0
    dropped_bytes = 0
    resync_bytes = 0
    kernel_drops: int | None = None
    total_bytes: int | None = None
    position = 0

    def __iter__(self) -> Iterator[tuple[bytes, float]]:  # pragma: no cover - abstract
        raise NotImplementedError

    def close(self) -> None:
        pass

    def write(self, data: bytes) -> None:
        """Send bytes back over the link (requests, heartbeats); no-op where impossible."""

    def __enter__(self) -> Source:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _ThreadedSource(Source):
    def __init__(self, max_chunks: int, idle_timeout_s: float | None) -> None:
        self._queue = _BoundedQueue(max_chunks)
        self._stop = threading.Event()
        self._idle = idle_timeout_s
        # tick_s: when set, the iterator also yields an empty chunk (b"", wall time) after this
        # long without data, so a consumer that holds data back (the fleet bridge's batches)
        # can let it go on time even when nothing more arrives
        self.tick_s: float | None = None
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _start(self) -> None:
        self._thread.start()

    def _run(self) -> None:  # pragma: no cover - overridden
        raise NotImplementedError

    @property
    def dropped_chunks(self) -> int:  # type: ignore[override]
        return self._queue.dropped_chunks

    @property
    def dropped_bytes(self) -> int:  # type: ignore[override]
        return self._queue.dropped_bytes

    def __iter__(self) -> Iterator[tuple[bytes, float]]:
        # The idle timeout counts from the last data received; before the first data arrives
        # the source waits (a monitor started before its vehicle must not give up).
        last: float | None = None
        while not self._stop.is_set():
            tick = self.tick_s
            item = self._queue.get(0.1 if tick is None else tick)
            if item is None:
                if self._idle is not None and last is not None and \
                        time.monotonic() - last > self._idle:
                    return
                if tick is not None:
                    yield b"", time.time()
                continue
            last = time.monotonic()
            yield item

    def close(self) -> None:
        self._stop.set()


class UdpSource(_ThreadedSource):
    """``udpin:HOST:PORT`` (bind and listen) or ``udpout:HOST:PORT`` (send first, then read)."""

    def __init__(self, host: str, port: int, *, listen: bool,
                 max_chunks: int = DEFAULT_MAX_QUEUE_CHUNKS,
                 idle_timeout_s: float | None = None,
                 rcvbuf_bytes: int = DEFAULT_UDP_RCVBUF) -> None:
        super().__init__(max_chunks, idle_timeout_s)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf_bytes)
        try:  # the kernel then hands its drop counter to every recvmsg
            self.sock.setsockopt(socket.SOL_SOCKET, SO_RXQ_OVFL, 1)
            self.kernel_drops = 0
        except OSError:
            self.kernel_drops = None
        self._peer: tuple[str, int] | None = None
        try:
            if listen:
                self.sock.bind((host, port))
            else:
                self._peer = (host, port)
                self.sock.bind(("0.0.0.0", 0))
        except OSError as exc:
            raise SourceError(f"cannot bind UDP {host}:{port}: {exc}") from None
        self.sock.settimeout(0.1)
        self._start()

    def _run(self) -> None:
        if self._peer is not None:  # udpout: a GCS HEARTBEAT tells the vehicle where we are
            try:
                self.sock.sendto(gcs_heartbeat(), self._peer)
            except OSError:
                pass
        anc = socket.CMSG_SPACE(_U32.size) if self.kernel_drops is not None else 0
        while not self._stop.is_set():
            try:
                data, cmsgs, _, addr = self.sock.recvmsg(65535, anc)
            except TimeoutError:
                continue
            except OSError:
                return
            for level, kind, value in cmsgs:
                if level == socket.SOL_SOCKET and kind == SO_RXQ_OVFL and len(value) >= 4:
                    # cumulative count of datagrams dropped on this socket
                    self.kernel_drops = _U32.unpack_from(value)[0]
            if self._peer is None:
                self._peer = addr
            self._queue.put((data, time.time()))

    def write(self, data: bytes) -> None:
        if self._peer is not None:
            try:
                self.sock.sendto(data, self._peer)
            except OSError:
                pass

    def close(self) -> None:
        super().close()
        self._thread.join(timeout=1.0)
        self.sock.close()


class TcpSource(_ThreadedSource):
    """``tcp:HOST:PORT``: connect as a client (as to SITL or a telemetry server)."""

    def __init__(self, host: str, port: int, *, max_chunks: int = DEFAULT_MAX_QUEUE_CHUNKS,
                 idle_timeout_s: float | None = None) -> None:
        super().__init__(max_chunks, idle_timeout_s)
        try:
            self.sock = socket.create_connection((host, port), timeout=5.0)
        except OSError as exc:
            raise SourceError(f"cannot connect to tcp:{host}:{port}: {exc}") from None
        self.sock.settimeout(0.1)
        self._start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                data = self.sock.recv(65536)
            except TimeoutError:
                continue
            except OSError:
                return
            if not data:
                self._stop.set()
                return
            self._queue.put((data, time.time()))

    def write(self, data: bytes) -> None:
        try:
            self.sock.sendall(data)
        except OSError:
            pass

    def close(self) -> None:
        super().close()
        self._thread.join(timeout=1.0)
        self.sock.close()


class SerialSource(_ThreadedSource):
    """``/dev/ttyX[:BAUD]`` through pyserial (optional dependency)."""

    def __init__(self, device: str, baud: int, *,
                 max_chunks: int = DEFAULT_MAX_QUEUE_CHUNKS) -> None:
        super().__init__(max_chunks, None)
        try:
            import serial  # type: ignore[import-untyped]
        except ImportError:
            raise SourceError("serial links need pyserial: pip install pyserial") from None
        try:
            self.port = serial.Serial(device, baud, timeout=0.1)
        except Exception as exc:
            raise SourceError(f"cannot open serial {device}: {exc}") from None
        self._start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                data = self.port.read(4096)
            except Exception:
                return
            if data:
                self._queue.put((bytes(data), time.time()))

    def close(self) -> None:
        super().close()
        self._thread.join(timeout=1.0)
        self.port.close()


class ZenohSource(_ThreadedSource):
    """``zenoh:KEYEXPR[@ENDPOINT,...]``: raw MAVLink frames published on a key expression.

    The session comes from :func:`gcs_monitor.link.zenoh_bus.open_bus` (peer mode, scouting
    off, connecting to the given endpoints, default ``tcp/127.0.0.1:7447``; TLS and access
    control from ``options``) and is always closed (stack-notes sec. 3).
    """

    def __init__(self, keyexpr: str, endpoints: list[str] | None = None, *,
                 max_chunks: int = DEFAULT_MAX_QUEUE_CHUNKS,
                 idle_timeout_s: float | None = None, options: Any = None) -> None:
        super().__init__(max_chunks, idle_timeout_s)
        from dataclasses import replace

        from gcs_monitor.link.zenoh_bus import (
            DEFAULT_ENDPOINT,
            RoleDefaults,
            ZenohOptions,
            open_bus,
        )

        opts = options if options is not None else ZenohOptions()
        if endpoints:
            opts = replace(opts, connect=tuple(endpoints))
        elif opts.connect is None:
            opts = replace(opts, connect=(DEFAULT_ENDPOINT,))
        # a client: it reaches a publishing peer directly and a router's other clients
        self._bus = open_bus(opts, what=f"zenoh:{keyexpr}", defaults=RoleDefaults(mode="client"))
        try:
            self._bus.subscribe(keyexpr, self._on_sample)
        except Exception as exc:
            self._bus.close()
            raise SourceError(f"zenoh:{keyexpr}: cannot subscribe: {exc}") from None
        self._closed = False

    def _on_sample(self, key: str, payload: bytes) -> None:
        self._queue.put((payload, time.time()))

    def _run(self) -> None:  # callbacks deliver; nothing to poll
        pass

    def close(self) -> None:
        super().close()
        if self._closed:
            return
        self._closed = True
        self._bus.close()


class TlogSource(Source):
    """A .tlog: 8-byte big-endian µs timestamp + one raw packet per record.

    Records are walked by their MAVLink lengths; where the byte after a timestamp is no MAVLink
    magic the walker advances byte by byte (counted in ``resync_bytes``) until a record lines up.
    A file cut mid-record ends cleanly (``truncated_bytes`` says how much was left). Packets are
    batched into chunks of about ``chunk_bytes``; a chunk's time is its last record's timestamp.

    Parameters
    ----------
    speed : replay speed factor against the recorded timestamps (None: as fast as possible)
    on_progress : called with (bytes done, total bytes) after every chunk (e.g. a tqdm bar)
    """

    def __init__(self, path: Path | str, *, speed: float | None = None,
                 chunk_bytes: int = 16384,
                 on_progress: Callable[[int, int], None] | None = None) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise SourceError(f"{self.path}: no such file")
        if speed is not None and not speed > 0:
            raise SourceError(f"replay speed must be > 0, got {speed}")
        self.speed = speed
        self.chunk_bytes = chunk_bytes
        self.total_bytes = self.path.stat().st_size
        self.on_progress = on_progress
        self.resync_bytes = 0
        self.truncated_bytes = 0
        self.records = 0
        self.position = 0

    def __iter__(self) -> Iterator[tuple[bytes, float]]:
        if self.total_bytes == 0:
            return
        with open(self.path, "rb") as fh, mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as mm:
            yield from self._walk(mm)

    def _walk(self, buf: Any) -> Iterator[tuple[bytes, float]]:
        n = len(buf)
        p = 0
        parts: list[bytes] = []
        size = 0
        t_rec = 0.0
        t0_rec: float | None = None
        t0_wall = time.monotonic()
        unpack = TLOG_HEADER.unpack_from
        records = 0
        while p + 9 <= n:
            magic = buf[p + 8]
            if magic == MAV2_MAGIC:
                if p + 11 > n:
                    break
                length = buf[p + 9] + MAV2_OVERHEAD + (
                    MAV2_SIGNATURE if buf[p + 10] & MAV2_SIGNED else 0)
            elif magic == MAV1_MAGIC:
                length = buf[p + 9] + MAV1_OVERHEAD
            else:
                p += 1
                self.resync_bytes += 1
                continue
            end = p + 8 + length
            if end > n:
                break  # truncated mid-packet
            t_rec = unpack(buf, p)[0] * 1e-6
            if t0_rec is None:
                t0_rec = t_rec
            parts.append(buf[p + 8:end])
            records += 1
            size += length
            p = end
            if size >= self.chunk_bytes:
                if self.speed is not None:
                    self._pace(t_rec - t0_rec, t0_wall)
                self.position = p
                self.records = records
                if self.on_progress is not None:
                    self.on_progress(p, n)
                yield b"".join(parts), t_rec
                parts, size = [], 0
        self.truncated_bytes = n - p
        self.position = n
        self.records = records
        if parts:
            if self.speed is not None and t0_rec is not None:
                self._pace(t_rec - t0_rec, t0_wall)
            yield b"".join(parts), t_rec
        if self.on_progress is not None:
            self.on_progress(n, n)

    def _pace(self, t_rel: float, t0_wall: float) -> None:
        assert self.speed is not None
        wait = t0_wall + t_rel / self.speed - time.monotonic()
        if wait > 0:
            time.sleep(wait)


def gcs_heartbeat() -> bytes:
    """One MAVLink 2 HEARTBEAT from a GCS (sysid 255, compid 190)."""
    from gcs_monitor.link.mav import mavlink

    mav = mavlink.MAVLink(None, srcSystem=GCS_SYSID, srcComponent=GCS_COMPID)
    msg = mavlink.MAVLink_heartbeat_message(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID,
                                            0, 0, mavlink.MAV_STATE_ACTIVE, 3)
    return bytes(msg.pack(mav))


def open_source(url: str, *, speed: float | None = None, idle_timeout_s: float | None = None,
                on_progress: Callable[[int, int], None] | None = None,
                zenoh_options: Any = None) -> Source:
    """Open a byte source from a URL; raise :class:`SourceError` with the expected forms."""
    forms = ("udpin:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT, /dev/ttyX[:BAUD], FILE.tlog, "
             "zenoh:KEYEXPR[@ENDPOINT]")
    if url.startswith(("udpin:", "udpout:", "udp:", "tcp:")):
        scheme, _, rest = url.partition(":")
        host, _, port_s = rest.rpartition(":")
        if not host or not port_s.isdigit():
            raise SourceError(f"{url!r}: expected {scheme}:HOST:PORT")
        if not 0 < int(port_s) <= 65535:
            raise SourceError(f"{url!r}: port {port_s} is outside 1..65535")
        if scheme == "tcp":
            return TcpSource(host, int(port_s), idle_timeout_s=idle_timeout_s)
        return UdpSource(host, int(port_s), listen=scheme != "udpout",
                         idle_timeout_s=idle_timeout_s)
    if url.startswith("zenoh:"):
        key, _, eps = url[len("zenoh:"):].partition("@")
        endpoints = eps.split(",") if eps else None
        if not key:
            raise SourceError(f"{url!r}: expected zenoh:KEYEXPR[@ENDPOINT]")
        return ZenohSource(key, endpoints, idle_timeout_s=idle_timeout_s, options=zenoh_options)
    if url.startswith("/dev/"):
        dev, _, baud = url.partition(":")
        return SerialSource(dev, int(baud) if baud.isdigit() else DEFAULT_SERIAL_BAUD)
    if url.endswith(".tlog") or Path(url).is_file():
        return TlogSource(Path(url), speed=speed, on_progress=on_progress)
    raise SourceError(f"cannot open {url!r}: expected one of {forms}")
