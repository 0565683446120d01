"""Real-time pacing against the wall clock: the simulator's live UDP output and tlog replay.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python -m benchmarks.bench_pacing [--live-s 3]
(from the repository root: the replay input comes from ``tests/helpers/mavgen.py``).

The tests check the pacing schedules exactly on a fake clock; this measures how closely the real
clock follows them on this machine:

* ``UdpSender.pace``: 50 calls 10 ms of vehicle time apart (0.49 s), no other work;
* ``sim-vehicle`` live: ``demo_airdata_faults`` (full physics) for ``--live-s`` s over UDP
  loopback, received and decoded by the monitor's ``Decoder``; wall time from the first to the
  last packet received, ATTITUDE arrival rate against the configured rate, and the share of
  packets received;
* ``TlogSource(speed=...)``: a 2 s synthetic .tlog replayed at 2x and 10x.

Each row: vehicle time, the wall time pacing asks for, the measured wall time and the relative
error (positive = slower than real time x speed). A loaded machine shows up as lateness.
"""

from __future__ import annotations

import argparse
import socket
import tempfile
import threading
import time
from pathlib import Path

from gcs_monitor.link.decode import Decoder
from gcs_monitor.link.transports import TlogSource
from sim_vehicle.mavlink_out import UdpSender
from sim_vehicle.run import run_scenario
from sim_vehicle.scenario import load_scenario, with_overrides
from tests.helpers.mavgen import MavGen, to_tlog

Row = tuple[str, float, float, float, str]  # case, vehicle s, expected wall s, wall s, detail


def udp_sender_row() -> Row:
    s = UdpSender("127.0.0.1", 9)
    late_ms = 0.0
    t0 = time.monotonic()
    for k in range(50):
        s.pace(k * 10_000)
        late_ms = max(late_ms, (time.monotonic() - t0 - k * 0.01) * 1e3)
    wall = time.monotonic() - t0
    s.close()
    return ("UdpSender.pace, 50 x 10 ms", 0.49, 0.49, wall, f"max lateness {late_ms:.2f} ms")


def live_run_row(duration_s: float) -> Row:
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(0.3)
    port = rx.getsockname()[1]
    dec = Decoder()
    attitude_s: list[float] = []
    arrival_s: list[float] = []  # every decoded message
    n_rx = [0]
    stop = threading.Event()

    def receive() -> None:
        while True:
            try:
                data = rx.recv(65536)
            except TimeoutError:
                if stop.is_set():
                    return
                continue
            now = time.monotonic()
            for m in dec.feed(data, now):
                n_rx[0] += 1
                arrival_s.append(now)
                if m.get_type() == "ATTITUDE":
                    attitude_s.append(now)

    th = threading.Thread(target=receive, daemon=True)
    th.start()
    sc = with_overrides(load_scenario("demo_airdata_faults"), duration_s=duration_s)
    with tempfile.TemporaryDirectory() as d:
        res = run_scenario(sc, d, live=True, udp=("127.0.0.1", port), progress=False)
    stop.set()
    th.join()
    rx.close()
    sent = sum(res.counts.values())
    rate_hz = (len(attitude_s) - 1) / (attitude_s[-1] - attitude_s[0])
    detail = (f"ATTITUDE {rate_hz:.1f} Hz (configured {sc.sensors.rates.attitude_hz:g}), "
              f"received {n_rx[0]}/{sent}")
    # first to last packet received (set-up and the truth file are outside)
    return (f"sim-vehicle live, {sc.name}", res.vehicle_duration_s, res.vehicle_duration_s,
            arrival_s[-1] - arrival_s[0], detail)


def tlog_rows(path: Path, span_s: float) -> list[Row]:
    rows = []
    for speed in (2.0, 10.0):
        t0 = time.monotonic()
        n = sum(1 for _ in TlogSource(path, speed=speed, chunk_bytes=2048))
        wall = time.monotonic() - t0
        rows.append((f"TlogSource speed {speed:g}x", span_s, span_s / speed, wall, f"{n} chunks"))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--live-s", type=float, default=3.0, help="live simulator run, vehicle s")
    args = ap.parse_args()
    rows = [udp_sender_row(), live_run_row(args.live_s)]
    packets = MavGen().packets(2.0)
    span_s = (packets[-1][0] - packets[0][0]) * 1e-6
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "pacing.tlog"
        path.write_bytes(to_tlog(packets))
        rows += tlog_rows(path, span_s)
    print("| case | vehicle s | paced wall s | measured wall s | error | detail |")
    print("|---|---|---|---|---|---|")
    for name, vehicle_s, expected_s, wall_s, detail in rows:
        err = (wall_s - expected_s) / expected_s * 100
        print(f"| {name} | {vehicle_s:.2f} | {expected_s:.3f} | {wall_s:.3f} | {err:+.1f} % | "
              f"{detail} |")


if __name__ == "__main__":
    main()
