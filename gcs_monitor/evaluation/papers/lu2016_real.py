"""Lu2016 on real data: open-loop IMU fault reconstruction on real flights (Lu2016 sec. 5),
through the MAVLink path (experiment ``imu_real``).

Each flight is converted to a contract .tlog by ``gcs_monitor.convert.writer.convert_file`` twice:
with the Lu2016 Table 2 faults added to IMU 0 (``lu2016_table2_injector()``; the converter
returns the injected values as truth) and without. Both tlogs are replayed through the
:class:`Monitor` (decode, FrameAssembler, GS-KM ATSEKF, channel FDI).

Noise settings (not tuned per flight; one set per data source, from the data's own statistics):

* Zipline (50 Hz): accelerometer / gyro sigma = the per-axis standard deviation while the
  aircraft sits on the launcher (t < -1.2 s since launch, data README), median over all flights,
  largest axis. Velocity and Euler angles are estimator outputs (smooth, zero-velocity clamp
  before launch), so their "noise" is taken from the one-step strapdown mismatch in flight
  (t > 0.5 s, reset window masked): ``e_k = v_k - v_{k-1} - dt (C_ned_frd f_k + g)`` and
  ``e_k = Euler_k - Euler_{k-1} - dt (E(phi, theta) omega)`` (trapezoid), sigma = RMS(e) /
  sqrt(2), median over flights, largest axis. For the Euler angles this is 3.3e-4 rad (roll),
  18x the 1.9e-5 rad on the launcher: the data README's "gyro agrees with the Euler rates to
  0.02 rad/s RMS" in flight. The larger of the two (stationary, in flight) is used.
* OnSpeed / VN-300 (50 Hz, 30 s, no stationary part): accelerometer and gyro sigma from the
  sample-to-sample differences in flight, std(diff x) / sqrt(2), largest axis (the VN-300 rates
  are quantised to 0.01 rad/s; the quantisation sigma 0.01/sqrt(12) is the floor); Euler sigma =
  median of the VN-300's own ``vn*Sigma`` outputs; GNSS velocity sigma = RMS of VN-300 INS minus
  raw GNSS velocity (data README: 0.28/0.28/0.50 m/s), largest axis.

Scoring (Zipline): times are seconds since launch; only t > 0.5 s after launch is scored (the
catapult stroke at -0.62..-0.06 s is 7 g and the launcher clamps velocity to zero before it). The
estimator-reset window (7.4-8.9 s, GPS velocity masked by the converter, so the filter restarts)
plus SCORE_DELAY_S after it is excluded. The injected window is scored from its start + 1 s.

FDI thresholds on real data: Zipline flights are split by index: the even-index flights'
fault-free replays calibrate the IMU channel thresholds (``fdi.monitor.calibrate``, rule
"max", over the monitor's windows: ``[imu.ts.fdi] window_s`` = 0.5 s, 25 samples of the 50 Hz
IMU), the odd-index flights are the evaluation set for the alarm check. OnSpeed (one flight) is
checked with the Zipline thresholds and with the monitor defaults. "Re-anchor notices" counts
the ESTIMATOR events (gcs_monitor/families/imu/gating.py: a velocity or attitude step the IMU
cannot explain, or an input gap; states re-anchored, fault estimates kept, channels not judged
while re-converging) -- what the operator sees instead of an IMU fault alarm.

The data folder is :func:`gcs_monitor.evaluation.data.real_data_dir` (``--data-dir``,
``GCS_DATA_DIR``); the replays run in the evaluation's process pool
(:func:`~gcs_monitor.evaluation.runner.run_parallel`).
"""

from __future__ import annotations

