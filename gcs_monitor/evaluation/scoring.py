"""Scores against ground truth: alarms, fault reconstruction and estimation error.

Air data (Wan2018 sec. VI-B, :mod:`gcs_monitor.fdi.metrics`): the alarm events of a run (what
the journal would hold) are compared with the fault intervals per channel from the scenario and
with the fault value actually applied per sample (``run_state.suite.fault_log``): false-alarm,
missed-detection and false-isolation rates and detection delay, per channel kind. Besides, per
run (:func:`score_air_run`):

* fault reconstruction RMSE per faulty channel: RMS over the fault interval of
  ``(y_i - reference) - f_i`` where ``reference`` is what the set's residuals are taken against
  (the MHE prediction, or the consensus) and ``f_i`` the applied fault (truth);
* output error per set and method: RMS of ``fused - true`` (the value handed on downstream:
  adaptive weighted fusion, median selection) and of the MHE's virtual sensor;
* fault-free residual statistics: the largest J per set and what
  :func:`gcs_monitor.fdi.monitor.calibrate` would set J_th to (over never-faulted instances).

IMU (Lu2016, Atmaca2025): per-channel RMSE of ``f_hat - f`` over scoring windows that are the
same for every estimator: the fault window is scored from 1 s after it opens to its end (a step
fault needs a few hundred ms to be followed, as in docs/results.md, "Synthetic truth"); the
fault-free windows are [2 s, first fault start) and [last fault end + 2 s, end of run).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, cast

import numpy as np

from gcs_monitor.config import MonitorConfig
from gcs_monitor.core.types import ChannelId
from gcs_monitor.evaluation.configs import airdata_of, imu_of, sim_air_period_s, window_n
from gcs_monitor.evaluation.records import (
    AIR_SETS,
    IMU_GROUPS,
    METHOD_FIXED,
    METHOD_MEDIAN,
    METHOD_MONITOR,
    METHODS,
    REPORT_SCALE,
    SIM_CHANNELS,
    UNITS,
    FaultResult,
    FaultTruth,
    ImuRun,
    RunRecord,
)
from gcs_monitor.families.imu.imu_ts import FAULT_CHANNELS
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState
from gcs_monitor.fdi.metrics import MetricsRow, evaluate_run, metrics_table
from gcs_monitor.fdi.monitor import calibrate
from sim_vehicle.scenario import Scenario

GRACE_US = 1_000_000  # a latched alarm raised up to 1 s after a fault ended still counts
CALIBRATE_K = 1.5  # calibrate(rule="max") margin over the worst fault-free J
SCORE_DELAY_S = 1.0
QUIET_START_S = 2.0
QUIET_AFTER_S = 2.0
STARTUP_S = 2.0  # IMU estimators' start-up transient, scored on its own


# ------------------------------------------------------------------------------------------------
# air data: truth and alarm scores
# ------------------------------------------------------------------------------------------------


def channel_of(name: str) -> ChannelId | None:
    """Scenario channel name -> monitored ChannelId (air data only: ``aoa1`` -> aoa/1)."""
    for kind in AIR_SETS:
        if name.startswith(kind) and name[len(kind):].isdigit():
            return ChannelId(kind, int(name[len(kind):]))
    return None


def air_fault_truth(sc: Scenario) -> list[FaultTruth]:
    """The scenario's air-data sensor faults as monitored channels and µs intervals."""
    out = []
    for f in sc.faults:
        ch = channel_of(f.channel)
        if ch is None:
            continue
        end = None if f.t_end_s is None else round(f.t_end_s * 1e6)
        out.append(FaultTruth(ch, f.kind, round(f.t_start_s * 1e6), end))
    return out


def truth_intervals(faults: Sequence[FaultTruth]) -> dict[ChannelId, list[tuple[int, int | None]]]:
    out: dict[ChannelId, list[tuple[int, int | None]]] = {}
    for f in faults:
        out.setdefault(f.channel, []).append((f.t_start_us, f.t_end_us))
    return out


def is_counted_raise(e: AlarmEvent) -> bool:
    """A RAISED sensor or actuator alarm (link and SET_LOST alarms are never scored)."""
    return e.state is AlarmState.RAISED and e.kind in (AlarmKind.SENSOR_FAULT,
                                                       AlarmKind.ACTUATOR_FAULT)


