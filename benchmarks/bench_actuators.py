"""Actuator family (aircraft tier): per-sample cost per actuator axis, and replay speed with
every default family.

The flight: ``demo_actuator_faults`` (small UAV, S-turn in turbulence, 3 IMUs, triplex air
data, servo outputs at 50 Hz, setpoints at 10 Hz) lengthened to ``--duration`` s, simulated once
into ``--cache``.

* per-sample cost: the Frames are assembled once (decode + FrameAssembler, outside the timing),
  then the aircraft tier runs over them alone; the cost per axis-sample is its time divided by
  the number of axis steps it took (an axis steps at each new control sample: 50 Hz servo
  outputs here, four axes), and the cost per Frame is given beside it;
* replay: the tlog through the Monitor with the actuator family alone and with the default
  families (imu: imu_ts; airdata: cmhe with the weather estimate; actuators), x real time,
  wall clock and CPU time, median of ``--repeat``; target >= 50x with the default families.

    .venv/bin/python benchmarks/bench_actuators.py [--duration S] [--cache DIR] [--repeat N]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from gcs_monitor.config import MonitorConfig  # noqa: E402
from gcs_monitor.families.actuators.aircraft import AircraftTier  # noqa: E402
from gcs_monitor.families.base import FamilyContext  # noqa: E402
from gcs_monitor.link.decode import Decoder  # noqa: E402
from gcs_monitor.link.transports import TlogSource  # noqa: E402
from gcs_monitor.monitor import Monitor  # noqa: E402
from gcs_monitor.telemetry.assembler import FrameAssembler  # noqa: E402

PRESET = "demo_actuator_faults"
TARGET_X = 50.0


def flight_tlog(cache: Path, duration_s: float) -> Path:
    """The benchmark flight, simulated once and kept in ``cache``."""
    from sim_vehicle.run import run_scenario
    from sim_vehicle.scenario import load_scenario

    path = cache / f"{PRESET}_{duration_s:.0f}s.tlog"
    if not path.exists():
        sc = dataclasses.replace(load_scenario(PRESET), duration_s=duration_s)
        res = run_scenario(sc, cache, progress=False)
        assert res.tlog_path is not None
        res.tlog_path.replace(path)
    return path


def frames_of(chunks: list[tuple[bytes, float]]) -> list:
    dec = Decoder()
    asm = FrameAssembler.aligned(stats=dec.vehicle_stats(1))
    out = []
    for data, t in chunks:
        for m in dec.feed(data, t):
            if m._header.srcSystem == 1:
                out += asm.push(m)
    return out + asm.flush()


def tier_pass(frames: list) -> tuple[float, float, int]:
    """(wall s, CPU s, axis steps) of the aircraft tier over the Frames."""
    cfg = MonitorConfig().family("actuators").aircraft
    tier = AircraftTier(cfg, FamilyContext(vehicle=1, stale_after_s=0.5, statuses=False))
    steps = 0
    t, c = time.perf_counter(), time.process_time()
    for f in frames:
        v = tier.judge(f, tier.predict(f))
        tier.update(f, v)
        steps += sum(1 for ax in tier.axes if ax.prev is not None and ax.prev.t_us == f.t_us)
    return time.perf_counter() - t, time.process_time() - c, steps


def replay(chunks: list[tuple[bytes, float]], cfg: MonitorConfig) -> None:
    mon = Monitor(cfg)
    for data, t in chunks:
        mon.feed(data, t)
    mon.finish()


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--duration", type=float, default=300.0, help="flight length, s")
    ap.add_argument("--cache", type=Path,
                    default=Path(tempfile.gettempdir()) / "gcs_bench_actuators")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    args.cache.mkdir(parents=True, exist_ok=True)
    path = flight_tlog(args.cache, args.duration)
    chunks = list(TlogSource(path))
    frames = frames_of(chunks)
    print(f"\n{path.name}: {args.duration:.0f} s, {len(frames)} Frames; load average before: "
          f"{os.getloadavg()[0]:.1f}\n", flush=True)
    tier_pass(frames[: len(frames) // 20])  # warm-up
    runs = [tier_pass(frames) for _ in range(args.repeat)]
    wall = statistics.median(r[0] for r in runs)
    cpu = statistics.median(r[1] for r in runs)
    steps = runs[0][2]
    print(f"| aircraft tier | median of {args.repeat} |")
    print("|---|---|")
    print(f"| axis steps (4 axes; servo outputs 50 Hz) | {steps} |")
    print(f"| per axis-sample, wall / CPU | {1e6 * wall / steps:.1f} / "
          f"{1e6 * cpu / steps:.1f} µs |")
    print(f"| per Frame (100 Hz IMU), wall | {1e6 * wall / len(frames):.1f} µs |")
    print(f"| tier alone, x real time (CPU) | {args.duration / cpu:.0f}x |")
    base = MonitorConfig()
    alone = base.with_family("imu", enabled=False).with_family("airdata", enabled=False)
    stages = [("actuator family alone", alone), ("default families (imu, airdata, actuators)",
                                                 base)]
    for _, cfg in stages:
        replay(chunks[: max(1, len(chunks) // 20)], cfg)  # warm-up
    print("\n| replay | x real time, wall (median) | x real time, CPU (median) | target |")
    print("|---|---|---|---|")
    for label, cfg in stages:
        w, c = [], []
        for _ in range(args.repeat):
            t0, c0 = time.perf_counter(), time.process_time()
            replay(chunks, cfg)
            w.append(args.duration / (time.perf_counter() - t0))
            c.append(args.duration / (time.process_time() - c0))
        med = statistics.median(w)
        flag = ""
        if cfg is base:
            flag = f">= {TARGET_X:.0f}x: {'met' if med >= TARGET_X else 'NOT met'}"
        print(f"| {label} | {med:.0f}x | {statistics.median(c):.0f}x | {flag} |", flush=True)
    print(f"\nload average after: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