import csv
import math
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from gcs_monitor.convert.writer import convert_file, lu2016_table2_injector
from gcs_monitor.core.frames import dcm_ned_frd, euler_rates
from gcs_monitor.core.units import RAD2DEG
from gcs_monitor.evaluation.configs import (
    imu_config,
    imu_fdi_sets,
    measured_period_s,
    window_n,
    with_imu_noise,
    with_imu_thresholds,
)
from gcs_monitor.evaluation.data import real_data_file
from gcs_monitor.evaluation.records import AXES, REPORT_SCALE
from gcs_monitor.evaluation.report import md_table, write_csv
from gcs_monitor.evaluation.runner import run_parallel
from gcs_monitor.evaluation.runs import replay_packets, tlog_chunks
from gcs_monitor.evaluation.scoring import SCORE_DELAY_S
from gcs_monitor.families.imu.config import ImuFamilyConfig
from gcs_monitor.families.imu.imu_ts import FAULT_CHANNELS, Lu2016Table1
from gcs_monitor.fdi.events import AlarmState
from gcs_monitor.fdi.monitor import calibrate

ZIPLINE_DIR = "zipline_launch"  # in the real-data folder
ONSPEED_FILE = "onspeed_vac_decel_stall_50hz.csv"  # in the real-data folder
ZIPLINE_T0_S = -5.0  # converter time 0 = first row; rows start 5 s before launch
LAUNCH_SETTLE_S = 0.5
STATIONARY_BEFORE_S = -1.2
RESET_S = (7.4, 8.9)
G_MPS2 = 9.78  # only for the velocity-mismatch statistic (Muhanga, 1,700 m)


# ------------------------------------------------------------------------------------------------
# noise from the data
# ------------------------------------------------------------------------------------------------


def _zipline_csv(path: Path) -> dict[str, np.ndarray]:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    h = rows[0]
    a = np.array([[float(x) if x else math.nan for x in r] for r in rows[1:]])

    def cols(stem: str) -> np.ndarray:
        return a[:, [h.index(f"{stem}[{i}]") for i in range(3)]]

    return {"t": a[:, h.index("seconds_since_launch")], "v": cols("velocity_ned_mps"),
            "f": cols("accel_body_mps2"), "w": cols("angular_rate_body_radps"),
            "e": cols("orientation_rad")}


def zipline_noise(paths: list[Path]) -> tuple[Lu2016Table1, dict[str, float]]:
    """Noise sigmas for all Zipline flights (module docstring); also returns the statistics."""
    acc, gyr, eul, vel, eul_fl = [], [], [], [], []
    for p in paths:
        d = _zipline_csv(p)
        still = d["t"] < STATIONARY_BEFORE_S
        acc.append(np.nanstd(d["f"][still], axis=0))
        gyr.append(np.nanstd(d["w"][still], axis=0))
        eul.append(np.nanstd(d["e"][still], axis=0))
        fl = (d["t"] > LAUNCH_SETTLE_S) & ~((d["t"] >= RESET_S[0] - 0.1) & (d["t"] <= RESET_S[1]))
        idx = np.nonzero(fl[1:] & fl[:-1])[0] + 1
        dt = np.diff(d["t"])[idx - 1]
        pred = np.array([dcm_ned_frd(*d["e"][k]) @ d["f"][k] for k in idx]) + [0, 0, G_MPS2]
        e = d["v"][idx] - d["v"][idx - 1] - dt[:, None] * pred
        vel.append(np.sqrt(np.nanmean(e * e, axis=0)) / math.sqrt(2.0))
        # attitude the same way: one-step Euler increment minus the gyro-predicted increment
        # (trapezoid of Lu2016 eq. 11 rows 4-6 without the earth/transport rates, < 1e-4 rad/s)
        rates = np.array([euler_rates(d["e"][k, 0], d["e"][k, 1], d["w"][k])
                          for k in range(len(d["t"]))])
        de = d["e"][idx] - d["e"][idx - 1]
        de[:, 2] = (de[:, 2] + math.pi) % (2.0 * math.pi) - math.pi
        ee = de - 0.5 * dt[:, None] * (rates[idx] + rates[idx - 1])
        eul_fl.append(np.sqrt(np.nanmean(ee * ee, axis=0)) / math.sqrt(2.0))
    st = {"acc_sigma_mps2": float(np.median(acc, axis=0).max()),
          "gyro_sigma_radps": float(np.median(gyr, axis=0).max()),
          "euler_sigma_rad": float(max(np.median(eul, axis=0).max(),
                                       np.median(eul_fl, axis=0).max())),
          "vel_sigma_mps": float(np.median(vel, axis=0).max())}
    return Lu2016Table1(**st), st