def score_faults(method: str, events: Sequence[AlarmEvent],
                 faults: Sequence[FaultTruth]) -> list[FaultResult]:
    """Per injected fault: detected (a counted RAISED on its channel inside its interval) and
    the delay from fault start, s. Same reading as :func:`gcs_monitor.fdi.metrics.evaluate_run`."""
    raised = sorted((e.t_us, e.channel) for e in events if is_counted_raise(e))
    out = []
    for f in faults:
        hit = next((t for t, c in raised if c == f.channel and t >= f.t_start_us
                    and (f.t_end_us is None or t <= f.t_end_us + GRACE_US)), None)
        out.append(FaultResult(method, str(f.channel), f.kind, hit is not None,
                               math.nan if hit is None else (hit - f.t_start_us) * 1e-6))
    return out


def n_raised(events: Sequence[AlarmEvent]) -> int:
    return sum(1 for e in events if is_counted_raise(e))


def tables_of(records: Sequence[RunRecord]) -> dict[str, list[MetricsRow]]:
    """Wan2018 Table IV rows per method."""
    methods = [m for m in METHODS if records and m in records[0].outcomes]
    return {m: metrics_table([r.outcomes[m] for r in records]) for m in methods}


def _sample_at(ts_s: np.ndarray, vals: np.ndarray, t_s: np.ndarray) -> np.ndarray:
    """Latest logged value at or before each time (zero before the first sample)."""
    idx = np.searchsorted(ts_s, t_s + 1e-9, side="right") - 1
    return np.where(idx >= 0, vals[np.clip(idx, 0, None)], 0.0) if len(ts_s) else np.zeros_like(t_s)


def rms_finite(x: np.ndarray) -> float:
    """RMS of the finite entries of ``x`` (NaN when there are none)."""
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x * x))) if x.size else math.nan


def score_air_run(index: int, sc: Scenario, cfg: MonitorConfig, events: Sequence[AlarmEvent],
                  baseline_events: dict[str, list[AlarmEvent]], a: dict[str, np.ndarray],
                  j_seen: dict[str, float], truth: dict[str, np.ndarray],
                  fault_log: dict[str, tuple[list[float], list[float]]], *,
                  keep_series: bool, wall_s: float) -> RunRecord:
    """Score one monitored air-data run against its truth (module docstring).

    Parameters
    ----------
    index : position of the run in its campaign
    sc : the scenario flown; cfg : the monitor configuration it was monitored with
    events : the monitor's alarm events
    baseline_events : baseline method -> its alarm events on the same samples
    a : per air-data sample captures (``t_us``, ``<set>.measured``, ``<set>.ref``,
        ``<set>.<method>.fused``, ``<set>.rms``, ...), SI
    j_seen : group -> largest J the channel monitors reported over the run, SI
    truth : the simulator's truth record (``state.t_s``, ``state.aoa_rad``, ``state.cas_mps``)
    fault_log : the sensor suite's applied fault per channel, (times s, values SI)
    keep_series : keep ``a`` and the true values in the record (example plot)
    wall_s : wall time of the run, s
    """
    faults = air_fault_truth(sc)
    intervals = truth_intervals(faults)
    imu = imu_of(cfg)
    imu_on = imu.enabled and (imu.ts.enabled or imu.hosm.enabled)
    groups = AIR_SETS + (IMU_GROUPS if imu_on else ())
    outcomes = {METHOD_MONITOR: evaluate_run(events, intervals, groups=groups,
                                             grace_us=GRACE_US)}
    results = score_faults(METHOD_MONITOR, events, faults)
    raised = {METHOD_MONITOR: n_raised(events)}
    for m, ev in baseline_events.items():
        outcomes[m] = evaluate_run(ev, intervals, groups=AIR_SETS, grace_us=GRACE_US)
        results += score_faults(m, ev, faults)
        raised[m] = n_raised(ev)

    t_s = a["t_us"] * 1e-6
    true = {"aoa": np.interp(t_s, truth["state.t_s"], truth["state.aoa_rad"]),
            "cas": np.interp(t_s, truth["state.t_s"], truth["state.cas_mps"])}
    recon: dict[str, float] = {}
    for f in faults:
        s, i = f.channel.kind, f.channel.instance
        if f"{s}.measured" not in a:
            continue
        ts, vals = fault_log.get(f"{s}{i}", ([], []))
        fv = _sample_at(np.asarray(ts, dtype=float), np.asarray(vals, dtype=float), t_s)
        inside = (a["t_us"] >= f.t_start_us) & (
            True if f.t_end_us is None else a["t_us"] < f.t_end_us)
        r = a[f"{s}.measured"][:, i] - a[f"{s}.ref"][:, 0]
        recon[str(f.channel)] = rms_finite((r - fv)[inside])
    out_rmse: dict[str, dict[str, float]] = {}
    out_lost: dict[str, dict[str, int]] = {}
    for m in (METHOD_MONITOR, "virtual", METHOD_MEDIAN, METHOD_FIXED):
        for s in AIR_SETS:
            key = f"{s}.{m}.fused"
            if key not in a:
                continue
            v = a[key][:, 0]
            if m == "virtual" and not np.isfinite(v).any():
                continue
            out_rmse.setdefault(m, {})[s] = rms_finite(v - true[s])
            out_lost.setdefault(m, {})[s] = int(np.sum(~np.isfinite(v)))
    j_max = dict(j_seen)
    j_cal: dict[str, float] = {}
    faulted = {f.channel for f in faults}
    air, period_s = airdata_of(cfg), sim_air_period_s(sc)
    n_eval = {"aoa": window_n(air.fdi.aoa, period_s), "cas": window_n(air.fdi.cas, period_s)}
    for s in AIR_SETS:
        if f"{s}.rms" not in a:
            continue
        healthy = [i for i in range(a[f"{s}.rms"].shape[1]) if ChannelId(s, i) not in faulted]
        if healthy:
            j_max[s] = float(np.nanmax(a[f"{s}.rms"][:, healthy]))
            r = a[f"{s}.measured"][:, healthy] - a[f"{s}.ref"]
            cal = [calibrate(r[:, k], rms_window_n=n_eval[s], k=CALIBRATE_K)
                   for k in range(len(healthy)) if np.isfinite(r[:, k]).sum() >= n_eval[s]]
            if cal:
                j_cal[s] = max(cal)
    series = None
    if keep_series:
        series = dict(a)
        for s in AIR_SETS:
            series[f"{s}.true"] = true[s]
    return RunRecord(
        index=index, name=sc.name, seed=sc.seed, duration_s=sc.duration_s,
        manoeuvre=sc.manoeuvre.kind, wind=sc.wind.kind, faults=faults, outcomes=outcomes,
        fault_results=results, raised=raised, recon_rmse=recon, output_rmse=out_rmse,
        output_lost=out_lost, j_max=j_max, j_calibrated=j_cal, wall_s=wall_s,
        events=list(events), series=series,
    )


