"""A fleet of processes, on loopback or on network-namespace hosts: the failover tests, the soak
and ``benchmarks/bench_fleet.py`` run it.

Placement: host 0 runs the Zenoh router (``gcs-monitor router``), the vehicles' sender (UDP,
paced in real time), ``gcs-monitor bridge`` and an alarm recorder; hosts 1.. run one
``gcs-monitor worker`` each (without namespaces everything is on 127.0.0.1). The sender is this
module run as a program: it replays simulated flights (templates simulated once, re-addressed to
each system id) and writes the wall time of vehicle time 0, so alarm latency can be taken from
the fault onset in vehicle time to the recorder's receipt.
"""

from __future__ import annotations

import argparse
import json
import pickle
import random
import socket
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tests.helpers.fleet import Procs, free_port, resysid, template, wait_for
from tests.helpers.netns import NetnsLab

PY = sys.executable
RECORDER = """
import json, sys, time
from gcs_monitor.link.zenoh_bus import ZenohOptions
from gcs_monitor.sinks.zenoh_sink import AlarmSubscriber
out = open(sys.argv[2], "a", buffering=1)
def on(d):
    d["recv_wall_s"] = time.time()
    out.write(json.dumps(d) + "\\n")
def miss(src, n):
    out.write(json.dumps({"type": "missed", "n": n}) + "\\n")
opts = ZenohOptions(mode="client", connect=(sys.argv[1],))
sub = AlarmSubscriber("gcs/*/alarm", options=opts, callback=on, on_miss=miss)
def status(key, payload):
    d = json.loads(payload)
    out.write(json.dumps({"type": "status", "recv_wall_s": time.time(),
                          "worker": d.get("worker"), "watermarks": d.get("watermarks"),
                          "raw_dropped": d.get("raw_dropped"), "owned": d.get("owned")}) + "\\n")
sub._bus.subscribe("gcs/fleet/*/status/*", status)
try:
    while True:
        time.sleep(0.5)
except KeyboardInterrupt:
    pass
finally:
    sub.close()
"""
QUERY = """
import json, sys
from gcs_monitor.link.zenoh_bus import ZenohOptions, open_bus
with open_bus(ZenohOptions(mode="client", connect=(sys.argv[1],))) as bus:
    out = {}
    for key in sys.argv[2:]:
        out[key] = [json.loads(p) for _, p in bus.get(key, timeout_s=3.0)]
    print(json.dumps(out))
"""


@dataclass
class Templates:
    """Simulated flights (sysid 1) with an AoA-1 bias at each onset (None: fault-free)."""

    duration_s: float
    onsets: tuple[float | None, ...]

    def build(self, path: Path) -> Path:
        flights = [list(template(self.duration_s, 1 + k, onset))
                   for k, onset in enumerate(self.onsets)]
        path.write_bytes(pickle.dumps({"onsets": self.onsets, "flights": flights}))
        return path


# -- the sender ----------------------------------------------------------------------------------


class LinkFaults:
    """Random link faults (soak): per vehicle, bursts of loss, outages, duplicates, corrupted
    bytes and reordering, from a seeded generator, about ``rate_per_min`` events per minute per
    vehicle; ``stats`` counts the events."""

    def __init__(self, seed: int, rate_per_min: float) -> None:
        self.rng = random.Random(seed)
        self.p_event = rate_per_min / 60.0 / 630.0  # per packet, at ~630 packets/s
        self.active: dict[int, tuple[str, int]] = {}
        self.held: dict[int, bytes] = {}
        self.stats: dict[str, int] = {}

    def apply(self, sysid: int, pkt: bytes) -> list[bytes]:
        kind, left = self.active.get(sysid, ("", 0))
        if not left and self.rng.random() < self.p_event:
            kind = self.rng.choice(["burst", "outage", "duplicate", "corrupt", "reorder"])
            left = {"burst": self.rng.randint(5, 600), "outage": self.rng.randint(600, 3000),
                    "duplicate": 60, "corrupt": 60, "reorder": 60}[kind]
            self.stats[kind] = self.stats.get(kind, 0) + 1
        out = [pkt]
        if left:
            self.active[sysid] = (kind, left - 1)
            if kind in ("burst", "outage"):
                out = []
            elif kind == "duplicate":
                out = [pkt, pkt]
            elif kind == "corrupt" and self.rng.random() < 0.3:
                b = bytearray(pkt)
                b[self.rng.randrange(len(b))] ^= 1 << self.rng.randrange(8)
                out = [bytes(b)]
            elif kind == "reorder" and sysid not in self.held and self.rng.random() < 0.3:
                self.held[sysid] = pkt  # sent after the next one
                return []
        held = self.held.pop(sysid, None)
        return out + [held] if held is not None else out


