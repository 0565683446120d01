"""Atmaca2025 experiment: OTSEKF+HOSM against the IOTSEKF and ATSEKF (Tables 2-3).

Every run simulator -> MAVLink bytes -> :class:`~gcs_monitor.monitor.Monitor`
(:func:`~gcs_monitor.evaluation.runs.simulate_imu`), all three estimators on the same Frames
with Atmaca2025 Table 1 sensor noise (:func:`~gcs_monitor.evaluation.configs.atmaca_variants`).
Commands and measured tables: docs/results.md.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from gcs_monitor.evaluation.configs import atmaca_variants
from gcs_monitor.evaluation.records import AXES, REPORT_SCALE, ImuRun
from gcs_monitor.evaluation.report import md_table, plot_imu_run, write_csv
from gcs_monitor.evaluation.runner import run_parallel
from gcs_monitor.evaluation.runs import simulate_imu
from gcs_monitor.evaluation.scenarios import ATMACA_PRESETS, preset
from gcs_monitor.evaluation.scoring import STARTUP_S, rmse, score_masks

ATMACA_NAMES = ("otsekf_hosm", "gs_iotsekf", "gs_atsekf")


def _atmaca_run(job: tuple[str, int | None]) -> ImuRun:
    name, seed = job
    return simulate_imu(preset(name, seed=seed), variants=atmaca_variants)


def atmaca2025(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """OTSEKF+HOSM vs IOTSEKF (and ATSEKF): per-channel RMSE in the fault windows and the
    start-up transient (max |f_hat| over the first 2 s, fault-free), Atmaca2025 Tables 2-3.
    ``quick``: the presets' seeds only; otherwise also seeds 11, 12 (mean RMSE, max transient).
    """
    out_dir = Path(out_dir)
    seeds: tuple[int | None, ...] = (None,) if quick else (None, 11, 12)
    args = [(p, s) for p in ATMACA_PRESETS for s in seeds]
    runs = run_parallel(_atmaca_run, args, jobs, desc="atmaca2025")
    header = ["scenario", "estimator"] + [f"{a} fault" for a in AXES] + [
        f"{a} start max" for a in AXES]
    acc: dict[tuple[str, str], list[np.ndarray]] = {}
    for (name, seed), run in zip(args, runs, strict=True):
        inf, _ = score_masks(run)
        first = run.t_s <= run.t_s[0] + STARTUP_S
        for n in ATMACA_NAMES:
            f = run.f_hat[n]
            start = np.nanmax(np.abs(f[first]) * REPORT_SCALE, axis=0)
            acc.setdefault((name, n), []).append(
                np.concatenate([rmse(f - run.f_true, inf), start]))
        if seed is None:
            plot_imu_run(run, ATMACA_NAMES, out_dir / f"atmaca2025_{name}.png")
    rows = []
    for name in ATMACA_PRESETS:
        for n in ATMACA_NAMES:
            a = np.asarray(acc[(name, n)])
            v = np.concatenate([a[:, :6].mean(axis=0), a[:, 6:].max(axis=0)])
            rows.append([name, n] + [float(x) for x in v])
    write_csv(out_dir / "atmaca2025.csv", header, rows)
    return ("Per-channel RMSE of f_hat - f in the fault windows (acc m/s^2, gyro deg/s; mean over "
            f"{len(seeds)} seed(s)) and start-up transient max |f_hat| over the first "
            f"{STARTUP_S:g} s (fault-free; max over seeds):\n\n" + md_table(header, rows) + "\n")


def experiments() -> dict[str, Callable[[Path, int, bool], str]]:
    return {"atmaca2025": atmaca2025}
