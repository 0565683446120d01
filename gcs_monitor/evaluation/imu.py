"""IMU fault reconstruction experiments (issue 4: Lu2016, Atmaca2025), through the MAVLink path.

Every run goes simulator -> MAVLink bytes (``sim_vehicle.run.iter_run``) -> :class:`Monitor`
(decode, FrameAssembler with causal GPS interpolation, estimators, FDI). Estimates are captured per
Frame with ``Monitor(on_step=...)``; the true fault of each IMU channel is the simulator's
``suite.fault_log`` (the value added to the healthy sample), interpolated to the Frame times.

Scoring windows (same for every estimator): the fault window is scored from 1 s after it opens to
its end (a step fault needs a few hundred ms to be followed, as in docs/results.md, "Synthetic
truth"); the fault-free windows are [2 s, first fault start) and [last fault end + 2 s, end of
run).

Experiments (``experiments()``; each takes ``(out_dir, jobs, quick)`` and returns Markdown):

* ``lu2016_table2`` -- GS-KM vs AS-KM and ATSEKF vs IOTSEKF (Lu2016 secs. 3.3-3.5);
* ``atmaca2025`` -- OTSEKF+HOSM vs IOTSEKF, RMSE and start-up transient (Atmaca2025 Tables 2-3);
* ``imu_detection`` -- thresholds from fault-free runs of other seeds, detection delays,
  isolation and zero-false-alarm check on fault-free manoeuvres in turbulence;
* ``closed_loop`` -- the simulator flies on the IMU corrected by the estimator (see
  :func:`closed_loop_run`).
"""

from __future__ import annotations

import csv
import dataclasses
import logging
import math
import time
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import numpy as np

from gcs_monitor.config import MonitorConfig
from gcs_monitor.config.loader import EstimatorsConfig, FdiConfig, SetConfig
from gcs_monitor.core.units import RAD2DEG
from gcs_monitor.estimators.base import Estimator
from gcs_monitor.families.imu.imu_hosm import ImuHosmEstimator
from gcs_monitor.families.imu.imu_ts import (
    FAULT_CHANNELS,
    ImuTsConfig,
    ImuTwoStageEstimator,
    Lu2016Table1,
)
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState
from gcs_monitor.fdi.monitor import calibrate
from gcs_monitor.monitor import Monitor

log = logging.getLogger(__name__)

SIM_CHANNELS = ("imu0.acc.x", "imu0.acc.y", "imu0.acc.z",
                "imu0.gyro.p", "imu0.gyro.q", "imu0.gyro.r")
AXES = ("Ax", "Ay", "Az", "p", "q", "r")
# report accelerometer channels in m/s^2, gyro channels in deg/s
REPORT_SCALE = np.array([1.0, 1.0, 1.0, RAD2DEG, RAD2DEG, RAD2DEG])
SCORE_DELAY_S = 1.0
QUIET_START_S = 2.0
QUIET_AFTER_S = 2.0
TABLE2_PRESETS = ("lu2016_calm", "lu2016_shear", "lu2016_turbulence", "lu2016_parabolic")
MANOEUVRES = ("level", "coordinated_turn", "parabolic", "doublet_3211", "s_turn")
CHUNK_PACKETS = 64

EstimatorFactory = Callable[[], list[Estimator]]


# ------------------------------------------------------------------------------------------------
# estimator variants
# ------------------------------------------------------------------------------------------------


def _named(est: Any, name: str) -> Any:
    est.name = name  # several variants on one Monitor: channel monitors are keyed by name
    return est


def lu2016_variants() -> list[Estimator]:
    """GS-KM/AS-KM x ATSEKF/IOTSEKF (Lu2016 secs. 3.3-3.5), Lu2016 Table 1 noise."""
    return [
        _named(ImuTwoStageEstimator(ImuTsConfig(model="gs", adaptive=True)), "gs_atsekf"),
        _named(ImuTwoStageEstimator(ImuTsConfig(model="gs", adaptive=False)), "gs_iotsekf"),
        _named(ImuTwoStageEstimator(ImuTsConfig(model="as", adaptive=True)), "as_atsekf"),
        _named(ImuTwoStageEstimator(ImuTsConfig(model="as", adaptive=False)), "as_iotsekf"),
    ]


