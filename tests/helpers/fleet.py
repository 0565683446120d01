"""Fleet test support: simulated flights of many vehicles, re-addressed MAVLink, paced senders,
free ports and child processes that are always stopped.

A flight is simulated once per template (scenario + seed) and re-addressed to any number of
system ids by rewriting the sender byte of every packet and its CRC (:func:`resysid`), so a
fleet of 60 vehicles costs the simulation of a few.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import signal
import socket
import struct
import subprocess
import sys
import time
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

Packet = tuple[int, bytes]
ROOT = Path(__file__).resolve().parents[2]
TLOG_EPOCH_US = 1_700_000_000_000_000
_CRC_EXTRA = {mid: cls.crc_extra for mid, cls in mavlink.mavlink_map.items()}

try:
    from fastcrc.crc16 import mcrf4xx as _crc16
except ImportError:  # pragma: no cover
    _crc16 = None


def _x25(data: bytes) -> int:
    if _crc16 is not None:
        return int(_crc16(data, 0xFFFF))
    return int(mavlink.x25crc(bytearray(data)).crc)


def resysid(packet: bytes, sysid: int) -> bytes:
    """The same MAVLink 2 packet sent by ``sysid`` (header byte and CRC rewritten; unsigned)."""
    b = bytearray(packet)
    b[5] = sysid
    n = b[1]
    mid = b[7] | b[8] << 8 | b[9] << 16
    crc = _x25(bytes(b[1:10 + n]) + bytes([_CRC_EXTRA[mid]]))
    struct.pack_into("<H", b, 10 + n, crc)
    return bytes(b)


def fault_scenario(*, duration_s: float, seed: int, fault_at_s: float | None,
                   channel: str = "aoa1", bias_deg: float = 3.0,
                   preset: str = "demo_airdata_faults") -> Any:
    """The demo's transport flight (3 IMUs, triplex AoA/CAS, every contract message), with one
    AoA bias at ``fault_at_s`` (None: fault-free)."""
    from sim_vehicle.faults.profiles import FaultSpec
    from sim_vehicle.scenario import load_scenario

    sc = load_scenario(preset)
    bias = (("bias_rad", math.radians(bias_deg)),)
    faults = () if fault_at_s is None else (FaultSpec(channel, "bias", fault_at_s, None, bias),)
    return dataclasses.replace(sc, faults=faults, duration_s=duration_s, seed=seed)


@functools.cache
def template(duration_s: float, seed: int, fault_at_s: float | None) -> tuple[Packet, ...]:
    """One simulated flight as (vehicle µs, packet), sysid 1."""
    from sim_vehicle.run import iter_packets

    return tuple(iter_packets(fault_scenario(duration_s=duration_s, seed=seed,
                                             fault_at_s=fault_at_s)))


def fleet_packets(sysids: Sequence[int], *, duration_s: float,
                  fault_at_s: dict[int, float | None] | None = None,
                  templates: int = 2, stagger_us: int = 0) -> list[Packet]:
    """Every vehicle's packets, merged in vehicle-time order (ties by sysid). Vehicle ``k`` of
    ``sysids`` flies template ``k % templates`` (seeds 1..); ``fault_at_s[sysid]`` gives it an
    AoA-1 bias from then. ``stagger_us`` shifts each vehicle's send times a little (vehicles
    are not synchronised)."""
    faults = fault_at_s or {}
    streams = []
    for k, sysid in enumerate(sysids):
        pk = template(duration_s, 1 + k % templates, faults.get(sysid))
        off = (k * stagger_us) % 10_000 if stagger_us else 0
        streams.append([(t + off, sysid, resysid(p, sysid)) for t, p in pk])
    merged = sorted((x for s in streams for x in s), key=lambda x: (x[0], x[1]))
    return [(t, p) for t, _, p in merged]


def write_tlog(path: Path, packets: Iterable[Packet]) -> Path:
    with open(path, "wb") as f:
        for t, p in packets:
            f.write(struct.pack(">Q", TLOG_EPOCH_US + t) + p)
    return path


def free_port(kind: int = socket.SOCK_STREAM) -> int:
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def paced_send(packets: Sequence[Packet], addr: tuple[str, int], *, speed: float = 1.0,
               stop_at_us: int | None = None) -> int:
    """Send packets over UDP at ``speed`` x their vehicle time; returns how many were sent."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    t0 = time.monotonic()
    t_first = packets[0][0] if packets else 0
    n = 0
    try:
        for t, p in packets:
            if stop_at_us is not None and t > stop_at_us:
                break
            due = t0 + (t - t_first) * 1e-6 / speed
            wait = due - time.monotonic()
            if wait > 0.002:
                time.sleep(wait)
            sock.sendto(p, addr)
            n += 1
    finally:
        sock.close()
    return n


class Procs:
    """Child processes of a test, stopped (SIGTERM, then SIGKILL) whatever happens."""

    def __init__(self) -> None:
        self.procs: list[subprocess.Popen[bytes]] = []

    def start(self, args: Sequence[str], *, log: Path, netns: str | None = None,
              env: dict[str, str] | None = None) -> subprocess.Popen[bytes]:
        cmd = list(args)
        if netns is not None:
            cmd = ["ip", "netns", "exec", netns, *cmd]
        e = dict(os.environ, OPENBLAS_NUM_THREADS="1", PYTHONUNBUFFERED="1",
                 PYTHONPATH=str(ROOT), **(env or {}))
        fh = open(log, "wb")  # noqa: SIM115 - closed with the process
        p = subprocess.Popen(cmd, stdout=fh, stderr=subprocess.STDOUT, env=e, cwd=ROOT,
                             start_new_session=True)
        p._log = fh  # type: ignore[attr-defined]
        self.procs.append(p)
        return p

    def gcs(self, *args: str, log: Path, netns: str | None = None) -> subprocess.Popen[bytes]:
        return self.start([sys.executable, "-m", "gcs_monitor.cli", *args], log=log, netns=netns)

    def stop(self, p: subprocess.Popen[bytes], sig: int = signal.SIGTERM,
             timeout: float = 20.0) -> int:
        if p.poll() is None:
            try:
                os.killpg(p.pid, sig)
            except ProcessLookupError:
                pass
            try:
                p.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait(timeout=10)
        p._log.close()  # type: ignore[attr-defined]
        return int(p.returncode)

    def close(self) -> None:
        for p in self.procs:
            if p.poll() is None:
                self.stop(p, timeout=10.0)
            elif not p._log.closed:  # type: ignore[attr-defined]
                p._log.close()  # type: ignore[attr-defined]

    def __enter__(self) -> Procs:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def wait_for(pred, timeout_s: float, period_s: float = 0.1) -> bool:  # type: ignore[no-untyped-def]
    t_end = time.monotonic() + timeout_s
    while time.monotonic() < t_end:
        if pred():
            return True
        time.sleep(period_s)
    return bool(pred())
