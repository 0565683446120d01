"""Lu2016 experiments: IMU fault reconstruction (Table 2 scenarios) and the closed loop.

* ``lu2016_table2`` -- GS-KM vs AS-KM and ATSEKF vs IOTSEKF (Lu2016 secs. 3.3-3.5), every run
  simulator -> MAVLink bytes -> :class:`~gcs_monitor.monitor.Monitor`
  (:func:`~gcs_monitor.evaluation.runs.simulate_imu`), scored with the windows of
  :mod:`gcs_monitor.evaluation.scoring`;
* ``closed_loop`` -- the simulator flies on the IMU corrected by the estimator (see
  :class:`ImuInTheLoop`).

Commands and measured tables: docs/results.md.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from gcs_monitor.core.frames import euler_rates
from gcs_monitor.core.units import RAD2DEG
from gcs_monitor.evaluation.configs import lu2016_variants
from gcs_monitor.evaluation.records import AXES, SIM_CHANNELS, ImuRun
from gcs_monitor.evaluation.report import md_table, plot_imu_run, write_csv
from gcs_monitor.evaluation.runner import run_parallel
from gcs_monitor.evaluation.runs import simulate_imu
from gcs_monitor.evaluation.scenarios import TABLE2_PRESETS, closed_loop_scenario, preset
from gcs_monitor.evaluation.scoring import SCORE_DELAY_S, rmse, score_masks
from gcs_monitor.families.imu.imu_ts import FAULT_CHANNELS, ImuTwoStageEstimator, Lu2016Table1
from gcs_monitor.telemetry.frame import Frame, ImuSample
from sim_vehicle.faults.profiles import FaultInjector, FaultSpec
from sim_vehicle.run import make_simulation
from sim_vehicle.scenario import Scenario

LU_NAMES = ("gs_atsekf", "gs_iotsekf", "as_atsekf", "as_iotsekf")


# ------------------------------------------------------------------------------------------------
# Table 2 scenarios
# ------------------------------------------------------------------------------------------------


def _lu_run(job: tuple[str, int]) -> ImuRun:
    name, seed = job
    return simulate_imu(preset(name, seed=seed), variants=lu2016_variants)


def lu2016_table2(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """Per-channel RMSE of the six fault estimates, GS-KM vs AS-KM, ATSEKF vs IOTSEKF.

    Lu2016 secs. 3.3-3.5 scenarios (presets lu2016_calm/shear/turbulence/parabolic, Table 2
    faults 10-30 s). ``quick``: seed 1 only; otherwise seeds 1-3, RMSE averaged over seeds.
    """
    out_dir = Path(out_dir)
    seeds = (1,) if quick else (1, 2, 3)
    args = [(p, s) for p in TABLE2_PRESETS for s in seeds]
    runs = run_parallel(_lu_run, args, jobs, desc="lu2016_table2")
    header = (["scenario", "estimator"] + [f"{a} fault" for a in AXES]
              + [f"{a} quiet" for a in AXES])
    rows: list[list[Any]] = []
    acc_ratio: list[list[Any]] = []
    by: dict[tuple[str, str], list[np.ndarray]] = {}
    for (name, seed), run in zip(args, runs, strict=True):
        inf, quiet = score_masks(run)
        for n in LU_NAMES:
            err = run.f_hat[n] - run.f_true
            by.setdefault((name, n), []).append(
                np.concatenate([rmse(err, inf), rmse(err, quiet)]))
        if seed == seeds[0]:
            plot_imu_run(run, LU_NAMES, out_dir / f"lu2016_table2_{name}.png")
    for name in TABLE2_PRESETS:
        for n in LU_NAMES:
            v = np.mean(by[(name, n)], axis=0)
            rows.append([name, n] + [float(x) for x in v])
        for adapt in ("atsekf", "iotsekf"):
            gs = np.mean(by[(name, f"gs_{adapt}")], axis=0)
            as_ = np.mean(by[(name, f"as_{adapt}")], axis=0)
            acc_ratio.append([name, adapt, float(np.mean(as_[:3]) / np.mean(gs[:3])),
                              float(np.mean(as_[3:6]) / np.mean(gs[3:6]))])
    write_csv(out_dir / "lu2016_table2.csv", header, rows)
    write_csv(out_dir / "lu2016_table2_ratio.csv",
              ["scenario", "filter", "acc_rmse_as_over_gs", "gyro_rmse_as_over_gs"], acc_ratio)
    return (f"Per-channel RMSE of f_hat - f (acc m/s^2, gyro deg/s), fault window "
            f"[t_start+{SCORE_DELAY_S:g} s, t_end] and fault-free ('quiet'), mean over seeds "
            f"{list(seeds)}:\n\n" + md_table(header, rows) + "\n\nAS-KM / GS-KM RMSE ratio in "
            "the fault window (mean over the three channels):\n\n"
            + md_table(["scenario", "filter", "acc AS/GS", "gyro AS/GS"], acc_ratio) + "\n")


# ------------------------------------------------------------------------------------------------
# closed loop: the simulator flies on the (corrected) IMU
# ------------------------------------------------------------------------------------------------

CF_TAU_S = 5.0  # complementary-filter time constant of the autopilot's attitude
CLOSED_LOOP_CASES = (("lu2016_calm", "acc", "level"), ("lu2016_calm", "gyro", "s_turn"))
CLOSED_LOOP_MODES = ("fault-free", "uncorrected", "corrected")


class ImuInTheLoop:
    """``Simulation(feedback=...)``: what the autopilot sees when it flies on the IMU.

    How the faulty IMU enters the autopilot (Lu2016 closed loop, Atmaca2025 Table 4 style):

    * body rates p, q, r of the inner loops = gyro measurement (true + Lu2016 Table 1 noise +
      fault), minus the estimator's f_hat when ``corrected``;
    * roll, pitch and heading = a complementary filter: Euler rates from that gyro integrated,
      roll/pitch pulled toward the accelerometer tilt (phi = atan2(-f_y, -f_z), theta =
      atan2(f_x, sqrt(f_y^2 + f_z^2))) with time constant CF_TAU_S; heading from the gyro alone;
    * the load-factor loop's n_z = accelerometer z (minus f_hat_z when corrected);
    * altitude, airspeed, sideslip stay true (not under test).

    The estimator (the same ImuTwoStageEstimator, GS-KM ATSEKF, as in the monitor) is fed a Frame
    per step built from the faulty IMU, the true attitude and ground velocity plus Lu2016 Table 1
    noise (the independent attitude/GNSS references of Lu2016 sec. 2; velocity at 100 Hz, no GPS
    interpolation) -- in-process, not over MAVLink.
    """

    def __init__(self, faults: tuple[FaultSpec, ...], seed: int, *, corrected: bool) -> None:
        self.inj = FaultInjector(tuple(faults), seed)
        self.channels = set(self.inj.channels)
        self.rng = np.random.default_rng(seed + 7919)
        self.noise = Lu2016Table1()
        self.est = ImuTwoStageEstimator() if corrected else None
        self.att: np.ndarray | None = None
        self.t_prev = 0.0
        self.f_hat = np.zeros(6)

    def _measure(self, st: Any) -> np.ndarray:
        n = self.noise
        x = np.concatenate([st.acc_frd_mps2, st.omega_frd_radps])
        sig = np.array([n.acc_sigma_mps2] * 3 + [n.gyro_sigma_radps] * 3)
        y = x + sig * self.rng.standard_normal(6)
        for i, ch in enumerate(SIM_CHANNELS):
            if ch in self.channels:
                y[i] = self.inj.apply(ch, st.t_s, float(x[i]), float(y[i]))
        return y

    def __call__(self, st: Any) -> Any:
        u = self._measure(st)
        if self.est is not None:
            n = self.noise
            t_us = round(st.t_s * 1e6)
            fr = Frame(t_us=t_us, imu=[ImuSample(t_us, 0, u[:3].copy(), u[3:].copy())],
                       euler_rad=st.euler_rad + n.euler_sigma_rad * self.rng.standard_normal(3),
                       att_age_s=0.0,
                       gps_vel_ned_mps=st.vel_ned_mps + n.vel_sigma_mps
                       * self.rng.standard_normal(3), gps_age_s=0.0,
                       lat_rad=st.lat_rad, lon_rad=st.lon_rad, alt_msl_m=st.alt_m)
            e = self.est.step(fr)
            if e.available and e.numerics_ok:
                self.f_hat = np.array([e.faults[c] for c in FAULT_CHANNELS])
        uc = u - self.f_hat
        acc, w = uc[:3], uc[3:]
        if self.att is None:
            self.att = np.array(st.euler_rad, dtype=np.float64)
        else:
            dt = st.t_s - self.t_prev
            phi, theta, psi = self.att
            self.att = self.att + dt * euler_rates(phi, theta, w)
            tilt = np.array([math.atan2(-acc[1], -acc[2]),
                             math.atan2(acc[0], math.hypot(acc[1], acc[2]))])
            self.att[:2] += (dt / CF_TAU_S) * (tilt - self.att[:2])
            self.att[2] = (self.att[2] + math.pi) % (2 * math.pi) - math.pi
        self.t_prev = st.t_s
        return dataclasses.replace(st, omega_frd_radps=w.copy(), euler_rad=self.att.copy(),
                                   acc_frd_mps2=acc.copy())


def closed_loop_run(sc: Scenario, *, corrected: bool, faulty: bool) -> dict[str, np.ndarray]:
    """Fly ``sc`` with :class:`ImuInTheLoop`; returns the true trajectory (t, alt, tas, phi,
    psi) at every step."""
    sim = make_simulation(sc)
    sim.feedback = ImuInTheLoop(sc.faults if faulty else (), sc.seed,  # type: ignore[attr-defined]
                                corrected=corrected)
    n = round(sc.duration_s / sc.dt_s)
    out = np.zeros((n, 5))
    for k in range(n):
        st = sim.step()
        out[k] = (st.t_s, st.alt_m, st.tas_mps, st.euler_rad[0], st.euler_rad[2])
    return {"t": out[:, 0], "alt": out[:, 1], "tas": out[:, 2], "phi": out[:, 3],
            "psi": out[:, 4]}


def _cl_case(job: tuple[str, str, str, str]) -> dict[str, np.ndarray]:
    name, group, manoeuvre, mode = job
    return closed_loop_run(closed_loop_scenario(name, group, manoeuvre),
                           corrected=mode == "corrected", faulty=mode != "fault-free")


def closed_loop(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """Tracking deviation from the fault-free closed-loop flight (same seed, same autopilot
    sensing) with and without IMU correction, over the fault window (10-30 s)."""
    out_dir = Path(out_dir)
    modes = CLOSED_LOOP_MODES
    args = [(p, o, m, mode) for p, o, m in CLOSED_LOOP_CASES for mode in modes]
    res = run_parallel(_cl_case, args, jobs, desc="closed_loop")
    header = ["faults", "manoeuvre", "IMU to autopilot", "alt RMSE [m]", "TAS RMSE [m/s]",
              "roll RMSE [deg]", "heading RMSE [deg]"]
    rows = []
    for i, (_p, o, m) in enumerate(CLOSED_LOOP_CASES):
        ref = res[3 * i]
        win = (ref["t"] >= 10.0) & (ref["t"] <= 30.0)
        for j, mode in enumerate(modes[1:], start=1):
            r = res[3 * i + j]
            dpsi = (r["psi"] - ref["psi"] + math.pi) % (2 * math.pi) - math.pi
            e = [r["alt"] - ref["alt"], r["tas"] - ref["tas"], (r["phi"] - ref["phi"]) * RAD2DEG,
                 dpsi * RAD2DEG]
            rows.append([f"Table 2 {o}", m, mode]
                        + [float(np.sqrt(np.mean(x[win] ** 2))) for x in e])
    write_csv(out_dir / "closed_loop.csv", header, rows)
    return ("Deviation of the true trajectory from the fault-free closed-loop flight over "
            "10-30 s (see ImuInTheLoop for how the IMU enters the autopilot):\n\n"
            + md_table(header, rows) + "\n")


def experiments() -> dict[str, Callable[[Path, int, bool], str]]:
    return {"lu2016_table2": lu2016_table2, "closed_loop": closed_loop}