def onspeed_noise(path: Path) -> tuple[Lu2016Table1, dict[str, float]]:
    """Noise sigmas of the OnSpeed / VN-300 flight (module docstring); also the statistics."""
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    h = [x.strip() for x in rows[0]]

    def col(n: str) -> np.ndarray:
        i = h.index(n)
        return np.array([float(r[i]) if i < len(r) and r[i].strip() else math.nan
                         for r in rows[1:]])

    acc = np.column_stack([col(n) for n in ("vnAccelFwd", "vnAccelLat", "vnAccelVert")])
    gyr = np.column_stack([col(n) for n in ("vnAngularRateRoll", "vnAngularRatePitch",
                                            "vnAngularRateYaw")])
    ins = np.column_stack([col(f"vnVelNed{a}") for a in ("North", "East", "Down")])
    gnss = np.column_stack([col(f"vnGnssVelNed{a}") for a in ("North", "East", "Down")])
    sig = np.column_stack([col(n) for n in ("vnRollSigma", "vnPitchSigma", "vnYawSigma")])
    quant = 0.01 / math.sqrt(12.0)
    st = {"acc_sigma_mps2": float((np.nanstd(np.diff(acc, axis=0), axis=0) / math.sqrt(2)).max()),
          "gyro_sigma_radps": float(max(quant, (np.nanstd(np.diff(gyr, axis=0), axis=0)
                                                / math.sqrt(2)).max())),
          "euler_sigma_rad": float(np.nanmedian(sig, axis=0).max() / RAD2DEG),
          "vel_sigma_mps": float(np.sqrt(np.nanmean((ins - gnss) ** 2, axis=0)).max())}
    return Lu2016Table1(**st), st


def imu_for(noise: Lu2016Table1, thresholds: ImuFamilyConfig | None = None
            ) -> ImuFamilyConfig:
    """The monitor's IMU family (GS-KM ATSEKF) with a data source's sensor noise and the
    channel thresholds of ``thresholds`` (default: the ``[imu]`` defaults). The estimator
    measures the IMU period (50 Hz for both sources) itself."""
    return with_imu_noise(thresholds or ImuFamilyConfig(), noise)


Replay = tuple[Path, Path, str, Lu2016Table1, bool, ImuFamilyConfig | None]


def replay_flight(job: Replay) -> dict[str, Any]:
    """Convert (optionally with the Lu2016 Table 2 injection) and replay one flight; ``job`` is
    (flight file, temporary folder, a tag that makes the tlog name unique, noise, inject,
    the IMU family whose thresholds to use or None for the defaults); the monitor is
    :func:`~gcs_monitor.evaluation.configs.imu_config` with :func:`imu_for`."""
    path, tmp, tag, noise, inject, thresholds = job
    out = tmp / f"{tag}_{path.stem}{'_inj' if inject else '_clean'}.tlog"
    res = convert_file(path, out, inject_imu=lu2016_table2_injector() if inject else None)
    notices: list[Any] = []
    t_s, f_hat, events = replay_packets(tlog_chunks(out), imu_config(imu_for(noise, thresholds)),
                                        notices=notices)
    f = f_hat.get("imu_ts", np.full((len(t_s), 6), math.nan))
    truth = np.zeros((len(t_s), 6))
    if res.injected_imu is not None:
        for i in range(6):
            truth[:, i] = np.interp(t_s, res.t_s, res.injected_imu[:, i])
    out.unlink(missing_ok=True)
    return {"t_s": t_s, "f_hat": f, "truth": truth, "events": events, "notices": notices}


