"""Replay speed of a 10-minute simulated flight through the Monitor with both IMU estimators.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_replay_imu.py [--duration 600]
     [--repeat 3] [--cache DIR]

The flight is lu2016_turbulence (Table 2 IMU faults at 10-30 s) with the duration overridden,
written once to a .tlog by the simulator (file mode) and kept in ``--cache``. The replay reads
the .tlog (``TlogSource``), decodes, assembles Frames and runs imu_ts (Lu2016 GS-KM ATSEKF),
imu_hosm (Atmaca2025 OTSEKF+HOSM) and the IMU channel FDI (air-data estimation off), with no
sinks. Each case is warmed up on the first 5 % of the flight (numba kernels loaded), then the
cases run interleaved ``--repeat`` times; the table gives the median wall-clock and CPU-time
(``time.process_time``) speeds. Target >= 50x real time with both estimators.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import tempfile
import time
from pathlib import Path

from gcs_monitor.config import MonitorConfig
from gcs_monitor.link.transports import TlogSource
from gcs_monitor.monitor import Monitor

TARGET_X = 50.0


def flight_tlog(cache: Path, preset: str, duration_s: float) -> Path:
    """The benchmark flight, simulated once and kept in ``cache``."""
    from sim_vehicle.run import run_scenario
    from sim_vehicle.scenario import load_scenario, with_overrides

    sc = with_overrides(load_scenario(preset), duration_s=duration_s)
    path = cache / f"{sc.name}_s{sc.seed}.tlog"
    marker = cache / f"{sc.name}_s{sc.seed}.duration"
    if not (path.exists() and marker.exists() and marker.read_text() == str(duration_s)):
        print(f"simulating {duration_s:.0f} s of {preset} into {cache} ...", flush=True)
        res = run_scenario(sc, cache, progress=False)
        assert res.tlog_path == path, (res.tlog_path, path)
        marker.write_text(str(duration_s))
    return path


def imu_config(ts: bool, hosm: bool) -> MonitorConfig:
    """Both, one or the other IMU estimator, air data judged against its consensus; the
    yaw-rate and actuator families (added since issue 4, benchmarked in bench_replay.py) off."""
    base = MonitorConfig()
    imu = base.family("imu")
    imu = dataclasses.replace(imu, ts=dataclasses.replace(imu.ts, enabled=ts),
                              hosm=dataclasses.replace(imu.hosm, enabled=hosm))
    return (base.with_family("imu", imu).with_family("airdata", estimator="none")
            .with_family("yaw_rate", enabled=False).with_family("actuators", enabled=False))


def replay(chunks: list[tuple[bytes, float]], cfg: MonitorConfig) -> tuple[int, int]:
    """Frames and alarm events of one replay of the chunks."""
    mon = Monitor(cfg)
    for chunk, wall_s in chunks:
        mon.feed(chunk, wall_s)
    mon.finish()
    frames = sum(v.pipeline.frames for v in mon.vehicles.values() if v.pipeline)
    return frames, len(mon.events)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=600.0, help="flight length, s")
    ap.add_argument("--preset", default="lu2016_turbulence")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--cache", type=Path,
                    default=Path(tempfile.gettempdir()) / "gcs_bench_replay_imu")
    args = ap.parse_args()
    args.cache.mkdir(parents=True, exist_ok=True)
    path = flight_tlog(args.cache, args.preset, args.duration)
    with TlogSource(path) as src:
        chunks = list(src)
    cases = [
        ("imu_ts + FDI", imu_config(True, False)),
        ("imu_hosm + FDI", imu_config(False, True)),
        ("imu_ts + imu_hosm + FDI", imu_config(True, True)),
    ]
    print(f"flight: {args.preset}, {args.duration:g} s, tlog {path.stat().st_size / 1e6:.1f} MB; "
          f"load average before: {os.getloadavg()[0]:.1f}", flush=True)
    for _, est in cases:  # warm-up (imports, numba kernels from the disk cache)
        replay(chunks[: max(1, len(chunks) // 20)], est)
    wall: dict[str, list[float]] = {k: [] for k, _ in cases}
    cpu: dict[str, list[float]] = {k: [] for k, _ in cases}
    out: dict[str, tuple[int, int]] = {}
    for _ in range(args.repeat):
        for label, est in cases:
            t, c = time.perf_counter(), time.process_time()
            out[label] = replay(chunks, est)
            wall[label].append(time.perf_counter() - t)
            cpu[label].append(time.process_time() - c)
    print()
    print(f"| replay | wall [s] (median of {args.repeat}) | CPU [s] | frames | alarm events | "
          "x real time, wall | x real time, CPU | target |")
    print("|---|---|---|---|---|---|---|---|")
    for label, _ in cases:
        w, c = statistics.median(wall[label]), statistics.median(cpu[label])
        x = args.duration / w
        flag = ""
        if label == cases[-1][0]:
            flag = f">= {TARGET_X:g}x: {'met' if x >= TARGET_X else 'NOT met'}"
        frames, events = out[label]
        print(f"| {label} | {w:.1f} | {c:.1f} | {frames} | {events} | {x:.1f} | "
              f"{args.duration / c:.1f} | {flag} |")
    print(f"\nload average after: {os.getloadavg()[0]:.1f} (wall-clock needs an idle machine)")


if __name__ == "__main__":
    main()
