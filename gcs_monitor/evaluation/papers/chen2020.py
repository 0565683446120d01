"""Chen2020 experiments: the LPV sliding-mode observer of the yaw_rate family.

* ``chen2020_design`` -- the LPV fit of the simulator's lateral dynamics (eq. 59) and the LMI
  design with its L2-gain bounds (:mod:`~gcs_monitor.evaluation.papers.chen2020_design`);
* ``chen2020_ftc`` -- the four flight-test cases (fault-free, slow drift 0.1 deg/s^2, fast drift
  0.4 deg/s^2, both capped at 5 deg/s, 0.02 Hz 2 deg/s sine; from 30 s) in light turbulence,
  closed loop: the autopilot flies on the measured yaw rate, with and without the observer's
  correction (Chen2020 Fig. 1), reconstruction error, ``||e_y||`` and roll / sideslip tracking;
* ``chen2020_open_loop`` -- the same faults only in the published telemetry, through MAVLink
  bytes and the Monitor with its default families: reconstruction error, alarms and delays;
* ``chen2020_false_alarms`` -- fault-free S-turns, coordinated turns and doublets in turbulence
  up to sigma 3.54 m/s: the worst fault-free J of the reconstructed fault (the threshold's
  calibration) and the false alarms of every default family;
* ``chen2020_roll_rate`` -- the same observer class on the roll-rate gyro;
* ``chen2020_uav`` -- the simulator's nominal default airframe (the UAV) under the defaults
  (the transport's design: not judged, and why) and under a configuration ``calibrate`` made
  from clean UAV flights (its identified lateral model and its own J_th).

Commands and measured tables: docs/results.md, "Yaw-rate family: Chen2020".
"""

from __future__ import annotations

import collections
import dataclasses
import json
import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from gcs_monitor.calibrate import calibrate, calibration_toml
from gcs_monitor.config import MonitorConfig
from gcs_monitor.core.atmosphere import tas_from_cas
from gcs_monitor.core.types import ChannelId
from gcs_monitor.core.units import RAD2DEG
from gcs_monitor.evaluation.configs import family_alone
from gcs_monitor.evaluation.papers.chen2020_design import (
    ENVELOPES,
    closed_loop_bounds,
    design_text,
    make_smc,
    write_design,
)
from gcs_monitor.evaluation.report import md_table, pyplot, write_csv
from gcs_monitor.evaluation.runner import run_parallel
from gcs_monitor.evaluation.runs import feed_packets
from gcs_monitor.evaluation.scoring import rms_finite
from gcs_monitor.families.yaw_rate.config import ObserverConfig, YawRateFamilyConfig
from gcs_monitor.families.yaw_rate.design import ObserverDesign, load_bands
from gcs_monitor.families.yaw_rate.estimator import EY_CHANNEL, YawRateEstimator
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState
from gcs_monitor.models.lateral import eas_from_tas, identify_lateral_model
from gcs_monitor.monitor import Monitor
from gcs_monitor.telemetry.frame import Frame, ImuSample
from sim_vehicle.dynamics.linearise import lateral_lti
from sim_vehicle.faults.profiles import FaultInjector, FaultSpec
from sim_vehicle.run import RunState, iter_run, make_simulation, run_scenario
from sim_vehicle.scenario import Scenario, load_scenario
from sim_vehicle.sensors.noise import LU2016

CASES = ("chen2020_fault_free", "chen2020_slow_drift", "chen2020_fast_drift", "chen2020_sine")
FAULT_T0_S = 30.0
EST = "yaw_rate_smo"


@dataclasses.dataclass
class OpenLoopRun:
    """What a monitored run gives the scores (SI)."""

    name: str
    t_s: np.ndarray  # observer steps
    f_hat: np.ndarray
    e_y: np.ndarray
    f_true_t: np.ndarray  # the simulator's fault log of the monitored channel
    f_true: np.ndarray
    events: list[AlarmEvent]
    j_max: float  # worst J of the yaw-rate channel while judged
    judged: int = 0  # Frames with a sample of the family's stream that it judged
    samples: int = 0  # Frames with a sample of the family's stream
    reasons: collections.Counter[str] = dataclasses.field(
        default_factory=collections.Counter)  # why not judged, per such Frame

    def truth_at(self, t: np.ndarray) -> np.ndarray:
        if self.f_true_t.size == 0:
            return np.zeros_like(t)
        return np.asarray(np.interp(t, self.f_true_t, self.f_true, left=0.0,
                                    right=float(self.f_true[-1])), dtype=np.float64)


class _Capture:
    def __init__(self, axis: str) -> None:
        self.axis = axis
        self.rows: list[tuple[float, float, float]] = []
        self.events: list[AlarmEvent] = []
        self.j_max = 0.0
        self.judged = 0
        self.samples = 0
        self.reasons: collections.Counter[str] = collections.Counter()

    def __call__(self, sysid: int, frame: Any, step: Any) -> None:
        self.events += step.events
        for st in step.families:
            if st.family == "yaw_rate" and st.sample:
                self.samples += 1
                self.judged += st.judged
                if not st.judged:
                    # the speed varies within one reason; the first words say which it is
                    self.reasons[re.sub(r"EAS \d+ m/s", "EAS", st.reason)] += 1
        for e in step.estimates:
            if e.name == EST and e.available and e.t_us == frame.t_us:
                (v,) = e.faults.values()
                self.rows.append((frame.t_us * 1e-6, v, e.residuals[EY_CHANNEL]))
        for cs in step.channels:
            if cs.estimator == EST and cs.rms > self.j_max:
                self.j_max = cs.rms


def monitor_config(sensor: str = "r", design: str = "transport") -> MonitorConfig:
    base = MonitorConfig()
    return base.with_family("yaw_rate", sensor=sensor, design=design)