def atmaca_noise() -> Lu2016Table1:
    """Atmaca2025 Table 1 sigmas in the Lu2016 estimator's noise dataclass (fair comparison)."""
    return Lu2016Table1(vel_sigma_mps=0.030, euler_sigma_rad=8.7e-5, acc_sigma_mps2=6.9e-4,
                        gyro_sigma_radps=4.1e-6, aoa_sigma_rad=2.7e-4, tas_sigma_mps=0.005)


def atmaca_variants() -> list[Estimator]:
    """OTSEKF+HOSM (Atmaca2025) and the IOTSEKF on the GS-KM with the same sensor noise."""
    return [
        _named(ImuHosmEstimator(), "otsekf_hosm"),
        _named(ImuTwoStageEstimator(ImuTsConfig(model="gs", adaptive=False,
                                                noise=atmaca_noise())), "gs_iotsekf"),
        _named(ImuTwoStageEstimator(ImuTsConfig(model="gs", adaptive=True,
                                                noise=atmaca_noise())), "gs_atsekf"),
    ]


def default_variant() -> list[Estimator]:
    """What the monitor runs by default (``MonitorConfig().estimators``: imu_ts, GS-KM ATSEKF)."""
    return [ImuTwoStageEstimator()]


def hosm_variant() -> list[Estimator]:
    """What the monitor runs with ``estimators.imu_hosm = true`` (and imu_ts off)."""
    return [ImuHosmEstimator()]


# estimator name -> (factory, FDI set names of its acc and gyro channels, MonitorConfig.fdi)
DETECTION_ESTIMATORS: dict[str, tuple[EstimatorFactory, tuple[str, str]]] = {
    "imu_ts": (default_variant, ("acc", "gyro")),
    "imu_hosm": (hosm_variant, ("acc_hosm", "gyro_hosm")),
}


# ------------------------------------------------------------------------------------------------
# one run through the MAVLink path
# ------------------------------------------------------------------------------------------------


@dataclass
class ImuRun:
    """Per-Frame capture of one run.

    t_s : (n,) Frame times, s
    f_hat : estimator name -> (n, 6) fault estimates, SI (NaN where unavailable)
    f_true : (n, 6) true injected fault, SI
    events : IMU-channel alarm events (all estimators)
    fault_windows : (start, end) of the scenario's faults, s
    duration_s : run length, s
    wall_s : wall time of simulation + monitor, s
    """

    name: str
    t_s: np.ndarray
    f_hat: dict[str, np.ndarray]
    f_true: np.ndarray
    events: list[AlarmEvent]
    fault_windows: list[tuple[float, float]]
    duration_s: float
    wall_s: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)


class _Capture:
    """``Monitor.on_step`` callback: fault estimates per Frame, per estimator name."""

    def __init__(self) -> None:
        self.t_us: list[int] = []
        self.rows: dict[str, list[list[float]]] = {}

    def __call__(self, sysid: int, frame: Any, step: Any) -> None:
        k = len(self.t_us)
        self.t_us.append(frame.t_us)
        for e in step.estimates:
            if not e.available:
                continue
            if not all(c in e.faults for c in FAULT_CHANNELS):
                continue  # not an IMU estimator (air data)
            rows = self.rows.setdefault(e.name, [])
            rows.extend([[math.nan] * 6] * (k - len(rows)))
            if len(rows) == k:
                rows.append([e.faults[c] for c in FAULT_CHANNELS])

    def arrays(self) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        n = len(self.t_us)
        out = {}
        for name, rows in self.rows.items():
            rows = rows + [[math.nan] * 6] * (n - len(rows))
            out[name] = np.asarray(rows, dtype=np.float64)
        return np.asarray(self.t_us, dtype=np.int64) * 1e-6, out