def _masks(r: dict[str, Any], zipline: bool) -> tuple[np.ndarray, np.ndarray]:
    """(in injected window, fault-free) scoring masks; see the module docstring."""
    t = r["t_s"] + (ZIPLINE_T0_S if zipline else 0.0)  # seconds since launch for Zipline
    ok = np.isfinite(r["f_hat"]).all(axis=1)
    if zipline:
        ok &= t > LAUNCH_SETTLE_S
        ok &= ~((t >= RESET_S[0]) & (t <= RESET_S[1] + SCORE_DELAY_S))
    on = np.any(r["truth"] != 0.0, axis=1)
    if on.any():
        idx = np.nonzero(on)[0]
        t_on, t_off = t[idx[0]], t[idx[-1]]
        inj = ok & (t >= t_on + SCORE_DELAY_S) & (t <= t_off)
    else:
        inj = np.zeros(len(t), dtype=bool)
    return inj, ok & ~on


def _rmse(r: dict[str, Any], m: np.ndarray) -> np.ndarray:
    e = (r["f_hat"] - r["truth"])[m] * REPORT_SCALE
    return np.sqrt(np.mean(e * e, axis=0)) if len(e) else np.full(6, math.nan)


def _alarms(r: dict[str, Any], m_time: np.ndarray | None = None) -> int:
    raised = [e for e in r["events"] if e.state == AlarmState.RAISED]
    if m_time is None:
        return len(raised)
    t = r["t_s"]
    ok_t = t[m_time]
    return sum(1 for e in raised if ok_t.size and ok_t[0] <= e.t_us * 1e-6 <= ok_t[-1])


def _channels_alarmed(r: dict[str, Any]) -> list[bool]:
    """Per channel: an alarm raised on it between its injection start and end (+1 s)."""
    t = r["t_s"]
    out = []
    for i, ch in enumerate(FAULT_CHANNELS):
        on = np.nonzero(r["truth"][:, i] != 0.0)[0]
        if not len(on):
            out.append(False)
            continue
        t0, t1 = t[on[0]], t[on[-1]] + 1.0
        out.append(any(e.state == AlarmState.RAISED and e.channel == ch
                       and t0 <= e.t_us * 1e-6 <= t1 for e in r["events"]))
    return out


def _thresholds(runs: list[dict[str, Any]], zipline: bool) -> ImuFamilyConfig:
    """IMU channel J_th from fault-free replays (rule "max" over the scored samples), each
    over the N_eval-sample windows the monitor uses at the replay's measured IMU period."""
    base = ImuFamilyConfig()
    sets = imu_fdi_sets(base)
    thr = np.zeros(6)
    for r in runs:
        _, ff = _masks(r, zipline)
        period_s = measured_period_s(r["t_s"])
        for i in range(6):
            n = window_n(sets.acc if i < 3 else sets.gyro, period_s)
            if ff.sum() >= n:
                thr[i] = max(thr[i], calibrate(r["f_hat"][ff, i], rms_window_n=n))
    return with_imu_thresholds(base, float(thr[:3].max()), float(thr[3:].max()))




