"""Cost of one simulator physics step (``Simulation.step``, 10 ms), per airframe and wind.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_sim_step.py [--steps 1000]

Physics only (6-DOF, autopilot, servos, wind), no sensors or MAVLink: ``bench_sim.py`` times the
whole run. The first ``--warm`` steps (numba kernels loaded from the disk cache) are excluded;
rows give the median of ``--repeat`` passes, wall and CPU time. Target on an idle core: < 150 µs
per step.
"""

from __future__ import annotations

import argparse
import statistics
import time

from sim_vehicle.physics import Simulation, WindConfig

TARGET_US = 150.0
WINDS = ("calm", "turbulence", "shear+turbulence")


def bench(airframe: str, wind: str, n_steps: int, n_warm: int, repeat: int) -> tuple[float, float]:
    """(wall, CPU) µs per step, median of ``repeat`` passes."""
    sim = Simulation(airframe, wind=WindConfig(kind=wind))
    for _ in range(n_warm):
        sim.step()
    wall, cpu = [], []
    for _ in range(repeat):
        w, c = time.perf_counter(), time.process_time()
        for _ in range(n_steps):
            sim.step()
        wall.append((time.perf_counter() - w) / n_steps * 1e6)
        cpu.append((time.process_time() - c) / n_steps * 1e6)
    return statistics.median(wall), statistics.median(cpu)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--steps", type=int, default=1000, help="steps per pass (10 s of flight)")
    ap.add_argument("--warm", type=int, default=100, help="steps run first, not timed")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    print(f"Simulation.step, {args.steps} steps x {args.repeat} passes (median)")
    print(f"| airframe | wind | µs/step wall | µs/step CPU | x real time (CPU) | "
          f"target < {TARGET_US:.0f} µs |")
    print("|---|---|---|---|---|---|")
    for airframe in ("uav", "transport"):
        for wind in WINDS:
            wall, cpu = bench(airframe, wind, args.steps, args.warm, args.repeat)
            verdict = "met" if cpu < TARGET_US else "NOT met"
            print(f"| {airframe} | {wind} | {wall:.0f} | {cpu:.0f} | {10_000 / cpu:.0f}x | "
                  f"{verdict} |")


if __name__ == "__main__":
    main()