def replay_packets(packets: Iterable[bytes], estimators: EstimatorFactory,
                   cfg: MonitorConfig | None = None, *,
                   notices: list[AlarmEvent] | None = None
                   ) -> tuple[np.ndarray, dict[str, np.ndarray], list[AlarmEvent]]:
    """Feed MAVLink packets through a Monitor; return Frame times, f_hat per estimator, alarms.

    ``estimators`` builds the IMU estimators (air-data estimation is off: not under test here;
    the AoA/CAS sets still run on set consensus). ``notices``: if given, the ESTIMATOR events
    (re-initialisation notices, never alarms) are appended to it."""
    cfg = cfg or MonitorConfig(estimators=EstimatorsConfig(airdata="none"))
    cap = _Capture()
    mon = Monitor(cfg, estimators_for=lambda sysid: (estimators(), None), on_step=cap)
    buf: list[bytes] = []
    for pkt in packets:
        buf.append(pkt)
        if len(buf) >= CHUNK_PACKETS:
            mon.feed(b"".join(buf))
            buf = []
    mon.feed(b"".join(buf))
    mon.finish()
    t_s, f_hat = cap.arrays()
    events = [e for e in mon.events if e.kind == AlarmKind.SENSOR_FAULT
              and e.channel.kind in ("acc", "gyro")]
    if notices is not None:
        notices += [e for e in mon.events if e.kind == AlarmKind.ESTIMATOR]
    return t_s, f_hat, events


def fault_truth(t_s: np.ndarray, fault_log: dict[str, tuple[list[float], list[float]]]
                ) -> np.ndarray:
    """(n, 6) true fault at the Frame times from ``SensorSuite.fault_log`` (0 where none)."""
    out = np.zeros((len(t_s), 6))
    for i, ch in enumerate(SIM_CHANNELS):
        if ch in fault_log and fault_log[ch][0]:
            ts, vs = (np.asarray(a, dtype=np.float64) for a in fault_log[ch])
            out[:, i] = np.interp(t_s, ts, vs, left=0.0, right=0.0)
    return out


def fault_windows(sc: Any) -> list[tuple[float, float]]:
    """Merged (start, end) intervals of the scenario's IMU faults."""
    iv = sorted((f.t_start_s, sc.duration_s if f.t_end_s is None else f.t_end_s)
                for f in sc.faults if f.channel in SIM_CHANNELS)
    out: list[tuple[float, float]] = []
    for a, b in iv:
        if out and a <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], b))
        else:
            out.append((a, b))
    return out


def simulate(sc: Any, estimators: EstimatorFactory, cfg: MonitorConfig | None = None) -> ImuRun:
    """Run a scenario through the simulator, the MAVLink bytes and the Monitor."""
    from sim_vehicle.run import RunState, iter_run

    t0 = time.perf_counter()
    rs = RunState()
    packets = (pkt for _, _, pkt in iter_run(sc, run_state=rs))
    t_s, f_hat, events = replay_packets(packets, estimators, cfg)
    assert rs.suite is not None
    return ImuRun(name=f"{sc.name}_s{sc.seed}", t_s=t_s, f_hat=f_hat,
                  f_true=fault_truth(t_s, rs.suite.fault_log), events=events,
                  fault_windows=fault_windows(sc), duration_s=sc.duration_s,
                  wall_s=time.perf_counter() - t0)


def score_masks(run: ImuRun) -> tuple[np.ndarray, np.ndarray]:
    """(in-fault, fault-free) boolean masks over the Frames (module docstring)."""
    t = run.t_s
    in_fault = np.zeros(len(t), dtype=bool)
    quiet = t >= QUIET_START_S
    for a, b in run.fault_windows:
        in_fault |= (t >= a + SCORE_DELAY_S) & (t <= b)
        quiet &= ~((t >= a) & (t < b + QUIET_AFTER_S))
    return in_fault, quiet