def send(templates: Path, port: int, host: str, n: int, t0_file: Path, *, speed: float,
         link_faults: float, seed: int) -> None:
    """Send ``n`` vehicles (sysids 1..n) of the templates, paced; write t0 first."""
    data = pickle.loads(templates.read_bytes())
    flights: list[list[tuple[int, bytes]]] = data["flights"]
    dur_us = max(f[-1][0] for f in flights) + 10_000
    faults = LinkFaults(seed, link_faults) if link_faults > 0 else None
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4 << 20)
    addr = (host, port)
    idx = [0] * n
    t0 = time.time() + 0.5
    t0_file.write_text(json.dumps({"t0_wall_s": t0, "n": n, "speed": speed,
                                   "onsets": data["onsets"], "duration_us": dur_us}))
    t0_mono = time.monotonic() + 0.5
    sent = 0
    horizon = 0
    while True:
        # every vehicle's packets due up to the next 5 ms of vehicle time go together; the
        # vehicles are staggered by up to 5 ms (their clocks are not synchronised)
        horizon += 5_000
        if horizon > dur_us + 10_000:
            break
        wait = t0_mono + horizon * 1e-6 / speed - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        for v in range(n):
            f = flights[v % len(flights)]
            stag = (v * 137) % 5000
            k = idx[v]
            while k < len(f) and f[k][0] + stag <= horizon:
                pkt = resysid(f[k][1], v + 1)
                for q in (faults.apply(v + 1, pkt) if faults else (pkt,)):
                    sock.sendto(q, addr)
                    sent += 1
                k += 1
            idx[v] = k
    sock.close()
    print(json.dumps({"sent": sent, "faults": faults.stats if faults else {}}), flush=True)


# -- the fleet -----------------------------------------------------------------------------------


@dataclass
class FleetResult:
    alarms: list[dict[str, Any]]
    status_log: list[dict[str, Any]]  # workers' statuses as the recorder received them
    t0_wall_s: float
    onsets: tuple[float | None, ...]
    n: int
    speed: float
    kill_wall_s: float | None
    duration_us: int | None = None  # the sender's last vehicle time (None: not known)
    samples: list[dict[str, Any]] = field(default_factory=list)  # per worker, every 2 s
    health: dict[str, Any] = field(default_factory=dict)
    statuses: dict[str, Any] = field(default_factory=dict)
    bridge_out: str = ""
    sender_out: str = ""
    logs: dict[str, str] = field(default_factory=dict)

    def onset_of(self, sysid: int) -> float | None:
        return self.onsets[(sysid - 1) % len(self.onsets)]

    def stagger_s(self, sysid: int) -> float:
        """The sender's offset of vehicle ``sysid`` (vehicles are not synchronised)."""
        return ((sysid - 1) * 137 % 5000) * 1e-6

    def sent_vehicle_time_s(self, wall_s: float) -> float:
        """Vehicle time the sender had reached at ``wall_s``: it stops at the flight's end (a lag
        measured after that would grow with the wall clock while nothing is sent)."""
        t = (wall_s - self.t0_wall_s) * self.speed
        return t if self.duration_us is None else min(t, self.duration_us * 1e-6)

    def lags_s(self) -> list[tuple[float, str, float]]:
        """(wall time, worker, its worst vehicle's lag behind the sender, s) per status."""
        out = []
        for st in self.status_log:
            marks = st.get("watermarks") or {}
            if not marks:
                continue
            sent = self.sent_vehicle_time_s(st["recv_wall_s"])
            worst = max(sent - w * 1e-6 - self.stagger_s(int(s)) for s, w in marks.items())
            out.append((st["recv_wall_s"], str(st["worker"]), worst))
        return out

    def latencies_s(self) -> dict[int, float]:
        """Per faulty vehicle: its first fault alarm's receipt minus the onset's send time."""
        out: dict[int, float] = {}
        for a in self.alarms:
            if a.get("state") != "raised" or a.get("kind") != "sensor_fault":
                continue
            v = int(a["vehicle"])
            onset = self.onset_of(v)
            if onset is None or v in out:
                continue
            sent = self.t0_wall_s + (onset + self.stagger_s(v)) / self.speed
            out[v] = a["recv_wall_s"] - sent
        return out


