"""RerunSink cost per published frame (100 Hz frames, .rrd file sink), wall and CPU time.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_rerun_sink.py [--frames 2000]

Each frame carries one IMU sample, attitude and position, one ``imu_ts`` estimate, two triplex
AoA set statuses and three IMU channel statuses; the sink decimates plots to ``plot_rate_hz`` and
batches them with ``send_columns``. ``close()`` (flush to disk) is outside the timed loop and
reported on its own. CPU time includes rerun's encoder threads. Budget: < 1 ms per 100 Hz
publish on a loaded 2-core machine.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from dashboards.blueprints import default_blueprint
from gcs_monitor.core.types import ChannelId
from gcs_monitor.fdi.events import ChannelStatus, SetStatus
from gcs_monitor.fdi.records import Estimate, StepOutput
from gcs_monitor.sinks.rerun_sink import RerunSink
from gcs_monitor.telemetry.frame import Frame, ImuSample

BUDGET_US = 1000.0
DT_US = 10_000  # 100 Hz frames


def _frame(t_us: int) -> Frame:
    return Frame(t_us=t_us, imu=[ImuSample(t_us, 0, np.array([0.1, 0.0, -9.8]), np.zeros(3))],
                 euler_rad=np.array([0.1, 0.05, 1.0]), lat_rad=0.8 + t_us * 1e-12, lon_rad=0.14,
                 alt_msl_m=300.0)


def _set(t_us: int) -> SetStatus:
    return SetStatus("aoa", t_us, (0.05, 0.051, 0.05), 0.05, 0.0505, (0.5, 0.5, 0.0),
                     (0.001, 0.001, 0.0), 0.01, (False, False, False), "duplex")


def run(rrd: Path, n_frames: int, plot_rate_hz: float) -> tuple[float, float, float, int]:
    """(wall µs per publish, CPU µs per publish, close s, rows sent) for one sink."""
    sink = RerunSink(1, rrd_path=rrd, plot_rate_hz=plot_rate_hz, blueprint=default_blueprint(1))
    est = Estimate("imu_ts", 0, states={"vel_ned_mps": np.zeros(3)},
                   faults={ChannelId("acc", 0, "x"): 0.2})
    ch = [ChannelStatus(ChannelId("acc", 0, a), 0, 0.2, 0.15, 0.3, False, "imu_ts") for a in "xyz"]
    w, c = time.perf_counter(), time.process_time()
    for k in range(n_frames):
        t_us = k * DT_US
        sink.publish(_frame(t_us), StepOutput(estimates=[est], sets=[_set(t_us), _set(t_us)],
                                              channels=ch))
    wall_us = (time.perf_counter() - w) / n_frames * 1e6
    cpu_us = (time.process_time() - c) / n_frames * 1e6
    t = time.perf_counter()
    sink.close()
    return wall_us, cpu_us, time.perf_counter() - t, sink.n_rows_sent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--frames", type=int, default=2000, help="100 Hz frames per run")
    ap.add_argument("--repeat", type=int, default=3, help="runs per row (median)")
    args = ap.parse_args()
    print(f"RerunSink.publish, {args.frames} frames at 100 Hz, median of {args.repeat} runs")
    print(f"| plot rate | µs/publish wall | µs/publish CPU | close s | rows sent | "
          f"budget < {BUDGET_US:.0f} µs |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as d:
        for rate_hz in (20.0, 100.0):
            runs = [run(Path(d) / f"r{rate_hz:.0f}_{i}.rrd", args.frames, rate_hz)
                    for i in range(args.repeat)]
            wall, cpu, close_s = (statistics.median(r[i] for r in runs) for i in range(3))
            verdict = "met" if wall < BUDGET_US else "NOT met"
            print(f"| {rate_hz:.0f} Hz | {wall:.0f} | {cpu:.0f} | {close_s:.2f} | {runs[0][3]} | "
                  f"{verdict} |")


if __name__ == "__main__":
    main()