def open_loop_run(sc: Scenario, cfg: MonitorConfig | None = None, *,
                  sensor: str = "r") -> OpenLoopRun:
    """Simulate ``sc`` (faults only in the published telemetry), monitor it over MAVLink."""
    cfg = cfg if cfg is not None else monitor_config(sensor)
    cap = _Capture(sensor)
    rs = RunState()
    mon = Monitor(cfg, on_step=cap)
    feed_packets(mon, (pkt for _, _, pkt in iter_run(sc, run_state=rs)))
    a = np.array(cap.rows) if cap.rows else np.zeros((0, 3))
    log = rs.suite.fault_log.get(f"imu0.gyro.{sensor}") if rs.suite is not None else None
    ft = np.array(log[0]) if log else np.zeros(0)
    fv = np.array(log[1]) if log else np.zeros(0)
    return OpenLoopRun(sc.name, a[:, 0], a[:, 1], a[:, 2], ft, fv, cap.events, cap.j_max,
                       cap.judged, cap.samples, cap.reasons)


def sensor_alarms(events: list[AlarmEvent]) -> list[AlarmEvent]:
    return [e for e in events if e.state is AlarmState.RAISED
            and e.kind is AlarmKind.SENSOR_FAULT]


def observer_alarms(events: list[AlarmEvent], ch: ChannelId) -> list[AlarmEvent]:
    """The yaw-rate observer's sensor-fault events on ``ch``: its confirmation is RAISED, or
    UPDATED when another estimator (imu_ts, which judges the same gyro channel) raised the
    channel's one published alarm first (``Monitor``: one alarm per channel)."""
    return [e for e in events if e.channel == ch and e.estimator == EST
            and e.kind is AlarmKind.SENSOR_FAULT
            and e.state in (AlarmState.RAISED, AlarmState.UPDATED)]


# ------------------------------------------------------------------------------------------------
# closed loop: the autopilot flies on the (corrected) gyro -- Chen2020 Fig. 1
# ------------------------------------------------------------------------------------------------

FTC_MODES = ("fault-free", "uncorrected", "corrected")


class LateralGyroInTheLoop:
    """``Simulation(feedback=...)``: the autopilot's yaw (or roll) rate is the gyro measurement
    (true + Lu2016 Table 1 noise + fault), minus the observer's fault estimate when
    ``corrected`` (Chen2020 eq. 24, the sensor-FTC loop of Fig. 1).

    The observer (the yaw_rate family's :class:`YawRateEstimator`, its stored design) is fed a
    Frame per observer step built from the faulty gyro, roll angle and sideslip with Lu2016
    Table 1 noise, the surface positions and the true CAS -- in-process, not over MAVLink. Roll
    angle, sideslip and the other rates reach the autopilot true (not under test).
    """

    def __init__(self, faults: tuple[FaultSpec, ...], seed: int, *, corrected: bool,
                 sensor: str = "r", design: str = "transport") -> None:

        self.inj = FaultInjector(tuple(faults), seed)
        self.channel = f"imu0.gyro.{sensor}"
        self.axis = "pqr".index(sensor)
        self.rng = np.random.default_rng(seed + 104_729)
        self.noise = LU2016.noise
        self.est = YawRateEstimator(YawRateFamilyConfig(sensor=sensor, design=design)) \
            if corrected else None
        self.corrected = corrected
        self.f_hat = 0.0
        self.rows: list[tuple[float, float, float, float]] = []  # t, f_hat, f, ||e_y||

    def __call__(self, st: Any) -> Any:

        n = self.noise
        w = np.array(st.omega_frd_radps, dtype=np.float64)
        wm = w + n.gyro_radps * self.rng.standard_normal(3)
        healthy = float(wm[self.axis])
        if self.channel in self.inj.channels:
            wm[self.axis] = self.inj.apply(self.channel, st.t_s, float(w[self.axis]), healthy)
        f_true = float(wm[self.axis]) - healthy
        t_us = round(st.t_s * 1e6)
        if self.est is not None:
            fr = Frame(t_us=t_us, imu=[ImuSample(t_us, 0, np.array(st.acc_frd_mps2), wm)],
                       euler_rad=np.array(st.euler_rad) + n.euler_rad[0]
                       * self.rng.standard_normal(3), att_age_s=0.0,
                       ssa_rad=float(st.ssa_rad) + n.ssa_rad * float(self.rng.standard_normal()),
                       cas_mps=np.full(3, st.cas_mps), cas_age_s=np.zeros(3),
                       baro_alt_m=st.pressure_alt_m, surf_pos_rad=np.array(st.surf_pos_rad),
                       surf_age_s=0.0)
            if self.est.due(fr):
                e = self.est.step(fr)
                if e.available and e.numerics_ok:
                    (self.f_hat,) = e.faults.values()
                    self.rows.append((st.t_s, self.f_hat, f_true, e.residuals[EY_CHANNEL]))
        wc = wm.copy()
        wc[self.axis] -= self.f_hat
        return dataclasses.replace(st, omega_frd_radps=wc)


