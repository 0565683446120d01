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
from gcs_monitor.config.loader import FdiConfig, SetConfig
from gcs_monitor.core.units import RAD2DEG
from gcs_monitor.evaluation.configs import DETECTION_ESTIMATORS, imu_config, set_thresholds
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
from gcs_monitor.fdi.monitor import calibrate

CALIBRATION_SEEDS = (101, 102)
EVAL_SEEDS = (1, 2, 3)


def _ff_run(job: tuple[str, int, float, str]) -> ImuRun:
    manoeuvre, seed, duration_s, estimator = job
    return simulate_imu(fault_free_variant(manoeuvre, seed, duration_s=duration_s),
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
    ``"imu_hosm"`` (sets ``acc_hosm``, ``gyro_hosm``), see
    :data:`~gcs_monitor.evaluation.configs.DETECTION_ESTIMATORS`.
    Prints the numbers; returns ``{acc set: ..., gyro set: ...}``.
    """
    base = base or FdiConfig()
    acc_set, gyro_set = DETECTION_ESTIMATORS[estimator][1]
    base_acc, base_gyro = getattr(base, acc_set), getattr(base, gyro_set)
    args = [(m, s, duration_s, estimator) for m in manoeuvres for s in seeds]
    runs = run_parallel(_ff_run, args, jobs, desc="calibrate")
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
    out = set_thresholds({acc_set: float(worst[:3].max()), gyro_set: float(worst[3:].max())},
                         base)
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


def _det_run(job: tuple[str | None, str | None, int, float, MonitorConfig, str]) -> ImuRun:
    spec, manoeuvre, seed, duration_s, cfg, estimator = job
    if spec is None:
        sc = fault_free_variant(manoeuvre or "level", seed, duration_s=duration_s)
    else:
        sc = detection_scenario(spec, seed)
    return simulate_imu(sc, DETECTION_ESTIMATORS[estimator][0], cfg)


def imu_detection(out_dir: Path, jobs: int = 1, quick: bool = False,
                  estimator: str = "imu_ts") -> str:
    """Thresholds from fault-free runs of calibration seeds, then detection delays and isolation
    on the Table 2 (and Atmaca2025) scenarios and false alarms on fault-free manoeuvres in
    turbulence with the evaluation seeds. ``quick``: one calibration seed, one evaluation seed,
    30 s fault-free runs. ``estimator``: see
    :data:`~gcs_monitor.evaluation.configs.DETECTION_ESTIMATORS`."""
    out_dir = Path(out_dir)
    lines: list[str] = []
    cal_seeds = CALIBRATION_SEEDS[:1] if quick else CALIBRATION_SEEDS
    eval_seeds = EVAL_SEEDS[:1] if quick else EVAL_SEEDS
    dur = 30.0 if quick else 60.0
    acc_set, gyro_set = DETECTION_ESTIMATORS[estimator][1]
    sets = calibrate_imu_thresholds(seeds=cal_seeds, duration_s=dur, jobs=jobs,
                                    echo=lines.append, estimator=estimator)
    cfg = imu_config(sets)
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
    return {"imu_detection": imu_detection, "imu_detection_hosm": imu_detection_hosm}
