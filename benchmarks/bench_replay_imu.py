"""Replay speed of a 10-minute simulated flight through the Monitor with both IMU estimators.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_replay_imu.py [--duration 600]

The flight is lu2016_turbulence (Table 2 IMU faults at 10-30 s) with the duration overridden,
written once to a .tlog by the simulator (file mode). The replay reads the .tlog
(``TlogSource``), decodes, assembles Frames and runs imu_ts (Lu2016 GS-KM ATSEKF), imu_hosm
(Atmaca2025 OTSEKF+HOSM) and the IMU channel FDI (air-data estimation off). The timing is the
replay only; target >= 50x real time.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from gcs_monitor.config import MonitorConfig
from gcs_monitor.config.loader import EstimatorsConfig
from gcs_monitor.link.transports import TlogSource
from gcs_monitor.monitor import Monitor
from sim_vehicle.run import run_scenario
from sim_vehicle.scenario import load_scenario, with_overrides

TARGET_X = 50.0


def replay(tlog: Path, est: EstimatorsConfig) -> tuple[float, int, int]:
    """Wall seconds, frames and alarm events of one replay."""
    frames = 0

    def count(sysid: int, frame: object, step: object) -> None:
        nonlocal frames
        frames += 1

    mon = Monitor(MonitorConfig(estimators=est), on_step=count)
    t0 = time.perf_counter()
    with TlogSource(tlog) as src:
        for chunk, _ in src:
            mon.feed(chunk)
    mon.finish()
    return time.perf_counter() - t0, frames, len(mon.events)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=600.0, help="flight length, s")
    ap.add_argument("--preset", default="lu2016_turbulence")
    args = ap.parse_args()
    sc = with_overrides(load_scenario(args.preset), duration_s=args.duration)
    with tempfile.TemporaryDirectory() as td:
        t0 = time.perf_counter()
        res = run_scenario(sc, td, progress=False)
        sim_s = time.perf_counter() - t0
        assert res.tlog_path is not None
        size = res.tlog_path.stat().st_size
        cases = [
            ("imu_ts + FDI", EstimatorsConfig(imu_ts=True, imu_hosm=False, airdata="none")),
            ("imu_hosm + FDI", EstimatorsConfig(imu_ts=False, imu_hosm=True, airdata="none")),
            ("imu_ts + imu_hosm + FDI",
             EstimatorsConfig(imu_ts=True, imu_hosm=True, airdata="none")),
        ]
        print(f"flight: {sc.name}, {args.duration:g} s, tlog {size / 1e6:.1f} MB "
              f"(simulated in {sim_s:.1f} s)")
        print()
        print("| replay | wall [s] | frames | alarm events | x real time | target |")
        print("|---|---|---|---|---|---|")
        for label, est in cases:
            wall, frames, events = replay(res.tlog_path, est)
            x = args.duration / wall
            ok = "met" if x >= TARGET_X else "NOT met"
            print(f"| {label} | {wall:.1f} | {frames} | {events} | {x:.1f} | {TARGET_X:g}x {ok} |")


if __name__ == "__main__":
    main()