def ftc_run(sc: Scenario, mode: str, *, sensor: str = "r",
            autopilot: Callable[[Any], Any] | None = None) -> dict[str, np.ndarray]:
    """Fly ``sc`` closed loop in ``mode`` (:data:`FTC_MODES`): true roll and sideslip with their
    commands per step, and the observer's fault estimate (corrected mode). ``autopilot``: a
    factory of the autopilot from the simulation (Chen2020's sliding-mode controller,
    :mod:`~gcs_monitor.evaluation.papers.chen2020_smc`); None = the simulator's PID autopilot.
    With an autopilot that has ``smc``, ``s`` holds ``||s^||`` per step (rad/s)."""

    faults = sc.faults if mode != "fault-free" else ()
    hook = LateralGyroInTheLoop(faults, sc.seed, corrected=mode == "corrected", sensor=sensor)
    sim: Any = make_simulation(sc)
    sim.feedback = hook
    if autopilot is not None:
        sim.autopilot = autopilot(sim)
    smc = getattr(sim.autopilot, "smc", None)
    n = round(sc.duration_s / sc.dt_s)
    out = np.zeros((n, 6))
    for k in range(n):
        st = sim.step()
        tg = sim.manoeuvre.targets(st.t_s, sim._fb)
        out[k] = (st.t_s, st.euler_rad[0], st.ssa_rad,
                  tg.bank_rad if tg.bank_rad is not None else math.nan, tg.beta_rad,
                  float(np.linalg.norm(smc.s)) if smc is not None else math.nan)
    est = np.array(hook.rows) if hook.rows else np.zeros((0, 4))
    return {"t": out[:, 0], "phi": out[:, 1], "beta": out[:, 2], "phi_c": out[:, 3],
            "beta_c": out[:, 4], "s": out[:, 5], "est_t": est[:, 0], "f_hat": est[:, 1],
            "f": est[:, 2], "e_y": est[:, 3]}



# ------------------------------------------------------------------------------------------------
# scenarios
# ------------------------------------------------------------------------------------------------

def case(name: str, *, sensor: str = "r", seed: int | None = None,
         sigma_mps: float | None = None, airframe: str | None = None) -> Scenario:
    """A Chen2020 preset, its faults moved to gyro ``sensor`` (p for the roll-rate cases),
    optionally flown by another airframe (at its default trim speed)."""
    sc = load_scenario(name)
    if airframe is not None and airframe != sc.airframe:
        sc = dataclasses.replace(sc, airframe=airframe, name=f"{sc.name}_{airframe}",
                                 initial=dataclasses.replace(sc.initial, tas_mps=None))
    faults = tuple(dataclasses.replace(f, channel=f"imu0.gyro.{sensor}") for f in sc.faults)
    wind = sc.wind if sigma_mps is None else dataclasses.replace(
        sc.wind, turbulence_sigma_mps=sigma_mps)
    return dataclasses.replace(sc, faults=faults, seed=sc.seed if seed is None else seed,
                               wind=wind, name=sc.name if sensor == "r" else f"{sc.name}_p")


# ------------------------------------------------------------------------------------------------
# experiments
# ------------------------------------------------------------------------------------------------

