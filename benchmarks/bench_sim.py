"""File-mode simulator speed: default airframe, all sensors (3 IMUs), median of 3 runs.

Prints x real time for the whole run (physics + sensors + faults + MAVLink + .tlog + truth) and
for the sensor/MAVLink half alone (physics replaced by a replayed state). Target >= 50x.

    .venv/bin/python benchmarks/bench_sim.py [--duration S]
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MAVLINK20", "1")
os.environ.setdefault("MAVLINK_DIALECT", "ardupilotmega")

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
    args = ap.parse_args()
    sc = with_overrides(load_scenario(args.preset), duration_s=args.duration)
    st0 = make_simulation(sc).state()
    rows = []
    with tempfile.TemporaryDirectory() as d:
        full = [run_scenario(sc, d, progress=False).realtime_factor for _ in range(3)]
        rows.append(("full run (physics + output, .tlog + truth)", full))
    phys = []
    for _ in range(3):
        sim = make_simulation(sc)
        n = round(sc.duration_s / sc.dt_s)
        t = time.perf_counter()
        for _ in range(n):
            sim.step()
        phys.append(sc.duration_s / (time.perf_counter() - t))
    rows.append(("physics only", phys))
    out = []
    for _ in range(3):
        t = time.perf_counter()
        n_pk = sum(1 for _ in iter_run(sc, simulation_factory=lambda s: _Replay(s, st0),
                                       record_truth=True))
        out.append(sc.duration_s / (time.perf_counter() - t))
    rows.append((f"sensors + faults + MAVLink ({n_pk / sc.duration_s:.0f} msg/s)", out))
    print(f"{'stage':<48} {'x real time (median of 3)':>26}")
    for name, xs in rows:
        print(f"{name:<48} {statistics.median(xs):>26.1f}")
    med = statistics.median(full)
    print(f"target >= {TARGET_X:.0f}x: {'met' if med >= TARGET_X else 'NOT met'}")


if __name__ == "__main__":
    main()
