"""IMU fault detection with the monitor's channel FDI (Lu2016 ATSEKF, Atmaca2025 OTSEKF+HOSM).

Thresholds J_th come from fault-free runs of calibration seeds by Wan2018 sec. VI-B's rule
(:func:`gcs_monitor.fdi.monitor.calibrate`); then detection delays and isolation on the Lu2016
Table 2 (and Atmaca2025) scenarios and false alarms on fault-free manoeuvres in turbulence with
the evaluation seeds, every run through the MAVLink path
(:func:`~gcs_monitor.evaluation.runs.simulate_imu`).

* ``imu_detection`` -- the monitor's default IMU estimator (``imu_ts``, GS-KM ATSEKF);
* ``imu_detection_hosm`` -- the same for ``imu_hosm`` (OTSEKF+HOSM) with its own thresholds.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gcs_monitor.config import MonitorConfig
from gcs_monitor.core.units import RAD2DEG
from gcs_monitor.evaluation.configs import (
    IMU_SECTIONS,
    detect_n,
    imu_config,
    imu_fdi_sets,
    imu_running,
    measured_period_s,
    sim_imu_period_s,
    window_n,
    with_imu_thresholds,
)
from gcs_monitor.evaluation.records import AXES, REPORT_SCALE, ImuRun
from gcs_monitor.evaluation.report import md_table, write_csv
from gcs_monitor.evaluation.runner import run_parallel
from gcs_monitor.evaluation.runs import simulate_imu
from gcs_monitor.evaluation.scenarios import (
    ISOLATION_VARIANTS,
    MANOEUVRES,
    TABLE2_PRESETS,
    detection_scenario,
    fault_free_variant,
)
from gcs_monitor.evaluation.scoring import STARTUP_S, detection_summary
from gcs_monitor.families.imu.config import ImuFamilyConfig
from gcs_monitor.fdi.monitor import calibrate

CALIBRATION_SEEDS = (101, 102)
EVAL_SEEDS = (1, 2, 3)


def _ff_run(job: tuple[str, int, float, str]) -> ImuRun:
    manoeuvre, seed, duration_s, estimator = job
    return simulate_imu(fault_free_variant(manoeuvre, seed, duration_s=duration_s),
                        imu_config(imu_running(estimator)))


def calibrate_imu_thresholds(*, seeds: Sequence[int] = CALIBRATION_SEEDS,
                             manoeuvres: Sequence[str] = MANOEUVRES, duration_s: float = 60.0,
                             jobs: int = 1, rule: str = "max", k: float | None = None,
                             base: ImuFamilyConfig | None = None,
                             echo: Callable[[str], None] = print,
                             estimator: str = "imu_ts") -> ImuFamilyConfig:
    """IMU channel thresholds J_th from fault-free runs (Wan2018 sec. VI-B rule, fdi.calibrate).

    Fault-free variants of lu2016_turbulence (every manoeuvre, Dryden turbulence, the given
    seeds -- NOT the evaluation seeds) run through the Monitor with ``estimator`` alone;
    ``calibrate`` over each channel's whole f_hat record (start-up included, since fault-free
    runs must not alarm at start-up either) with the monitor's N_eval (its window at the
    run's IMU period); the threshold of the acc (gyro) set is the largest over its three
    channels. Windows and confirmation stay as in ``base`` (default: the ``[imu]`` defaults).
    ``estimator``: ``"imu_ts"`` (sets ``[imu.ts.fdi]``) or ``"imu_hosm"`` (``[imu.hosm.fdi]``).
    Prints the numbers; returns ``base`` running ``estimator`` with those thresholds.
    """
    imu = imu_running(estimator, base)
    sets = imu_fdi_sets(imu, estimator)
    args = [(m, s, duration_s, estimator) for m in manoeuvres for s in seeds]
    runs = run_parallel(_ff_run, args, jobs, desc="calibrate")
    per = np.zeros((len(runs), 6))
    warm = np.zeros((len(runs), 6))  # the same without the first STARTUP_S (for the report)
    for j, run in enumerate(runs):
        f = run.f_hat[estimator]
        late = run.t_s >= run.t_s[0] + STARTUP_S
        period_s = measured_period_s(run.t_s)
        for i in range(6):
            n = window_n(sets.acc if i < 3 else sets.gyro, period_s)
            per[j, i] = calibrate(f[:, i], rms_window_n=n, rule=rule, k=k)
            warm[j, i] = calibrate(f[late, i], rms_window_n=n, rule=rule, k=k)
    worst = per.max(axis=0)
    out = with_imu_thresholds(imu, float(worst[:3].max()), float(worst[3:].max()), estimator)
    new = imu_fdi_sets(out, estimator)
    key = f"imu.{IMU_SECTIONS[estimator]}.fdi"
    p = sim_imu_period_s()
    echo(f"calibrate_imu_thresholds ({estimator}): {len(runs)} fault-free runs "
         f"({list(manoeuvres)} x seeds {list(seeds)}, {duration_s:g} s, turbulence), "
         f"rule={rule} k={k}")
    for i, a in enumerate(AXES):
        j = int(np.argmax(per[:, i]))
        unit = "m/s^2" if i < 3 else "deg/s"
        echo(f"  {a}: J_th = {per[j, i] * REPORT_SCALE[i]:.4g} {unit} (worst run {runs[j].name});"
             f" without the first {STARTUP_S:g} s: {warm[:, i].max() * REPORT_SCALE[i]:.4g}")
    echo(f"  -> {key}.acc.threshold_mps2 = {new.acc.threshold:.4g} (n_eval "
         f"{window_n(new.acc, p)}, n_detect {detect_n(new.acc, p)})")
    echo(f"  -> {key}.gyro.threshold_degps = {new.gyro.threshold * RAD2DEG:.4g} (n_eval "
         f"{window_n(new.gyro, p)}, n_detect {detect_n(new.gyro, p)})")
    return out


def _det_run(job: tuple[str | None, str | None, int, float, MonitorConfig, str]) -> ImuRun:
    spec, manoeuvre, seed, duration_s, cfg, estimator = job
    if spec is None:
        sc = fault_free_variant(manoeuvre or "level", seed, duration_s=duration_s)
    else:
        sc = detection_scenario(spec, seed)
    return simulate_imu(sc, cfg)


def imu_detection(out_dir: Path, jobs: int = 1, quick: bool = False,
                  estimator: str = "imu_ts") -> str:
    """Thresholds from fault-free runs of calibration seeds, then detection delays and isolation
    on the Table 2 (and Atmaca2025) scenarios and false alarms on fault-free manoeuvres in
    turbulence with the evaluation seeds. ``quick``: one calibration seed, one evaluation seed,
    30 s fault-free runs. ``estimator``: the monitor's ``imu_ts`` or ``imu_hosm``, run alone
    (:func:`~gcs_monitor.evaluation.configs.imu_running`)."""
    out_dir = Path(out_dir)
    lines: list[str] = []
    cal_seeds = CALIBRATION_SEEDS[:1] if quick else CALIBRATION_SEEDS
    eval_seeds = EVAL_SEEDS[:1] if quick else EVAL_SEEDS
    dur = 30.0 if quick else 60.0
    imu = calibrate_imu_thresholds(seeds=cal_seeds, duration_s=dur, jobs=jobs,
                                   echo=lines.append, estimator=estimator)
    cfg = imu_config(imu)
    presets = TABLE2_PRESETS + ISOLATION_VARIANTS
    args: list[tuple[str | None, str | None, int, float, MonitorConfig, str]] = [
        (p, None, s, dur, cfg, estimator) for p in presets for s in eval_seeds]
    args += [(None, m, s, dur, cfg, estimator) for m in MANOEUVRES for s in eval_seeds]
    runs = run_parallel(_det_run, args, jobs, desc="detection")
    header = ["scenario", "seed"] + [f"delay {a} [s]" for a in AXES] + [
        "missed", "false alarms"]
    rows: list[list[Any]] = []
    ff_rows: list[list[Any]] = []
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
    sets, p = imu_fdi_sets(imu, estimator), sim_imu_period_s()
    thr = (f"Thresholds of {estimator} (n_eval {window_n(sets.acc, p)}, n_detect "
           f"{detect_n(sets.acc, p)}): acc {sets.acc.threshold:.4g} m/s^2, gyro "
           f"{sets.gyro.threshold * RAD2DEG:.4g} deg/s")
    return ("Calibration (fault-free, seeds " + str(list(cal_seeds)) + "):\n\n```\n"
            + "\n".join(lines) + "\n```\n\n" + thr + "\n\nDetection (delay = first alarm "
            "raised on the channel minus the channel's fault start; '-' = channel not faulty "
            "or missed):\n\n" + md_table(header, rows) + "\n\nFault-free runs in turbulence "
            f"({dur:g} s; max |f_hat| acc m/s^2, gyro deg/s):\n\n"
            + md_table(ff_header, ff_rows) + "\n")


def imu_detection_hosm(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """:func:`imu_detection` for the OTSEKF+HOSM (Atmaca2025) with its own thresholds
    (``[imu.hosm.fdi]``), calibrated the same way on the same calibration
    seeds (not the evaluation seeds)."""
    return imu_detection(out_dir, jobs, quick, estimator="imu_hosm")


def experiments() -> dict[str, Callable[[Path, int, bool], str]]:
    return {"imu_detection": imu_detection, "imu_detection_hosm": imu_detection_hosm}