def imu_real(out_dir: Path, jobs: int, quick: bool, data_dir: Path) -> str:
    """Open-loop validation on the Zipline flights and the OnSpeed flight (module docstring).
    ``quick``: the first 8 Zipline flights."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    zips = sorted(real_data_file(data_dir, ZIPLINE_DIR).glob("flight_*.csv"))
    onspeed = real_data_file(data_dir, ONSPEED_FILE)
    if quick:
        zips = zips[:8]
    zn, zst = zipline_noise(zips)
    on, ost = onspeed_noise(onspeed)
    lines = ["Noise from the data (SI): Zipline " + ", ".join(f"{k} {v:.3g}" for k, v in
                                                             zst.items()),
             "OnSpeed/VN-300 " + ", ".join(f"{k} {v:.3g}" for k, v in ost.items())]
    rows: list[list[Any]] = []
    with tempfile.TemporaryDirectory() as td:
        tmp = Path(td)
        clean = run_parallel(replay_flight, [(p, tmp, "a", zn, False, None) for p in zips],
                             jobs, desc="imu_real calibrate")
        imu = _thresholds(clean[0::2], zipline=True)
        n, n_eval = len(zips), len(zips[1::2])
        work: list[Replay] = [(p, tmp, "b", zn, True, imu) for p in zips]
        work += [(p, tmp, "c", zn, False, imu) for p in zips[1::2]]
        work += [(onspeed, tmp, "d", on, True, imu), (onspeed, tmp, "e", on, False, imu),
                 (onspeed, tmp, "f", on, False, None)]
        res = run_parallel(replay_flight, work, jobs, desc="imu_real")
        inj, eval_clean = res[:n], res[n:n + n_eval]
        r_on_inj, r_on_clean, r_on_clean_def = res[n + n_eval:]
    lines.append(f"Zipline thresholds from the fault-free replays of flights {zips[0].stem}, "
                 f"every 2nd ({len(clean[0::2])}): acc {imu_fdi_sets(imu).acc.threshold:.4g} "
                 f"m/s^2, gyro {imu_fdi_sets(imu).gyro.threshold * RAD2DEG:.4g} deg/s")
    z = np.array([_rmse(r, _masks(r, True)[0]) for r in inj])
    rows.append(["Zipline median", len(zips)] + [float(x) for x in np.nanmedian(z, axis=0)])
    rows.append(["Zipline worst", len(zips)] + [float(x) for x in np.nanmax(z, axis=0)])
    rows.append(["OnSpeed", 1] + [float(x) for x in _rmse(r_on_inj, _masks(r_on_inj, False)[0])])
    header = ["flights", "n"] + [f"RMSE {a}" for a in AXES]
    write_csv(out_dir / "imu_real_rmse.csv", header, rows)
    write_csv(out_dir / "imu_real_zipline_per_flight.csv", ["flight"] + list(AXES),
              [[p.stem] + [float(x) for x in zz] for p, zz in zip(zips, z, strict=True)])
    det = [sum(1 for e in r["events"] if e.state == AlarmState.RAISED) for r in inj]
    ch_hit = np.array([_channels_alarmed(r) for r in inj])
    on_hit = _channels_alarmed(r_on_inj)
    ff_rows: list[list[Any]] = []
    for label, runs, zl in (("Zipline (evaluation half)", eval_clean, True),
                            ("Zipline (all, default thresholds)", clean, True),
                            ("OnSpeed (Zipline thresholds)", [r_on_clean], False),
                            ("OnSpeed (default thresholds)", [r_on_clean_def], False)):
        fmax = np.max([np.nanmax(np.abs(r["f_hat"][_masks(r, zl)[1]]) * REPORT_SCALE, axis=0)
                       for r in runs], axis=0)
        n_al = sum(_alarms(r) for r in runs)
        n_no = sum(sum(1 for e in r["notices"] if e.state == AlarmState.RAISED) for r in runs)
        ff_rows.append([label, len(runs), n_al, n_no] + [float(x) for x in fmax])
    ff_header = ["fault-free replay", "n", "alarms", "re-anchor notices"] + [
        f"max abs {a}" for a in AXES]
    write_csv(out_dir / "imu_real_fault_free.csv", ff_header, ff_rows)
    return ("\n".join(f"- {x}" for x in lines) + "\n\nInjected Lu2016 Table 2 faults: RMSE of "
            "f_hat - f (acc m/s^2, gyro deg/s) in the injected window (from start + "
            f"{SCORE_DELAY_S:g} s; Zipline: t > {LAUNCH_SETTLE_S} s after launch, reset window "
            "excluded):\n\n" + md_table(header, rows) + f"\n\nInjected replays with alarms: "
            f"{sum(1 for d in det if d > 0)}/{len(det)} Zipline. Injected channel alarmed "
            "(alarm raised on that channel inside the injected window): "
            + ", ".join(f"{a} {int(ch_hit[:, i].sum())}/{len(inj)}" for i, a in enumerate(AXES))
            + " Zipline; OnSpeed " + ", ".join(f"{a} {'yes' if on_hit[i] else 'no'}"
                                               for i, a in enumerate(AXES))
            + ".\n\nWithout injection "
            "(max |f_hat| over the scored fault-free samples; alarms over the whole flight):"
            "\n\n" + md_table(ff_header, ff_rows) + "\n")


def real_data_experiments() -> dict[str, Callable[[Path, int, bool, Path], str]]:
    """Named experiments on the real data (registry hook)."""
    return {"imu_real": imu_real}