def chen2020_design(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """LPV fit of the simulator's lateral dynamics (eq. 59) and the LMI design of L_1 with its
    L2-gain bound, per airframe and gyro axis; compared with the shipped design files; the
    closed-loop bound of eq. 58 with the PID autopilot and with Chen2020's sliding-mode
    controller (its LMI design, :mod:`~gcs_monitor.evaluation.papers.chen2020_smc`)."""


    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    fit_rows, lmi_rows = [], []
    cl_rows: list[list[Any]] = []
    smc_text = ""
    for af in ENVELOPES:
        path, bands = write_design(af, out_dir)
        if af == "transport":
            cl_rows = closed_loop_bounds(af, bands[0])
            smc_text = design_text(bands[0], *make_smc(bands[0]))
        stored = load_bands(af)
        env = ENVELOPES[af]
        for d, st, (centre, lo_m, hi_m) in zip(bands, stored, env.bands_m, strict=True):
            f = d.meta["fit"]
            lo, hi = d.model.eas_range_mps
            tas = env.band_tas_mps(centre)
            fit_rows.append([af, f"{lo_m:g}-{hi_m:g}", f"{tas[0]:.0f}-{tas[1]:.0f} at {centre:g} m",
                             f"{lo:.1f}-{hi:.1f}", f["n_points"], f"{f['rel_A']:.2e}",
                             f"{f['rel_B']:.2e}", f"{f['eig_max_radps']:.2e}",
                             " / ".join(f"{x:.1e}" for x in f["nrmse"])])
            for s, sd in d.sensors.items():
                same = np.allclose(np.asarray(st.sensors[s].L1), np.asarray(sd.L1), rtol=1e-5,
                                   atol=1e-8)
                info = d.meta["lmi"][s]
                lmi_rows.append([af, f"{lo_m:g}-{hi_m:g}", s, f"{sd.gamma:.4f}",
                                 np.array2string(np.asarray(sd.L1)[0], precision=4,
                                                 separator=", "),
                                 f"{info['a11_margin_radps']:.3f}", info["solver"],
                                 info["status"], "yes" if same else "NO"])
    write_csv(out_dir / "chen2020_design_fit.csv", ["airframe", "band", "tas", "eas", "n",
                                                     "rel_A", "rel_B", "eig", "nrmse"], fit_rows)
    return ("LPV fit (eq. 59) of the linearised simulator per altitude band, worst over the trim "
            "points:\n\n"
            + md_table(["airframe", "band [m]", "TAS range [m/s]", "EAS range [m/s]", "points",
                        "A rel. error", "B rel. error", "eigenvalue error [rad/s]",
                        "derivative NRMSE phi/beta/p/r"], fit_rows)
            + "\n\nLMI design (observer: xi -> e_f bounded real lemma at the 4 vertices of "
            "Omega, ||L_1|| <= l1_max):\n\n"
            + md_table(["airframe", "band [m]", "sensor", "L2-gain bound", "L_1",
                        "max Re eig A~_11 [1/s]",
                        "solver", "status", "= shipped"], lmi_rows)
            + "\n\nClosed loop (eq. 58 with the simulator's autopilot on the corrected yaw rate, "
            "transport, 6 trim speeds, common P; Chen2020 reports 1.2918 with its sliding-mode "
            "controller):\n\n"
            + md_table(["uncertainty xi", "L_1", "L2-gain bound xi -> x_p", "c_1 = 1/gamma",
                        "status"], cl_rows) + "\n\n" + smc_text)


def _ftc_job(job: tuple[str, str, str]) -> dict[str, np.ndarray]:
    name, sensor, mode = job
    return ftc_run(case(name, sensor=sensor), mode, sensor=sensor)


def _ftc_table(out_dir: Path, jobs: int, sensor: str, tag: str) -> str:
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    args = [(c, sensor, m) for c in CASES for m in FTC_MODES]
    res = run_parallel(_ftc_job, args, jobs, desc=tag)
    rows = []
    plt = pyplot()
    for i, c in enumerate(CASES):
        ref = res[3 * i]
        win = ref["t"] >= FAULT_T0_S
        fig, ax = plt.subplots(4, 1, figsize=(9, 9), sharex=True)
        for j, mode in enumerate(FTC_MODES):
            r = res[3 * i + j]
            ep = (r["phi"] - r["phi_c"]) * RAD2DEG
            eb = (r["beta"] - r["beta_c"]) * RAD2DEG
            dphi = (r["phi"] - ref["phi"]) * RAD2DEG
            dbeta = (r["beta"] - ref["beta"]) * RAD2DEG
            rec = ey = math.nan
            if r["est_t"].size:
                we = r["est_t"] >= FAULT_T0_S
                rec = rms_finite((r["f_hat"] - r["f"])[we]) * RAD2DEG
                ey = float(np.max(r["e_y"][we]))
                ax[0].plot(r["est_t"], r["f"] * RAD2DEG, "k", lw=1, label="true fault")
                ax[0].plot(r["est_t"], r["f_hat"] * RAD2DEG, "C1", lw=1, label="reconstructed")
                ax[1].plot(r["est_t"], r["e_y"], "C2", lw=0.8)
            rows.append([c.replace("chen2020_", ""), mode, rms_finite(ep[win]), rms_finite(eb[win]),
                         rms_finite(dphi[win]), rms_finite(dbeta[win]), rec, ey])
            ax[2].plot(r["t"], r["phi"] * RAD2DEG, lw=1, label=mode)
            ax[3].plot(r["t"], r["beta"] * RAD2DEG, lw=1, label=mode)
        ax[2].plot(ref["t"], ref["phi_c"] * RAD2DEG, "k:", lw=1, label="command")
        ax[3].plot(ref["t"], ref["beta_c"] * RAD2DEG, "k:", lw=1, label="command")
        ax[0].set_ylabel(f"{sensor} fault [deg/s]")
        ax[0].legend(loc="upper left", fontsize=7)
        ax[1].set_ylabel("||e_y||")
        ax[2].set_ylabel("roll [deg]")
        ax[2].legend(loc="upper right", fontsize=7)
        ax[3].set_ylabel("sideslip [deg]")
        ax[3].set_xlabel("time [s]")
        ax[0].set_title(f"{c} ({sensor} gyro), closed loop")
        fig.tight_layout()
        fig.savefig(out_dir / f"{tag}_{c.replace('chen2020_', '')}.png", dpi=80)
        plt.close(fig)
    header = ["case", "gyro to autopilot", "roll RMSE [deg]", "sideslip RMSE [deg]",
              "roll dev. from fault-free [deg]", "sideslip dev. [deg]",
              "reconstruction error RMS [deg/s]", "max ||e_y||"]
    write_csv(out_dir / f"{tag}.csv", header, rows)
    return (f"Closed loop, {sensor} gyro faults from {FAULT_T0_S:g} s, RMS over "
            f"{FAULT_T0_S:g}-120 s (tracking: true minus commanded; deviation: from the "
            "fault-free closed-loop flight of the same seed):\n\n" + md_table(header, rows)
            + "\n")


def chen2020_ftc(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """Chen2020's four flight-test cases closed loop (transport, S-turn, sigma 1 m/s): roll and
    sideslip tracking with the raw and the corrected yaw-rate gyro, reconstruction error and
    ||e_y|| (Chen2020 Figs. 4-7, the FTC benefit as Atmaca2025 Table 4)."""
    return _ftc_table(out_dir, jobs, "r", "chen2020_ftc")


def _ol_job(job: tuple[str, str, int | None, float | None]) -> OpenLoopRun:
    name, sensor, seed, sigma = job
    return open_loop_run(case(name, sensor=sensor, seed=seed, sigma_mps=sigma), sensor=sensor)


def _ol_uav_job(name: str) -> OpenLoopRun:
    """The UAV (the simulator's nominal default airframe) with its own design."""
    return open_loop_run(case(name, airframe="uav"), monitor_config("r", design="uav"))


def _ol_rows(runs: list[OpenLoopRun], sensor: str) -> list[list[Any]]:
    rows = []
    ch = ChannelId("gyro", 0, sensor)
    for r in runs:
        f = r.truth_at(r.t_s)
        w = r.t_s >= FAULT_T0_S
        alarms = sensor_alarms(r.events)
        mine = observer_alarms(r.events, ch)
        first = mine[0].t_us * 1e-6 if mine else math.nan
        faulty = r.f_true_t.size > 0
        other = [e for e in alarms if not (e.channel == ch and faulty)]
        if mine and not faulty and mine[0].state is AlarmState.UPDATED:
            other.append(mine[0])  # a false alarm of the observer behind another's
        rows.append([r.name.replace("chen2020_", ""), rms_finite((r.f_hat - f)[w]) * RAD2DEG,
                     float(np.max(r.e_y[w])) if w.any() else math.nan,
                     r.j_max * RAD2DEG,
                     ("none" if not mine else f"FALSE, at {first:.1f} s (before the fault)"
                      if first < FAULT_T0_S else f"{first - FAULT_T0_S:.2f} s, "
                      f"{mine[0].fault_type.value}") if faulty else "-",
                     "; ".join(sorted({f"{e.channel} ({e.estimator})" for e in other}))
                     or "none"])
    return rows


def chen2020_open_loop(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """The four cases with the faults only in the published telemetry (autopilot on the true
    rates), through MAVLink and the Monitor with all default families: reconstruction error,
    ||e_y||, the yaw-rate alarm and its delay, every other sensor-fault alarm."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    runs = run_parallel(_ol_job, [(c, "r", None, None) for c in CASES], jobs,
                        desc="chen2020_open_loop")
    plt = pyplot()
    fig, ax = plt.subplots(len(runs), 1, figsize=(9, 2.2 * len(runs)), sharex=True)
    for a, r in zip(ax, runs, strict=True):
        a.plot(r.t_s, r.truth_at(r.t_s) * RAD2DEG, "k", lw=1, label="true fault")
        a.plot(r.t_s, r.f_hat * RAD2DEG, "C1", lw=1, label="reconstructed")
        for e in sensor_alarms(r.events):
            if e.estimator == EST:
                a.axvline(e.t_us * 1e-6, color="r", ls="--", lw=1)
        a.set_ylabel("deg/s")
        a.set_title(r.name, fontsize=8)
    ax[0].legend(loc="upper left", fontsize=7)
    ax[-1].set_xlabel("time [s] (red: yaw-rate alarm raised)")
    fig.tight_layout()
    fig.savefig(out_dir / "chen2020_open_loop.png", dpi=80)
    plt.close(fig)
    header = ["case", "reconstruction error RMS [deg/s]", "max ||e_y||", "max J [deg/s]",
              "yaw-rate alarm: delay, type", "other sensor-fault alarms"]
    rows = _ol_rows(runs, "r")
    uav = _ol_rows(run_parallel(_ol_uav_job, list(CASES), jobs, desc="chen2020_open_loop_uav"),
                   "r")
    write_csv(out_dir / "chen2020_open_loop.csv", header, rows + uav)
    return (f"Open loop (faults only in the telemetry), from {FAULT_T0_S:g} s, RMS over "
            f"{FAULT_T0_S:g}-120 s; J_th of the yaw-rate channel "
            f"{monitor_config().family('yaw_rate').fdi.threshold * RAD2DEG:.2f} deg/s:\n\n"
            + md_table(header, rows) + "\n\nThe same cases flown by the UAV (25 m/s), the "
            "monitor on the `uav` design:\n\n" + md_table(header, uav) + "\n")


FALSE_ALARM_MANOEUVRES = (("s_turn", "aileron"), ("coordinated_turn", "aileron"),
                          ("doublet_3211", "aileron"), ("doublet_3211", "rudder"))
FALSE_ALARM_SIGMAS = (1.0, 3.54)


def _ff_scenario(manoeuvre: str, surface: str, sigma: float, seed: int,
                 airframe: str | None = None) -> Scenario:
    """A 180 s fault-free run of one manoeuvre in turbulence ``sigma`` (m/s)."""
    sc = case("chen2020_fault_free", seed=seed, sigma_mps=sigma, airframe=airframe)
    return dataclasses.replace(
        sc, name=f"{manoeuvre}{'_' + surface if manoeuvre == 'doublet_3211' else ''}_"
        f"s{sigma:g}_seed{seed}{'_' + airframe if airframe else ''}", duration_s=180.0,
        manoeuvre=dataclasses.replace(sc.manoeuvre, kind=manoeuvre, surface=surface,
                                      amplitude=0.0 if manoeuvre != "s_turn"
                                      else sc.manoeuvre.amplitude))


def _ff_job(job: tuple[str, str, float, int]) -> OpenLoopRun:
    return open_loop_run(_ff_scenario(*job))


def chen2020_false_alarms(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """Fault-free S-turns, coordinated turns and aileron / rudder doublets (transport, 180 s) in
    turbulence sigma 1 and 3.54 m/s through the Monitor with every default family: the worst J
    of the reconstructed yaw-rate fault against its J_th, and every sensor-fault alarm.
    ``quick``: seed 101 only; otherwise seeds 101-103."""
    seeds = (101,) if quick else (101, 102, 103)
    args = [(m, s, sig, seed) for m, s in FALSE_ALARM_MANOEUVRES for sig in FALSE_ALARM_SIGMAS
            for seed in seeds]
    runs = run_parallel(_ff_job, args, jobs, desc="chen2020_false_alarms")
    th = monitor_config().family("yaw_rate").fdi.threshold * RAD2DEG
    rows = []
    for r in runs:
        alarms = sensor_alarms(r.events)
        rows.append([r.name, rms_finite(r.f_hat[r.t_s >= 15.0]) * RAD2DEG, r.j_max * RAD2DEG,
                     r.j_max * RAD2DEG / th,
                     "; ".join(f"{e.channel} ({e.estimator}) at {e.t_us * 1e-6:.1f} s"
                               for e in alarms) or "none"])
    worst = max(row[2] for row in rows)
    header = ["run", "fault estimate RMS [deg/s]", "max J [deg/s]", "max J / J_th",
              "sensor-fault alarms"]
    write_csv(Path(out_dir) / "chen2020_false_alarms.csv", header, rows)
    return (f"Fault-free runs, J_th = {th:.2f} deg/s; worst J {worst:.3f} deg/s (1.5 x worst = "
            f"{1.5 * worst:.3f} deg/s):\n\n" + md_table(header, rows) + "\n")


ALTITUDES_M = (1500.0, 3000.0, 4500.0, 6000.0, 7500.0, 9000.0, 10500.0)
ALTITUDE_EAS_MPS = 150.0  # one equivalent airspeed at every altitude: q-bar the same
ALTITUDE_MANOEUVRES = ("s_turn", "coordinated_turn")


def _altitude_job(job: tuple[str, float, str, str]) -> tuple[str, float, str, float, int]:
    manoeuvre, alt_m, label, design = job
    sc = _ff_scenario(manoeuvre, "aileron", 1.0, 101)
    tas = ALTITUDE_EAS_MPS / eas_from_tas(1.0, alt_m)
    sc = dataclasses.replace(sc, name=f"{manoeuvre}_{alt_m:.0f}m", duration_s=120.0,
                             initial=dataclasses.replace(sc.initial, alt_m=alt_m, tas_mps=tas))
    r = open_loop_run(sc, family_alone(monitor_config(design=design), "yaw_rate"))
    return manoeuvre, alt_m, label, r.j_max, len(observer_alarms(r.events,
                                                                 ChannelId("gyro", 0, "r")))


def chen2020_altitudes(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """Fault-free S-turns and coordinated turns of the transport at one equivalent airspeed
    (150 m/s) from 1500 to 10500 m (sigma 1 m/s, 120 s), the yaw-rate family alone: the worst J
    of the reconstructed yaw-rate fault with the model of the reference band only (built at
    1500 m, Chen2020 eq. 59 as printed: V_eas alone) and with the shipped altitude bands.
    ``quick``: the S-turn only."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    ref = load_bands("transport")[0]
    one = out_dir / "transport_reference_band_only.json"
    one.write_text(json.dumps(ObserverDesign(ref.model, ref.sensors, ref.meta).to_dict()))
    designs = (("reference band only (1500 m)", str(one)), ("altitude bands", "transport"))
    mans = ALTITUDE_MANOEUVRES[:1] if quick else ALTITUDE_MANOEUVRES
    args = [(m, a, label, d) for m in mans for a in ALTITUDES_M for label, d in designs]
    res = run_parallel(_altitude_job, args, jobs, desc="chen2020_altitudes")
    th = monitor_config().family("yaw_rate").fdi.threshold * RAD2DEG
    by: dict[tuple[str, float], dict[str, tuple[float, int]]] = {}
    for m, a, label, j, n in res:
        by.setdefault((m, a), {})[label] = (j * RAD2DEG, n)
    header = ["manoeuvre", "altitude [m]", "TAS [m/s]"] + [
        h for label, _ in designs for h in (f"{label}: max J [deg/s]", f"{label}: alarms")]
    rows: list[list[Any]] = [
        [m, f"{a:.0f}", f"{ALTITUDE_EAS_MPS / eas_from_tas(1.0, a):.0f}"]
        + [x for label, _ in designs for x in (f"{v[label][0]:.3f}", str(v[label][1]))]
        for (m, a), v in by.items()]
    write_csv(out_dir / "chen2020_altitudes.csv", header, rows)
    return (f"Fault-free turns at V_eas {ALTITUDE_EAS_MPS:.0f} m/s, J_th = {th:.2f} deg/s "
            "(yaw-rate family alone, sigma 1 m/s, seed 101):\n\n" + md_table(header, rows)
            + "\n")


def chen2020_roll_rate(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """The same observer class on the roll-rate gyro (H_p = e_3): the four cases' faults on p,
    closed loop (the autopilot's roll-rate loop on the raw and the corrected gyro) and open
    loop through the Monitor (yaw_rate family with ``sensor = "p"``)."""
    text = _ftc_table(out_dir, jobs, "p", "chen2020_roll_rate_ftc")
    runs = run_parallel(_ol_job, [(c, "p", None, None) for c in CASES], jobs,
                        desc="chen2020_roll_rate")
    header = ["case", "reconstruction error RMS [deg/s]", "max ||e_y||", "max J [deg/s]",
              "roll-rate alarm: delay, type", "other sensor-fault alarms"]
    return (text + "\nOpen loop through the Monitor (sensor = \"p\"):\n\n"
            + md_table(header, _ol_rows(runs, "p")) + "\n")


class _Frames:
    def __init__(self) -> None:
        self.frames: list[Any] = []

    def __call__(self, sysid: int, frame: Any, step: Any) -> None:
        self.frames.append(frame)


def _identify_job(job: tuple[str, str, int]) -> list[Any]:
    """The Frames of one fault-free transport flight (what the monitor assembles from MAVLink)."""
    manoeuvre, surface, seed = job
    sc = case("chen2020_fault_free", seed=seed)
    sc = dataclasses.replace(sc, name=f"ident_{manoeuvre}_{surface}", duration_s=150.0,
                             manoeuvre=dataclasses.replace(sc.manoeuvre, kind=manoeuvre,
                                                           surface=surface, amplitude=0.0
                                                           if manoeuvre != "s_turn" else
                                                           sc.manoeuvre.amplitude))
    cap = _Frames()
    cfg = MonitorConfig()
    for fam in ("imu", "airdata", "yaw_rate"):
        cfg = cfg.with_family(fam, enabled=False)
    feed_packets(Monitor(cfg, on_step=cap), (pkt for _, _, pkt in iter_run(sc)))
    return cap.frames


def chen2020_identify(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """``identify_lateral_model`` on the telemetry of clean flights (what ``calibrate`` would
    give it on a real aircraft): fault-free S-turn and aileron / rudder doublets of the
    transport in sigma 1 m/s turbulence, Frames from MAVLink; fit error and the identified
    matrices against the simulator's linearisation at the flown speed."""

    flights = [("s_turn", "aileron", 201), ("doublet_3211", "aileron", 202),
               ("doublet_3211", "rudder", 203)]
    frames = [f for fr in run_parallel(_identify_job, flights, jobs, desc="chen2020_identify")
              for f in fr]
    model, err = identify_lateral_model(frames)
    v = 0.5 * sum(model.eas_range_mps)
    sc = case("chen2020_fault_free")

    lti = lateral_lti("transport", tas_from_cas(v, sc.initial.alt_m), sc.initial.alt_m)
    A, B, c = model.matrices(v)
    rows = []
    for i, s in enumerate(("phi", "beta", "p", "r")):
        rows.append([s, f"{err.nrmse[i]:.3f}",
                     np.array2string(A[i], precision=3, separator=", "),
                     np.array2string(lti.A[i], precision=3, separator=", "),
                     np.array2string(B[i], precision=3, separator=", "),
                     np.array2string(lti.B[i], precision=3, separator=", ")])
    rel = [float(np.linalg.norm(A[2:] - lti.A[2:]) / np.linalg.norm(lti.A[2:])),
           float(np.linalg.norm(B[2:] - lti.B[2:]) / np.linalg.norm(lti.B[2:]))]
    return (f"Identified from {err.n_points} samples of {len(flights)} flights (EAS "
            f"{model.eas_range_mps[0]:.1f}-{model.eas_range_mps[1]:.1f} m/s: one speed, so the "
            f"model is constant); moment rows against the linearisation: A rel. error "
            f"{rel[0]:.3f}, B {rel[1]:.3f}:\n\n"
            + md_table(["state", "derivative NRMSE", "A row (identified)",
                        "A row (linearised)", "B row (identified)", "B row (linearised)"],
                       rows) + "\n")


def _replay_observer(frames: list[Any], k: float, tau_s: float, fault: Callable[[float], float],
                     design: str = "transport") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The family's estimator alone over recorded Frames, with ``fault(t)`` added to the
    yaw-rate gyro: (t, f_hat, f)."""

    cfg = YawRateFamilyConfig(design=design, observer=ObserverConfig(modulation=k,
                                                                      nu_filter_s=tau_s))
    est = YawRateEstimator(cfg)
    rows = []
    for fr in frames:
        imu = fr.primary_imu
        if imu is None or not est.due(fr):
            continue
        f = fault(fr.t_us * 1e-6)
        w = imu.omega_frd_radps.copy()
        w[2] += f
        e = est.step(dataclasses.replace(fr, imu=[ImuSample(imu.t_us, imu.instance,
                                                            imu.acc_frd_mps2, w)]))
        if e.available and e.numerics_ok:
            (v,) = e.faults.values()
            rows.append((fr.t_us * 1e-6, v, f))
    a = np.array(rows)
    return a[:, 0], a[:, 1], a[:, 2]


def chen2020_tuning(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """Chen2020 Fig. 2 on simulated data: the observer run off-line on the telemetry of one
    fault-free S-turn (sigma 1 and 3.54 m/s) for several modulation gains k and equivalent-
    injection filters; the RMS of the fault estimate (fault-free) and the reconstruction error
    of a 0.4 deg/s^2 drift capped at 5 deg/s added to the recorded yaw rate from 30 s."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    flights = run_parallel(_tuning_frames, [1.0, 3.54], jobs, desc="chen2020_tuning")
    ks = (0.2, 0.4, 0.8, 1.2, 1.6, 2.4)
    taus = (0.0, 0.25, 0.5, 1.0)

    def drift(t: float) -> float:
        return min(max(t - FAULT_T0_S, 0.0) * 0.4, 5.0) / RAD2DEG

    rows = []
    res: dict[tuple[float, float, float], tuple[float, float]] = {}
    for sigma, frames in zip((1.0, 3.54), flights, strict=True):
        for k in ks:
            for tau in taus:
                t, fh, _ = _replay_observer(frames, k, tau, lambda _t: 0.0)
                ff = rms_finite(fh[t >= 15.0]) * RAD2DEG
                t, fh, f = _replay_observer(frames, k, tau, drift)
                w = t >= FAULT_T0_S
                rec = rms_finite((fh - f)[w]) * RAD2DEG
                res[(sigma, k, tau)] = (ff, rec)
                rows.append([sigma, k, tau, ff, rec])
    plt = pyplot()
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.8))
    for sigma, ls in ((1.0, "-"), (3.54, "--")):
        for tau, c in zip(taus, ("C0", "C1", "C2", "C3"), strict=True):
            ax[0].plot(ks, [res[(sigma, k, tau)][0] for k in ks], ls, color=c,
                       label=f"sigma {sigma:g}, tau {tau:g} s")
            ax[1].plot(ks, [res[(sigma, k, tau)][1] for k in ks], ls, color=c)
    ax[0].set_xlabel("modulation gain k")
    ax[1].set_xlabel("modulation gain k")
    ax[0].set_ylabel("fault-free |f_hat| RMS [deg/s]")
    ax[1].set_ylabel("drift reconstruction error RMS [deg/s]")
    ax[0].legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(out_dir / "chen2020_tuning.png", dpi=80)
    plt.close(fig)
    header = ["sigma [m/s]", "k", "filter tau [s]", "fault-free f_hat RMS [deg/s]",
              "drift reconstruction error RMS [deg/s]"]
    write_csv(out_dir / "chen2020_tuning.csv", header, rows)
    return ("Observer replayed on recorded fault-free telemetry (transport S-turn), Chen2020 "
            "Fig. 2:\n\n" + md_table(header, rows) + "\n")


def _tuning_frames(sigma: float) -> list[Any]:
    sc = case("chen2020_fault_free", sigma_mps=sigma)
    cap = _Frames()
    cfg = MonitorConfig()
    for fam in ("imu", "airdata", "yaw_rate"):
        cfg = cfg.with_family(fam, enabled=False)
    feed_packets(Monitor(cfg, on_step=cap), (pkt for _, _, pkt in iter_run(sc)))
    return cap.frames


# clean UAV flights for calibrate: the S-turn (roll, yaw rate) and a rudder doublet (sideslip)
UAV_CLEAN_FLIGHTS = (("s_turn", "aileron", 301), ("doublet_3211", "rudder", 302))
UAV_CLEAN_S = 90.0


def _uav_clean_scenario(manoeuvre: str, surface: str, seed: int) -> Scenario:
    sc = case("chen2020_fault_free", airframe="uav", seed=seed)
    return dataclasses.replace(
        sc, name=f"uav_clean_{manoeuvre}_{surface}_seed{seed}", duration_s=UAV_CLEAN_S,
        manoeuvre=dataclasses.replace(sc.manoeuvre, kind=manoeuvre, surface=surface,
                                      amplitude=0.0 if manoeuvre != "s_turn"
                                      else sc.manoeuvre.amplitude))


def _uav_job(job: tuple[str, Scenario, MonitorConfig]) -> tuple[str, OpenLoopRun]:
    label, sc, cfg = job
    return label, open_loop_run(sc, cfg)


def chen2020_uav(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """The Chen2020 cases flown by the simulator's nominal default airframe (the UAV, 25 m/s),
    monitored (faults only in the telemetry, every default family) under three configurations:
    the defaults (the transport's design, whose model holds at 79-172 m/s EAS); the shipped
    ``uav`` design at the default (transport's) J_th, fault-free only; and what ``gcs-monitor
    calibrate`` makes of clean UAV flights (``UAV_CLEAN_FLIGHTS``: the identified lateral model,
    its observer and its own J_th). Per run: the share of the family's samples it judged, why
    not, the worst J against J_th and the alarms. ``quick``: calibrate on the S-turn only, the
    fault-free and fast-drift cases only. The calibrated configuration also flies the fault-free
    manoeuvres of ``chen2020_false_alarms`` (180 s, sigma 1 and 3.54 m/s, seed 101)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    clean = UAV_CLEAN_FLIGHTS[:1] if quick else UAV_CLEAN_FLIGHTS
    flights = []
    for f in clean:
        res = run_scenario(_uav_clean_scenario(*f), out_dir / "uav_clean", progress=False)
        assert res.tlog_path is not None
        flights.append(res.tlog_path)
    base = MonitorConfig()
    cal = calibrate(flights, base, design_path=out_dir / "uav_calibrated.yaw_rate.json")
    (out_dir / "uav_calibrated.toml").write_text(calibration_toml(cal, base, flights))
    cases = [case(c, airframe="uav") for c in ((CASES[0], CASES[2]) if quick else CASES)]
    calibrated = "calibrated (uav_calibrated.toml)"
    configs = {"defaults (transport design)": base, calibrated: cal.config}
    work = [(label, sc, cfg) for label, cfg in configs.items() for sc in cases]
    work.insert(len(cases), ("`uav` design, default J_th", cases[0], monitor_config("r", "uav")))
    # the calibrated configuration on the fault-free manoeuvres of chen2020_false_alarms
    work += [(calibrated, _ff_scenario(m, srf, sig, 101, "uav"), cal.config)
             for m, srf in FALSE_ALARM_MANOEUVRES for sig in FALSE_ALARM_SIGMAS]
    ch = ChannelId("gyro", 0, "r")
    rows = []
    for label, r in run_parallel(_uav_job, work, jobs, desc="chen2020_uav"):
        cfg = next(w[2] for w in work if w[0] == label)
        th = cfg.family("yaw_rate").fdi.threshold
        alarms = sensor_alarms(r.events)
        mine = observer_alarms(r.events, ch)
        faulty = r.f_true_t.size > 0
        if not mine:
            alarm = "none" if faulty else "-"
        elif faulty:
            alarm = f"{mine[0].t_us * 1e-6 - FAULT_T0_S:.2f} s, {mine[0].fault_type.value}"
        else:
            alarm = f"FALSE, at {mine[0].t_us * 1e-6:.1f} s"
        n = max(r.samples, 1)
        why = "; ".join(f"{k} ({100.0 * c / n:.0f} %)" for k, c in r.reasons.most_common()
                        if c >= 0.005 * n)
        others = "; ".join(sorted({f"{e.channel} ({e.estimator})" for e in alarms
                                   if e.estimator != EST})) or "none"
        rows.append([label, r.name.replace("chen2020_", ""),
                     f"{100.0 * r.judged / n:.0f} %", why or "-",
                     f"{r.j_max * RAD2DEG:.3g} / {th * RAD2DEG:.3g}", alarm, others])
    header = ["configuration", "case", "yaw_rate judged", "not judged because (share of samples)",
              "max J / J_th [deg/s]", "yaw_rate_smo alarm: delay, type",
              "other estimators' sensor-fault alarms"]
    write_csv(out_dir / "chen2020_uav.csv", header, rows)
    yaw = base.family("yaw_rate")
    return ("\n".join(cal.yaw_rate.summary(yaw.design, yaw.observer.eas_margin))
            + f"\n\ncalibrated on {len(flights)} clean UAV flight(s) of {UAV_CLEAN_S:g} s "
            f"({', '.join(p.name for p in flights)}); yaw-rate J_th "
            f"{cal.config.family('yaw_rate').fdi.threshold * RAD2DEG:.3g} deg/s\n\n"
            + md_table(header, rows) + "\n")


def experiments() -> dict[str, Callable[[Path, int, bool], str]]:
    return {"chen2020_design": chen2020_design, "chen2020_ftc": chen2020_ftc,
            "chen2020_open_loop": chen2020_open_loop,
            "chen2020_false_alarms": chen2020_false_alarms,
            "chen2020_roll_rate": chen2020_roll_rate, "chen2020_identify": chen2020_identify,
            "chen2020_tuning": chen2020_tuning, "chen2020_uav": chen2020_uav,
            "chen2020_altitudes": chen2020_altitudes}