# ------------------------------------------------------------------------------------------------
# air data: estimation error of the MHE output (Wan2018 Table III)
# ------------------------------------------------------------------------------------------------


def estimate_error(rec: RunRecord) -> dict[str, tuple[float, float]]:
    """(max, mean) |MHE estimate - truth| per set, SI; CAS only while a CAS instance is healthy
    (Wan2018 Table III leaves CAS out in configurations III and IV). Needs ``rec.series``."""
    s = rec.series or {}
    out: dict[str, tuple[float, float]] = {}
    for k in AIR_SETS:
        v, tr = s.get(f"{k}.virtual.fused"), s.get(f"{k}.true")
        if v is None or tr is None:
            continue
        e = np.abs(v[:, 0] - tr)
        if k == "cas" and f"{k}.faulty" in s:
            e = e[~np.all(s[f"{k}.faulty"] > 0.5, axis=1)]
        e = e[np.isfinite(e)]
        if e.size:
            out[k] = (float(e.max()), float(e.mean()))
    return out


def table3(stats: Sequence[tuple[bool, dict[str, tuple[float, float]]]]) -> dict[str, list[float]]:
    """Wan2018 Table III: max and mean |estimate - truth| of AoA [deg] and CAS [kts]."""
    out = {}
    for name, faulty in (("fault-free", False), ("faulty", True)):
        sel = [s for f, s in stats if f == faulty]
        row = []
        for agg in (0, 1):
            for k in AIR_SETS:
                v = [s[k][agg] for s in sel if k in s]
                x = (max(v) if agg == 0 else float(np.mean(v))) if v else math.nan
                row.append(x / UNITS[k][1])
        out[name] = row
    return out


# ------------------------------------------------------------------------------------------------
# IMU: fault reconstruction and detection
# ------------------------------------------------------------------------------------------------


def imu_fault_truth(t_s: np.ndarray, fault_log: dict[str, tuple[list[float], list[float]]]
                    ) -> np.ndarray:
    """(n, 6) true fault at the Frame times from ``SensorSuite.fault_log`` (0 where none)."""
    out = np.zeros((len(t_s), 6))
    for i, ch in enumerate(SIM_CHANNELS):
        if ch in fault_log and fault_log[ch][0]:
            ts, vs = (np.asarray(a, dtype=np.float64) for a in fault_log[ch])
            out[:, i] = np.interp(t_s, ts, vs, left=0.0, right=0.0)
    return out


def imu_fault_windows(sc: Scenario) -> list[tuple[float, float]]:
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
