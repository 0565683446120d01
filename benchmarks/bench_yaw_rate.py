"""Per-sample cost of the Chen2020 LPV sliding-mode observer (yaw_rate family).

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_yaw_rate.py [--steps N]

Rows: one ``smo_step`` (eqs. 3, 6, 7, 21 on the affine stacks of the shipped transport design);
``YawRateEstimator.step`` (the observer plus Frame I/O and the Estimate); the family's
predict + judge + update on every Frame of a 100 Hz stream (the observer steps every second
Frame, Chen2020's 50 Hz). Synthetic Frames from the design's own linear model.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from gcs_monitor.families.base import FamilyContext
from gcs_monitor.families.yaw_rate.config import YawRateFamilyConfig
from gcs_monitor.families.yaw_rate.design import load_design
from gcs_monitor.families.yaw_rate.estimator import YawRateEstimator
from gcs_monitor.families.yaw_rate.family import YawRateFamily
from gcs_monitor.filters.lpv_smo import smo_init, smo_matrices, smo_step
from gcs_monitor.telemetry.frame import Frame, ImuSample


def _frames(n: int) -> list[Frame]:
    model = load_design("transport").model
    A, B, _ = model.matrices(120.0)
    rng = np.random.default_rng(0)
    x = np.zeros(4)
    out = []
    for k in range(n):
        u = rng.normal(0.0, 0.01, 2) - np.array([0.5 * x[0] + 0.5 * x[2], -x[3]])
        t = k * 10_000
        out.append(Frame(t_us=t, imu=[ImuSample(t, 0, np.zeros(3), np.array([x[2], 0.0, x[3]]))],
                         euler_rad=np.array([x[0], 0.0, 0.0]), att_age_s=0.0, ssa_rad=x[1],
                         cas_mps=np.full(3, 120.0), cas_age_s=np.zeros(3), baro_alt_m=0.0,
                         surf_pos_rad=np.array([u[0], 0.0, u[1]]), surf_age_s=0.0))
        x = x + 0.01 * (A @ x + B @ u)
    return out


def _stats(ts: list[float]) -> tuple[float, float]:
    a = np.array(ts) * 1e6
    return float(np.median(a)), float(np.percentile(a, 99))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=6000)
    args = ap.parse_args()
    frames = _frames(args.steps)
    d = load_design("transport")
    mats = smo_matrices(d.model.A, d.model.B, d.model.c, d.sensors["r"])
    y = np.array([0.01, 0.0, 0.0, 0.01])
    s = smo_init(mats, y)
    ts = []
    for f in frames:
        yp = np.array([f.euler_rad[0], f.ssa_rad, f.imu[0].omega_frd_radps[0],
                       f.imu[0].omega_frd_radps[2]])
        u = f.surf_pos_rad[[0, 2]]
        t0 = time.perf_counter()
        s, _ = smo_step(s, mats, yp, u, (120.0, 14400.0), 0.01)
        ts.append(time.perf_counter() - t0)
    rows = [("smo_step (observer, eqs. 3-21)", _stats(ts))]
    est = YawRateEstimator(YawRateFamilyConfig())
    ts = []
    for f in frames:
        t0 = time.perf_counter()
        est.step(f)
        ts.append(time.perf_counter() - t0)
    rows.append(("YawRateEstimator.step (observer + Frame I/O)", _stats(ts)))
    fam = YawRateFamily(YawRateFamilyConfig(), FamilyContext(vehicle=1, stale_after_s=0.5,
                                                             statuses=False))
    ts = []
    for f in frames:
        t0 = time.perf_counter()
        v = fam.judge(f, fam.predict(f))
        fam.update(f, v)
        ts.append(time.perf_counter() - t0)
    med, p99 = _stats(ts)
    mean = float(np.mean(ts)) * 1e6
    rows.append(("family predict+judge+update per 100 Hz Frame (steps at 50 Hz)", (med, p99)))
    print(f"| stage (median of {args.steps} samples) | median µs | p99 µs |")
    print("|---|---|---|")
    for name, (m, p) in rows:
        print(f"| {name} | {m:.1f} | {p:.1f} |")
    print(f"\nfamily: mean {mean:.1f} µs per Frame = {mean * 100 / 1e6 * 100:.2f} % of real time "
          f"at 100 Hz ({1e6 / (mean * 100):.0f}x real time alone)")
    assert math.isfinite(mean)


if __name__ == "__main__":
    main()