def run_fleet(tmp: Path, templates: Path, *, n: int, workers: int, duration_s: float,
              lab: NetnsLab | None = None, kill: tuple[int, float] | None = None,
              speed: float = 1.0, link_faults: float = 0.0, seed: int = 0,
              worker_args: Sequence[str] = (), sample_s: float = 2.0,
              same_host_workers: bool = False) -> FleetResult:
    """Run the fleet for ``duration_s`` of wall time (module docstring). ``kill``: (worker
    index, seconds after the start) to SIGKILL. Returns what the recorder and queries saw."""
    import psutil

    host0 = lab.hosts[0] if lab else None
    addr0 = lab.addrs[0] if lab else "127.0.0.1"
    zport, uport = free_port(), free_port(socket.SOCK_DGRAM)
    zep = f"tcp/{addr0}:{zport}"
    alarms_file, t0_file = tmp / "alarms.jsonl", tmp / "t0.json"
    with Procs() as procs:
        procs.gcs("router", "--zenoh-listen", zep, log=tmp / "router.log", netns=host0)
        time.sleep(1.0)
        recorder = procs.start([PY, "-c", RECORDER, zep, str(alarms_file)],
                               log=tmp / "recorder.log", netns=host0)
        wprocs = []
        for k in range(workers):
            ns = (lab.hosts[1 + k] if not same_host_workers else lab.hosts[1]) if lab else None
            wprocs.append(procs.gcs("worker", "--name", f"w{k}", "--zenoh-connect", zep,
                                    "--quiet", "--journal", str(tmp / f"w{k}.jsonl"),
                                    *worker_args, log=tmp / f"w{k}.log", netns=ns))
        bridge = procs.gcs("bridge", f"udpin:{addr0}:{uport}", "--zenoh-connect", zep,
                           log=tmp / "bridge.log", netns=host0)
        # everyone up: the workers' statuses answer
        assert wait_for(lambda: len(_query(zep, [f"gcs/fleet/default/status/w{k}"
                                                 for k in range(workers)], host0)
                                    .get("ok", [])) == workers, 90, 1.0), "workers not up"
        time.sleep(2.0)
        sender = procs.start([PY, "-m", "tests.helpers.fleet_procs", "send", str(templates),
                              str(uport), addr0, str(n), str(t0_file), "--speed", str(speed),
                              "--link-faults", str(link_faults), "--seed", str(seed)],
                             log=tmp / "sender.log", netns=host0)
        t_start = time.monotonic()
        kill_wall = None
        samples: list[dict[str, Any]] = []
        ps = {f"w{k}": psutil.Process(p.pid) for k, p in enumerate(wprocs)}
        ps["bridge"] = psutil.Process(bridge.pid)
        next_sample = t_start
        while time.monotonic() - t_start < duration_s:
            now = time.monotonic()
            if kill is not None and kill_wall is None and now - t_start >= kill[1]:
                kill_wall = time.time()
                procs.stop(wprocs[kill[0]], sig=9)
                ps.pop(f"w{kill[0]}", None)
            if now >= next_sample:
                next_sample = now + sample_s
                row: dict[str, Any] = {"t_s": now - t_start, "wall_s": time.time()}
                for name, p in ps.items():
                    try:
                        ct = p.cpu_times()
                        row[name] = {"cpu_s": ct.user + ct.system,
                                     "rss_mb": p.memory_info().rss / 2**20}
                    except psutil.Error:
                        pass
                samples.append(row)
            time.sleep(0.2)
        sender.wait(timeout=60)
        time.sleep(3.0)  # the last frames and alarms arrive
        live = [k for k in range(workers) if kill is None or k != kill[0]]
        statuses = _query(zep, [f"gcs/fleet/default/status/w{k}" for k in live], host0)
        health = _query(zep, [f"gcs/{s}/health" for s in range(1, n + 1)], host0)
        bridge_rc = procs.stop(bridge, sig=2)
        for k in live:
            procs.stop(wprocs[k], sig=15)
        procs.stop(recorder, sig=2)
        del bridge_rc
    records = [json.loads(ln) for ln in alarms_file.read_text().splitlines() if ln.strip()] \
        if alarms_file.exists() else []
    alarms = [d for d in records if d.get("type") != "status"]
    status_log = [d for d in records if d.get("type") == "status"]
    t0 = json.loads(t0_file.read_text())
    logs = {p.name: p.read_text(errors="replace") for p in tmp.glob("*.log")}
    return FleetResult(alarms=alarms, status_log=status_log, t0_wall_s=t0["t0_wall_s"],
                       onsets=tuple(t0["onsets"]), duration_us=t0.get("duration_us"),
                       n=n, speed=speed, kill_wall_s=kill_wall, samples=samples,
                       health=health, statuses=statuses, bridge_out=logs.get("bridge.log", ""),
                       sender_out=logs.get("sender.log", ""), logs=logs)


def _query(ep: str, keys: Sequence[str], netns: str | None) -> dict[str, Any]:
    import subprocess

    cmd = [PY, "-c", QUERY, ep, *keys]
    if netns is not None:
        cmd = ["ip", "netns", "exec", netns, *cmd]
    from tests.helpers.fleet import ROOT

    r = subprocess.run(cmd, capture_output=True, text=True, timeout=60, cwd=ROOT,
                       env={"PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": "1",
                            "PATH": "/usr/sbin:/usr/bin:/sbin:/bin"})
    if r.returncode != 0:
        return {}
    out: dict[str, Any] = json.loads(r.stdout)
    out["ok"] = [k for k, v in out.items() if v]
    return out


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser()
    sub = p.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("send")
    s.add_argument("templates", type=Path)
    s.add_argument("port", type=int)
    s.add_argument("host")
    s.add_argument("n", type=int)
    s.add_argument("t0_file", type=Path)
    s.add_argument("--speed", type=float, default=1.0)
    s.add_argument("--link-faults", type=float, default=0.0)
    s.add_argument("--seed", type=int, default=0)
    a = p.parse_args(argv)
    send(a.templates, a.port, a.host, a.n, a.t0_file, speed=a.speed,
         link_faults=a.link_faults, seed=a.seed)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