def rmse(err: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(6,) RMS of ``err[mask]`` per channel, reported units (m/s^2, deg/s); NaN-safe."""
    e = err[mask] * REPORT_SCALE
    if e.size == 0:
        return np.full(6, math.nan)
    return cast(np.ndarray, np.sqrt(np.nanmean(e * e, axis=0)))


# ------------------------------------------------------------------------------------------------
# scenario variants
# ------------------------------------------------------------------------------------------------


def scenario(preset: str, *, seed: int | None = None, duration_s: float | None = None) -> Any:
    from sim_vehicle.scenario import load_scenario, with_overrides

    return with_overrides(load_scenario(preset), seed=seed, duration_s=duration_s)


def fault_free_variant(manoeuvre: str, seed: int, *, duration_s: float = 60.0,
                       wind: str = "turbulence") -> Any:
    """lu2016_turbulence without faults, with another manoeuvre, wind and seed (in memory)."""
    sc = scenario("lu2016_turbulence")
    return dataclasses.replace(
        sc, name=f"ff_{manoeuvre}_{wind}", faults=(), seed=seed, duration_s=duration_s,
        wind=dataclasses.replace(sc.wind, kind=wind),
        manoeuvre=dataclasses.replace(sc.manoeuvre, kind=manoeuvre, start_s=5.0))


def _pmap(fn: Callable[..., Any], args: Sequence[tuple[Any, ...]], jobs: int) -> list[Any]:
    if jobs <= 1 or len(args) <= 1:
        return [fn(*a) for a in args]
    with ProcessPoolExecutor(max_workers=jobs) as ex:
        futs = [ex.submit(fn, *a) for a in args]
        return [f.result() for f in futs]


# ------------------------------------------------------------------------------------------------
# output helpers
# ------------------------------------------------------------------------------------------------


def _fmt(x: float, nd: int = 3) -> str:
    if not math.isfinite(x):
        return "-"
    return f"{x:.{nd}g}" if abs(x) < 1e4 else f"{x:.3e}"


def md_table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for r in rows:
        lines.append("| " + " | ".join(_fmt(v) if isinstance(v, float) else str(v) for v in r)
                     + " |")
    return "\n".join(lines)


def write_csv(path: Path, header: Sequence[str], rows: Sequence[Sequence[Any]]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)


def plot_run(run: ImuRun, names: Sequence[str], path: Path, title: str = "") -> None:
    """f_hat of each estimator against the true fault, six panels."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(3, 2, figsize=(11, 8), sharex=True)
    units = ("m/s^2",) * 3 + ("deg/s",) * 3
    for i in range(6):
        ax = axs[i % 3, i // 3]
        ax.plot(run.t_s, run.f_true[:, i] * REPORT_SCALE[i], "k", lw=2, label="true")
        for n in names:
            if n in run.f_hat:
                ax.plot(run.t_s, run.f_hat[n][:, i] * REPORT_SCALE[i], lw=0.8, label=n)
        ax.set_ylabel(f"f_{AXES[i]} [{units[i]}]")
        ax.grid(True, alpha=0.3)
    axs[0, 0].legend(fontsize=7)
    axs[2, 0].set_xlabel("t [s]")
    axs[2, 1].set_xlabel("t [s]")
    fig.suptitle(title or run.name)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)


# ------------------------------------------------------------------------------------------------
# 1. Lu2016 Table 2 scenarios
# ------------------------------------------------------------------------------------------------

LU_NAMES = ("gs_atsekf", "gs_iotsekf", "as_atsekf", "as_iotsekf")


def _lu_run(preset: str, seed: int) -> ImuRun:
    return simulate(scenario(preset, seed=seed), lu2016_variants)


def lu2016_table2(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """Per-channel RMSE of the six fault estimates, GS-KM vs AS-KM, ATSEKF vs IOTSEKF.

    Lu2016 secs. 3.3-3.5 scenarios (presets lu2016_calm/shear/turbulence/parabolic, Table 2
    faults 10-30 s). ``quick``: seed 1 only; otherwise seeds 1-3, RMSE averaged over seeds.
    """
    out_dir = Path(out_dir)
    seeds = (1,) if quick else (1, 2, 3)
    args = [(p, s) for p in TABLE2_PRESETS for s in seeds]
    runs = _pmap(_lu_run, args, jobs)
    header = (["scenario", "estimator"] + [f"{a} fault" for a in AXES]
              + [f"{a} quiet" for a in AXES])
    rows: list[list[Any]] = []
    acc_ratio: list[list[Any]] = []
    by: dict[tuple[str, str], list[np.ndarray]] = {}
    for (preset, _seed), run in zip(args, runs, strict=True):
        inf, quiet = score_masks(run)
        for n in LU_NAMES:
            err = run.f_hat[n] - run.f_true
            by.setdefault((preset, n), []).append(
                np.concatenate([rmse(err, inf), rmse(err, quiet)]))
        if _seed == seeds[0]:
            plot_run(run, LU_NAMES, out_dir / f"lu2016_table2_{preset}.png")
    for preset in TABLE2_PRESETS:
        for n in LU_NAMES:
            v = np.mean(by[(preset, n)], axis=0)
            rows.append([preset, n] + [float(x) for x in v])
        for adapt in ("atsekf", "iotsekf"):
            gs = np.mean(by[(preset, f"gs_{adapt}")], axis=0)
            as_ = np.mean(by[(preset, f"as_{adapt}")], axis=0)
            acc_ratio.append([preset, adapt, float(np.mean(as_[:3]) / np.mean(gs[:3])),
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
# 2. Atmaca2025
# ------------------------------------------------------------------------------------------------

ATMACA_PRESETS = ("atmaca2025_acc", "atmaca2025_gyro")
ATMACA_NAMES = ("otsekf_hosm", "gs_iotsekf", "gs_atsekf")
STARTUP_S = 2.0


def _atmaca_run(preset: str, seed: int | None) -> ImuRun:
    return simulate(scenario(preset, seed=seed), atmaca_variants)


def atmaca2025(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """OTSEKF+HOSM vs IOTSEKF (and ATSEKF): per-channel RMSE in the fault windows and the
    start-up transient (max |f_hat| over the first 2 s, fault-free), Atmaca2025 Tables 2-3.
    ``quick``: the presets' seeds only; otherwise also seeds 11, 12 (mean RMSE, max transient).
    """
    out_dir = Path(out_dir)
    seeds: tuple[int | None, ...] = (None,) if quick else (None, 11, 12)
    args = [(p, s) for p in ATMACA_PRESETS for s in seeds]
    runs = _pmap(_atmaca_run, args, jobs)
    header = ["scenario", "estimator"] + [f"{a} fault" for a in AXES] + [
        f"{a} start max" for a in AXES]
    acc: dict[tuple[str, str], list[np.ndarray]] = {}
    for (preset, seed), run in zip(args, runs, strict=True):
        inf, _ = score_masks(run)
        first = run.t_s <= run.t_s[0] + STARTUP_S
        for n in ATMACA_NAMES:
            f = run.f_hat[n]
            start = np.nanmax(np.abs(f[first]) * REPORT_SCALE, axis=0)
            acc.setdefault((preset, n), []).append(
                np.concatenate([rmse(f - run.f_true, inf), start]))
        if seed is None:
            plot_run(run, ATMACA_NAMES, out_dir / f"atmaca2025_{preset}.png")
    rows = []
    for preset in ATMACA_PRESETS:
        for n in ATMACA_NAMES:
            a = np.asarray(acc[(preset, n)])
            v = np.concatenate([a[:, :6].mean(axis=0), a[:, 6:].max(axis=0)])
            rows.append([preset, n] + [float(x) for x in v])
    write_csv(out_dir / "atmaca2025.csv", header, rows)
    return ("Per-channel RMSE of f_hat - f in the fault windows (acc m/s^2, gyro deg/s; mean over "
            f"{len(seeds)} seed(s)) and start-up transient max |f_hat| over the first "
            f"{STARTUP_S:g} s (fault-free; max over seeds):\n\n" + md_table(header, rows) + "\n")


# ------------------------------------------------------------------------------------------------
# 3. detection: calibration, delays, isolation, false alarms
# ------------------------------------------------------------------------------------------------

CALIBRATION_SEEDS = (101, 102)
# lu2016_turbulence with only the accelerometer (gyro) faults of Table 2: isolation check
ISOLATION_VARIANTS = ("lu2016_turbulence:acc", "lu2016_turbulence:gyro")
EVAL_SEEDS = (1, 2, 3)


def _ff_run(manoeuvre: str, seed: int, duration_s: float, estimator: str = "imu_ts") -> ImuRun:
    return simulate(fault_free_variant(manoeuvre, seed, duration_s=duration_s),
                    DETECTION_ESTIMATORS[estimator][0])


def calibrate_imu_thresholds(*, seeds: Sequence[int] = CALIBRATION_SEEDS,
                             manoeuvres: Sequence[str] = MANOEUVRES, duration_s: float = 60.0,
                             jobs: int = 1, rule: str = "max", k: float | None = None,
                             base: FdiConfig | None = None,
                             echo: Callable[[str], None] = print,
                             estimator: str = "imu_ts") -> dict[str, SetConfig]:
    """IMU channel thresholds J_th from fault-free runs (Wan2018 sec. VI-B rule, fdi.calibrate).

    Fault-free variants of lu2016_turbulence (every manoeuvre, Dryden turbulence, the given
    seeds -- NOT the evaluation seeds) run through the Monitor with the default estimator;
    ``calibrate`` over each channel's whole f_hat record (start-up included, since fault-free
    runs must not alarm at start-up either) with the monitor's N_eval; the threshold of the
    acc (gyro) set is the largest over its three channels. ``n_eval``/``n_detect`` stay as in
    ``base`` (the config defaults). ``estimator``: ``"imu_ts"`` (sets ``acc``, ``gyro``) or
    ``"imu_hosm"`` (sets ``acc_hosm``, ``gyro_hosm``), see :data:`DETECTION_ESTIMATORS`.
    Prints the numbers; returns ``{acc set: ..., gyro set: ...}``.
    """
    base = base or FdiConfig()
    acc_set, gyro_set = DETECTION_ESTIMATORS[estimator][1]
    base_acc, base_gyro = getattr(base, acc_set), getattr(base, gyro_set)
    args = [(m, s, duration_s, estimator) for m in manoeuvres for s in seeds]
    runs = _pmap(_ff_run, args, jobs)
    per = np.zeros((len(runs), 6))
    warm = np.zeros((len(runs), 6))  # the same without the first STARTUP_S (for the report)
    for j, run in enumerate(runs):
        f = run.f_hat[estimator]
        late = run.t_s >= run.t_s[0] + STARTUP_S
        for i in range(6):
            cfg = base_acc if i < 3 else base_gyro
            per[j, i] = calibrate(f[:, i], rms_window_n=cfg.n_eval, rule=rule, k=k)
            warm[j, i] = calibrate(f[late, i], rms_window_n=cfg.n_eval, rule=rule, k=k)
    worst = per.max(axis=0)
    out = {acc_set: dataclasses.replace(base_acc, threshold=float(worst[:3].max())),
           gyro_set: dataclasses.replace(base_gyro, threshold=float(worst[3:].max()))}
    echo(f"calibrate_imu_thresholds ({estimator}): {len(runs)} fault-free runs "
         f"({list(manoeuvres)} x seeds {list(seeds)}, {duration_s:g} s, turbulence), "
         f"rule={rule} k={k}")
    for i, a in enumerate(AXES):
        j = int(np.argmax(per[:, i]))
        unit = "m/s^2" if i < 3 else "deg/s"
        echo(f"  {a}: J_th = {per[j, i] * REPORT_SCALE[i]:.4g} {unit} (worst run {runs[j].name});"
             f" without the first {STARTUP_S:g} s: {warm[:, i].max() * REPORT_SCALE[i]:.4g}")
    echo(f"  -> fdi.{acc_set}.threshold_mps2 = {out[acc_set].threshold:.4g} (n_eval "
         f"{out[acc_set].n_eval}, n_detect {out[acc_set].n_detect})")
    echo(f"  -> fdi.{gyro_set}.threshold_degps = {out[gyro_set].threshold * RAD2DEG:.4g} (n_eval "
         f"{out[gyro_set].n_eval}, n_detect {out[gyro_set].n_detect})")
    return out


def detection_config(sets: dict[str, SetConfig]) -> MonitorConfig:
    base = MonitorConfig(estimators=EstimatorsConfig(airdata="none"))
    return dataclasses.replace(base, fdi=dataclasses.replace(base.fdi, **sets))


def _det_run(preset: str | None, manoeuvre: str | None, seed: int, duration_s: float,
             cfg: MonitorConfig, estimator: str = "imu_ts") -> ImuRun:
    if preset is None:
        sc = fault_free_variant(manoeuvre or "level", seed, duration_s=duration_s)
    else:
        name, _, only = preset.partition(":")
        sc = scenario(name, seed=seed)
        if only:
            sc = dataclasses.replace(sc, name=preset.replace(":", "_"), faults=tuple(
                f for f in sc.faults if f.channel.startswith(f"imu0.{only}.")))
    return simulate(sc, DETECTION_ESTIMATORS[estimator][0], cfg)


def detection_summary(run: ImuRun, estimator: str = "imu_ts") -> dict[str, Any]:
    """Per channel: first-raise delay after the fault start; false alarms (raised on a channel
    without a fault, or before its fault started)."""
    faulty = np.any(run.f_true != 0.0, axis=0)
    raised = [e for e in run.events if e.state == AlarmState.RAISED and e.estimator == estimator]
    out: dict[str, Any] = {"delay_s": [math.nan] * 6, "false": 0, "missed": 0}
    for i, ch in enumerate(FAULT_CHANNELS):
        evs = sorted(e.t_us * 1e-6 for e in raised if e.channel == ch)
        if faulty[i]:
            on = np.nonzero(run.f_true[:, i] != 0.0)[0]
            t_on = float(run.t_s[on[0]])
            t_off = float(run.t_s[on[-1]])
            hits = [t for t in evs if t_on <= t <= t_off + QUIET_AFTER_S]
            out["false"] += sum(1 for t in evs if t < t_on)
            if hits:
                out["delay_s"][i] = hits[0] - t_on
            else:
                out["missed"] += 1
        else:
            out["false"] += len(evs)
    return out


def imu_detection(out_dir: Path, jobs: int = 1, quick: bool = False,
                  estimator: str = "imu_ts") -> str:
    """Thresholds from fault-free runs of calibration seeds, then detection delays and isolation
    on the Table 2 (and Atmaca2025) scenarios and false alarms on fault-free manoeuvres in
    turbulence with the evaluation seeds. ``quick``: one calibration seed, one evaluation seed,
    30 s fault-free runs. ``estimator``: see :data:`DETECTION_ESTIMATORS`."""
    out_dir = Path(out_dir)
    lines: list[str] = []
    cal_seeds = CALIBRATION_SEEDS[:1] if quick else CALIBRATION_SEEDS
    eval_seeds = EVAL_SEEDS[:1] if quick else EVAL_SEEDS
    dur = 30.0 if quick else 60.0
    acc_set, gyro_set = DETECTION_ESTIMATORS[estimator][1]
    sets = calibrate_imu_thresholds(seeds=cal_seeds, duration_s=dur, jobs=jobs,
                                    echo=lines.append, estimator=estimator)
    cfg = detection_config(sets)
    presets = TABLE2_PRESETS + ISOLATION_VARIANTS
    args: list[tuple[Any, ...]] = [(p, None, s, dur, cfg, estimator) for p in presets
                                   for s in eval_seeds]
    args += [(None, m, s, dur, cfg, estimator) for m in MANOEUVRES for s in eval_seeds]
    runs = _pmap(_det_run, args, jobs)
    header = ["scenario", "seed"] + [f"delay {a} [s]" for a in AXES] + [
        "missed", "false alarms"]
    rows = []
    ff_rows = []
    for a, run in zip(args, runs, strict=True):
        d = detection_summary(run, estimator)
        name = a[0] if a[0] is not None else f"fault-free {a[1]}"
        if a[0] is not None:
            rows.append([name, a[2]] + [float(x) for x in d["delay_s"]]
                        + [d["missed"], d["false"]])
        else:
            f = np.abs(run.f_hat[estimator]) * REPORT_SCALE
            late = run.t_s >= run.t_s[0] + STARTUP_S
            fmax = np.concatenate([np.nanmax(f, axis=0), np.nanmax(f[late], axis=0)])
            ff_rows.append([name, a[2], d["false"]] + [float(x) for x in fmax])
    tag = "" if estimator == "imu_ts" else f"_{estimator}"
    write_csv(out_dir / f"imu_detection{tag}.csv", header, rows)
    ff_header = ["scenario", "seed", "alarms"] + [f"max abs {a}" for a in AXES] + [
        f"max abs {a} after {STARTUP_S:g} s" for a in AXES]
    write_csv(out_dir / f"imu_detection{tag}_fault_free.csv", ff_header, ff_rows)
    thr = (f"Thresholds of {estimator} (n_eval {sets[acc_set].n_eval}, n_detect "
           f"{sets[acc_set].n_detect}): acc {sets[acc_set].threshold:.4g} m/s^2, gyro "
           f"{sets[gyro_set].threshold * RAD2DEG:.4g} deg/s")
    return ("Calibration (fault-free, seeds " + str(list(cal_seeds)) + "):\n\n```\n"
            + "\n".join(lines) + "\n```\n\n" + thr + "\n\nDetection (delay = first alarm "
            "raised on the channel minus the channel's fault start; '-' = channel not faulty "
            "or missed):\n\n" + md_table(header, rows) + "\n\nFault-free runs in turbulence "
            f"({dur:g} s; max |f_hat| acc m/s^2, gyro deg/s):\n\n"
            + md_table(ff_header, ff_rows) + "\n")


def imu_detection_hosm(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """:func:`imu_detection` for the OTSEKF+HOSM (Atmaca2025) with its own thresholds
    (``fdi.acc_hosm``, ``fdi.gyro_hosm``), calibrated the same way on the same calibration
    seeds (not the evaluation seeds)."""
    return imu_detection(out_dir, jobs, quick, estimator="imu_hosm")


def experiments() -> dict[str, Callable[[Path, int, bool], str]]:
    out: dict[str, Callable[[Path, int, bool], str]] = {
        "lu2016_table2": lu2016_table2,
        "atmaca2025": atmaca2025,
        "imu_detection": imu_detection,
        "imu_detection_hosm": imu_detection_hosm,
    }
    out["closed_loop"] = closed_loop
    return out


# ------------------------------------------------------------------------------------------------
# 5. closed loop: the simulator flies on the (corrected) IMU
# ------------------------------------------------------------------------------------------------

CF_TAU_S = 5.0  # complementary-filter time constant of the autopilot's attitude


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

    def __init__(self, faults: tuple[Any, ...], seed: int, *, corrected: bool) -> None:
        from sim_vehicle.faults.profiles import FaultInjector

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
        from gcs_monitor.telemetry.frame import Frame, ImuSample

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
            from gcs_monitor.core.frames import euler_rates

            self.att = self.att + dt * euler_rates(phi, theta, w)
            tilt = np.array([math.atan2(-acc[1], -acc[2]),
                             math.atan2(acc[0], math.hypot(acc[1], acc[2]))])
            self.att[:2] += (dt / CF_TAU_S) * (tilt - self.att[:2])
            self.att[2] = (self.att[2] + math.pi) % (2 * math.pi) - math.pi
        self.t_prev = st.t_s
        return dataclasses.replace(st, omega_frd_radps=w.copy(), euler_rad=self.att.copy(),
                                   acc_frd_mps2=acc.copy())


def closed_loop_run(sc: Any, *, corrected: bool, faulty: bool) -> dict[str, np.ndarray]:
    """Fly ``sc`` with :class:`ImuInTheLoop`; returns the true trajectory (t, alt, tas, phi,
    psi) at every step."""
    from sim_vehicle.run import make_simulation

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


CLOSED_LOOP_CASES = (("lu2016_calm", "acc", "level"), ("lu2016_calm", "gyro", "s_turn"))


def _cl_case(preset: str, only: str, manoeuvre: str, mode: str) -> dict[str, np.ndarray]:
    sc = scenario(preset)
    sc = dataclasses.replace(
        sc, faults=tuple(f for f in sc.faults if f.channel.startswith(f"imu0.{only}.")),
        manoeuvre=dataclasses.replace(sc.manoeuvre, kind=manoeuvre))
    return closed_loop_run(sc, corrected=mode == "corrected", faulty=mode != "fault-free")


def closed_loop(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """Tracking deviation from the fault-free closed-loop flight (same seed, same autopilot
    sensing) with and without IMU correction, over the fault window (10-30 s)."""
    out_dir = Path(out_dir)
    modes = ("fault-free", "uncorrected", "corrected")
    args = [(p, o, m, mode) for p, o, m in CLOSED_LOOP_CASES for mode in modes]
    res = _pmap(_cl_case, args, jobs)
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
