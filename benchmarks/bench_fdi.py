"""Per-step cost of ``RedundantSetMonitor.step`` on a triplex set (n = 3), CPU time.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_fdi.py [--steps 2000] [--chunks 10]

Triplex AoA at 100 Hz (noise 0.002 rad, J_th = 4 sigma, fault-free), stepped with and without a
model reference (the Wan2018 eq. 17 prediction). Each row is the best of ``--chunks`` passes of
``--steps`` steps, in ``time.process_time`` (on a shared machine wall time is not this process's
cost). Target: < 15 µs per step, so that replay runs at >= 100x real time with every set.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from gcs_monitor.fdi.monitor import RedundantSetMonitor, SetMonitorParams

DT_US = 10_000
SIGMA = 0.002  # rad, vane noise 1-sigma
PARAMS = SetMonitorParams(threshold=4 * SIGMA, noise_sigma=SIGMA, runaway_rate_per_s=0.02)
TARGET_US = 15.0


def _truth(n: int) -> np.ndarray:
    t_s = np.arange(n) * DT_US * 1e-6
    return 0.05 + 0.03 * np.sin(2 * np.pi * 0.2 * t_s)  # manoeuvring AoA, rad


def bench(n_steps: int, n_chunks: int) -> list[tuple[str, float, float]]:
    """Rows (case, best µs per step, median µs per step), CPU time."""
    truth = _truth(n_steps)
    y = truth[:, None] + np.random.default_rng(11).normal(0.0, SIGMA, (n_steps, 3))
    rows = [y[k] for k in range(n_steps)]
    valid = np.ones(3, dtype=bool)
    out = []
    for name, ref in (
        ("no reference", [None] * n_steps),
        ("with reference (eq. 17)",
         (truth + np.random.default_rng(12).normal(0.0, 0.5 * SIGMA, n_steps)).tolist()),
    ):
        mon = RedundantSetMonitor("aoa", 3, PARAMS)
        per_step = []
        for c in range(n_chunks):  # one monitor, vehicle time running on across the passes
            k0 = c * n_steps
            t0 = time.process_time()
            for k in range(n_steps):
                mon.step((k0 + k) * DT_US, rows[k], valid, ref[k])
            per_step.append((time.process_time() - t0) / n_steps * 1e6)
        out.append((name, min(per_step), float(np.median(per_step))))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--steps", type=int, default=2000, help="steps per pass (100 Hz)")
    ap.add_argument("--chunks", type=int, default=10, help="passes; the best one is reported")
    args = ap.parse_args()
    rows = bench(args.steps, args.chunks)
    print(f"RedundantSetMonitor.step, n = 3, {args.steps} steps x {args.chunks} passes, CPU time")
    print(f"| case | best µs/step | median µs/step | target < {TARGET_US:.0f} µs |")
    print("|---|---|---|---|")
    for name, best, med in rows:
        print(f"| {name} | {best:.2f} | {med:.2f} | {'met' if best < TARGET_US else 'NOT met'} |")
    worst = max(best for _, best, _ in rows)
    print(f"at 100 Hz one set costs {worst / DT_US * 100:.2f} % of real time "
          f"({DT_US / worst:.0f}x real time)")


if __name__ == "__main__":
    main()
