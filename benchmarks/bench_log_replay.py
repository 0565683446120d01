"""Reading speed of autopilot logs: ArduPilot .bin and PX4 .ulg replayed with the default
families (issue 16 target: >= 50x real time).

Each log goes through ``gcs_monitor.link.logs.open_log`` (reader -> contract MAVLink bytes) and
a default ``Monitor`` (decode, Frames, the imu and airdata families), as ``gcs-monitor replay``
runs it. A warm-up replay loads the numba kernels first; then each log is replayed
``--repeat`` times and the median wall time is reported, with the reading stage alone
(reader + packing + decoding, no Monitor) beside it.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_log_replay.py [--data-dir DIR]
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

from gcs_monitor.config import MonitorConfig
from gcs_monitor.evaluation.data import real_data_dir
from gcs_monitor.link.decode import Decoder
from gcs_monitor.link.logs import open_log
from gcs_monitor.monitor import Monitor

TARGET_X = 50.0
LOGS = ("ardupilot_bin/erle_copter_16.BIN", "ardupilot_bin/erle_copter_loiter_rtl.bin",
        "px4_ulog/pyulog_sample.ulg",
        "px4_ulog/pyulog_sample_logging_tagged_and_default_params.ulg")


def replay(path: Path) -> tuple[float, float]:
    t0 = time.perf_counter()
    opened = open_log(path)
    mon = Monitor(MonitorConfig())
    for data, wall in opened.source:
        mon.feed(data, wall)
    mon.finish()
    return time.perf_counter() - t0, opened.info.duration_s


def read_only(path: Path) -> float:
    t0 = time.perf_counter()
    dec = Decoder()
    for data, wall in open_log(path).source:
        dec.feed(data, wall)
    return time.perf_counter() - t0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--data-dir", type=Path, default=None)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    root = real_data_dir(args.data_dir) if args.data_dir else real_data_dir()
    logs = [root / p for p in LOGS if (root / p).exists()]
    if not logs:
        print(f"no logs under {root} (give --data-dir or GCS_DATA_DIR)")
        return 0
    replay(logs[0])  # warm-up: numba kernels from the disk cache
    print(f"load average {os.getloadavg()[0]:.1f}; median of {args.repeat}\n")
    print("| log | flight (s) | read + decode, x real time | replay (default families), wall (s) "
          "| x real time | target |")
    print("|---|---|---|---|---|---|")
    ok = True
    for p in logs:
        walls = []
        dur = 0.0
        for _ in range(args.repeat):
            w, dur = replay(p)
            walls.append(w)
        w = statistics.median(walls)
        r = statistics.median(read_only(p) for _ in range(args.repeat))
        x = dur / w
        ok &= x >= TARGET_X
        print(f"| `{p.relative_to(root)}` | {dur:.0f} | {dur / r:.0f}x | {w:.2f} | {x:.0f}x | "
              f">= {TARGET_X:.0f}x: {'met' if x >= TARGET_X else 'NOT met'} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
