"""Per-sample cost of the IOTSEKF / ATSEKF step (Lu2016) against filterpy's EKF on the GS-KM.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_imu_ts.py [--steps N]

All filters see the same 100 Hz synthetic data (a level turn with IMU noise per Lu2016 Table 1)
and the same model code (kinematics.GsKm: Heun propagation, analytic Jacobians, eq. 33-34
series). filterpy's ExtendedKalmanFilter estimates only the 6 states; the two-stage filters
also estimate the 6 IMU faults. Timing covers one full predict+update per sample.
"""

from __future__ import annotations

import argparse
import logging
import math
import time

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter

from gcs_monitor.core.atmosphere import gravity_mps2
from gcs_monitor.families.imu.imu_ts import ImuTsConfig, ImuTwoStageEstimator, Lu2016Table1
from gcs_monitor.filters.two_stage import (
    TwoStageConfig,
    TwoStageNoise,
    discretise_series,
    two_stage_init,
    two_stage_step,
)
from gcs_monitor.models.kinematics import GsKm

log = logging.getLogger(__name__)
DT_S = 0.01
LAT_RAD = math.radians(52.0)
ALT_M = 1000.0


def _data(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    nz = Lu2016Table1()
    model = GsKm(LAT_RAD, ALT_M)
    g = gravity_mps2(LAT_RAD, ALT_M)
    x = np.array([60.0, 0.0, 0.0, 0.2, 0.02, 0.0])
    us, ys = np.zeros((n, 6)), np.zeros((n, 6))
    for k in range(n):
        u = np.array([0.0, g * math.sin(0.2), -g * math.cos(0.2) * math.cos(0.02), 0.0, 0.01, 0.05])
        us[k] = u
        ys[k] = x
        x = model.propagate(x, u, u, DT_S)
    us += rng.normal(size=us.shape) * np.array([nz.acc_sigma_mps2] * 3 + [nz.gyro_sigma_radps] * 3)
    ys += rng.normal(size=ys.shape) * np.array([nz.vel_sigma_mps] * 3 + [nz.euler_sigma_rad] * 3)
    return us, ys


def _stats(ts: list[float]) -> tuple[float, float]:
    a = np.array(ts) * 1e6
    return float(np.median(a)), float(np.percentile(a, 99))


def bench_two_stage(us: np.ndarray, ys: np.ndarray, adapt: bool) -> tuple[float, float]:
    est = ImuTwoStageEstimator(ImuTsConfig(adaptive=adapt))
    noise = TwoStageNoise(Q=est._noise.Q, R=est._noise.R)
    cfg = TwoStageConfig(adapt=adapt)
    s = two_stage_init(
        ys[0], noise.R, np.zeros(6), np.eye(6), est.qf0(DT_S), m=6, window_n=cfg.window_n
    )
    ts = []
    for k in range(1, len(us)):
        t0 = time.perf_counter()
        model = GsKm(LAT_RAD, ALT_M)
        s, innov = two_stage_step(s, model, us[k - 1], us[k], ys[k], DT_S, noise, cfg)
        ts.append(time.perf_counter() - t0)
        assert innov.numerics_ok
    return _stats(ts[20:])  # the first ten steps iterate (Lu2016); exclude the warm-up


def bench_two_stage_packed(us: np.ndarray, ys: np.ndarray) -> tuple[float, float]:
    """The ATSEKF step as ImuTwoStageEstimator runs it: numba GS-KM + one packed filter call."""
    from gcs_monitor.core.kernels import load_kernels
    from gcs_monitor.filters.two_stage import PackedTwoStage

    kin = load_kernels("gcs_monitor.models._kinematics_jit")
    est = ImuTwoStageEstimator(ImuTsConfig())
    noise = TwoStageNoise(Q=est._noise.Q, R=est._noise.R)
    cfg = TwoStageConfig(adapt=True)
    s = two_stage_init(
        ys[0], noise.R, np.zeros(6), np.eye(6), est.qf0(DT_S), m=6, window_n=cfg.window_n
    )
    packed = PackedTwoStage(6, 6, 6, cfg.window_n)
    F, G, xb = np.zeros((6, 6)), np.zeros((6, 6)), np.zeros(6)
    ts = []
    for k in range(1, len(us)):
        t0 = time.perf_counter()
        if s.k < cfg.n_iterated_steps:
            s, innov = two_stage_step(s, GsKm(LAT_RAD, ALT_M), us[k - 1], us[k], ys[k], DT_S,
                                      noise, cfg)
        else:
            g = gravity_mps2(LAT_RAD, ALT_M)
            kin.jacobians(s.x, us[k - 1] - s.f, LAT_RAD, ALT_M, F, G)
            kin.propagate(s.x_bar, us[k - 1], us[k], LAT_RAD, ALT_M, g, DT_S, xb)
            s, innov = packed.step(s, F, G, xb, ys[k], DT_S, noise, cfg)
        ts.append(time.perf_counter() - t0)
        assert innov.numerics_ok
    return _stats(ts[20:])


def bench_filterpy(us: np.ndarray, ys: np.ndarray) -> tuple[float, float]:
    nz = Lu2016Table1()
    Q = np.diag(np.square([nz.acc_sigma_mps2] * 3 + [nz.gyro_sigma_radps] * 3))
    ekf = ExtendedKalmanFilter(dim_x=6, dim_z=6)
    ekf.x = ys[0].copy()
    ekf.R = np.diag(np.square([nz.vel_sigma_mps] * 3 + [nz.euler_sigma_rad] * 3))
    ekf.P = ekf.R.copy()
    state = {"u0": us[0], "u1": us[0], "model": GsKm(LAT_RAD, ALT_M)}

    def predict_x(u: object = 0) -> None:
        ekf.x = state["model"].propagate(ekf.x, state["u0"], state["u1"], DT_S)

    ekf.predict_x = predict_x
    eye6 = np.eye(6)
    ts = []
    for k in range(1, len(us)):
        t0 = time.perf_counter()
        model = GsKm(LAT_RAD, ALT_M)
        state.update(u0=us[k - 1], u1=us[k], model=model)
        F, G = model.jacobians(ekf.x, us[k - 1])
        Phi, Gam = discretise_series(F, G, DT_S)
        ekf.F = Phi
        ekf.Q = Gam @ Q @ Gam.T
        ekf.predict()
        ekf.update(ys[k], lambda x: eye6, lambda x: x)
        ts.append(time.perf_counter() - t0)
    return _stats(ts[20:])


def bench_estimator(us: np.ndarray, ys: np.ndarray) -> tuple[float, float]:
    from gcs_monitor.telemetry.frame import Frame, ImuSample

    est = ImuTwoStageEstimator(ImuTsConfig())
    frames = [
        Frame(
            t_us=k * 10_000,
            imu=[ImuSample(k * 10_000, 0, us[k, :3], us[k, 3:])],
            euler_rad=ys[k, 3:],
            att_age_s=0.0,
            gps_vel_ned_mps=ys[k, :3],
            gps_age_s=0.0,
            lat_rad=LAT_RAD,
            alt_msl_m=ALT_M,
        )
        for k in range(len(us))
    ]
    ts = []
    for fr in frames:
        t0 = time.perf_counter()
        est.step(fr)
        ts.append(time.perf_counter() - t0)
    return _stats(ts[20:])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    us, ys = _data(np.random.default_rng(args.seed), args.steps)
    rows = [
        ("filterpy EKF (6 states)", bench_filterpy(us, ys)),
        ("IOTSEKF step (6 states + 6 faults)", bench_two_stage(us, ys, adapt=False)),
        ("ATSEKF step (6 states + 6 faults)", bench_two_stage(us, ys, adapt=True)),
        ("ATSEKF step, packed kernel (estimator hot path)", bench_two_stage_packed(us, ys)),
        ("ImuTwoStageEstimator.step (ATSEKF + Frame I/O)", bench_estimator(us, ys)),
    ]
    ref = rows[0][1][0]
    print(f"| filter (median of {args.steps - 21} steps) | median µs | p99 µs | "
          "ratio to filterpy |")
    print("|---|---|---|---|")
    for name, (med, p99) in rows:
        print(f"| {name} | {med:.1f} | {p99:.1f} | {med / ref:.2f} |")
    worst = max(med / ref for _, (med, _) in rows[1:])
    print(f"\ntarget: every two-stage row / filterpy EKF <= 1: worst {worst:.2f}, "
          f"{'met' if worst <= 1.0 else 'NOT met'}")


if __name__ == "__main__":
    main()
