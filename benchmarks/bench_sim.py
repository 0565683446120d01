"""File-mode simulator speed: default airframe, all sensors (3 IMUs), median of 3 runs.

Prints x real time for the whole run (physics + sensors + faults + MAVLink + .tlog + truth) and
for the sensor/MAVLink half alone (physics replaced by a replayed state). Target >= 50x (wall).
The CPU column (process time) is the same ratio with the time this process was not running
removed: on a shared machine it is the steadier number.

    .venv/bin/python benchmarks/bench_sim.py [--duration S] [--preset NAME] [--airframe uav]
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

from sim_vehicle.mavlink_out import TlogWriter  # noqa: E402
from sim_vehicle.run import iter_run, make_simulation, run_scenario  # noqa: E402
from sim_vehicle.scenario import load_scenario, with_overrides  # noqa: E402

TARGET_X = 50.0


class _Replay:
    """Physics stand-in that replays one precomputed state (isolates the output half)."""

    def __init__(self, sc: object, st: object) -> None:
        self.dt_s = 0.01
        self._st = st

    def state(self):  # noqa: ANN201
        return self._st

    def step(self):  # noqa: ANN201
        return self._st


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--preset", default="demo_airdata_faults")
    ap.add_argument("--airframe", default=None, help="override the preset's airframe")
    args = ap.parse_args()
    sc = with_overrides(load_scenario(args.preset), duration_s=args.duration)
    if args.airframe:
        sc = dataclasses.replace(sc, airframe=args.airframe)
    st0 = make_simulation(sc).state()  # also loads the compiled kernels (numba disk cache)
    rows = []

    def timed(fn) -> tuple[float, float]:  # noqa: ANN001
        w, c = time.perf_counter(), time.process_time()
        fn()
        return sc.duration_s / (time.perf_counter() - w), sc.duration_s / (
            time.process_time() - c)

    with tempfile.TemporaryDirectory() as d:
        wall = [run_scenario(sc, d, progress=False).realtime_factor for _ in range(3)]

        def loop() -> None:  # run_scenario's timed loop, for its CPU time
            with TlogWriter(Path(d) / "cpu.tlog") as w:
                for t_us, _, pkt in iter_run(sc, record_truth=True):
                    w.write(t_us, pkt)

        cpu = [timed(loop)[1] for _ in range(3)]
        full = list(zip(wall, cpu, strict=True))
        rows.append(("full run (physics + output, .tlog + truth)", full))

    def physics() -> None:
        sim = make_simulation(sc)
        for _ in range(round(sc.duration_s / sc.dt_s)):
            sim.step()

    rows.append(("physics only", [timed(physics) for _ in range(3)]))
    n_pk = [0]

    def output() -> None:
        n_pk[0] = sum(1 for _ in iter_run(sc, simulation_factory=lambda s: _Replay(s, st0),
                                          record_truth=True))

    out = [timed(output) for _ in range(3)]
    rows.append((f"sensors + faults + MAVLink ({n_pk[0] / sc.duration_s:.0f} msg/s)", out))
    print(f"{sc.name}, airframe {sc.airframe}, {sc.sensors.n_imu} IMU, {sc.duration_s:g} s")
    print(f"{'stage':<48} {'x real time (median of 3)':>26} {'CPU':>8}")
    for name, xs in rows:
        wall = statistics.median(x[0] for x in xs)
        cpu = statistics.median(x[1] for x in xs)
        print(f"{name:<48} {wall:>26.1f} {cpu:>8.1f}")
    med = statistics.median(x[0] for x in full)
    print(f"target >= {TARGET_X:.0f}x: {'met' if med >= TARGET_X else 'NOT met'}")


if __name__ == "__main__":
    main()
