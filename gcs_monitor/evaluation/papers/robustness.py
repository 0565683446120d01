"""Never blind, never fooled (issue 15): the monitor with its defaults on flights it was not
tuned to.

* :func:`rate_sweep`: the demo and a Lu2016 scenario flown at every combination of IMU 10 / 25 /
  50 / 100 / 200 Hz, air data 5 / 10 / 20 / 50 Hz and GPS 1 / 5 / 10 Hz (the simulator's sensor
  rates; everything else identical), monitored with the defaults: each family's coverage, the
  monitor_degraded alarms, false alarms, faults detected and their delays;
* :func:`no_declared_weather`: fault-free and faulty flights from calm air to Dryden sigma
  3.54 m/s with shear, monitored with the defaults (weather estimated from the flight) against
  the same with the scenario's weather declared; and every Lu2016 / Atmaca2025 preset with the
  defaults: no air-data alarm.

Every run goes through MAVLink bytes (:func:`gcs_monitor.evaluation.runs.feed_packets`).
"""

from __future__ import annotations

import dataclasses
import math
import re
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gcs_monitor.config import MonitorConfig
from gcs_monitor.core.types import ChannelId
from gcs_monitor.evaluation import scenarios
from gcs_monitor.evaluation.campaign import run_records
from gcs_monitor.evaluation.configs import (
    family_alone,
    with_declared_weather,
    with_weather_estimate,
)
from gcs_monitor.evaluation.records import METHOD_MEDIAN, METHOD_MONITOR, RunRecord
from gcs_monitor.evaluation.report import METHOD_LABEL, fmt_fixed, md_table, write_csv
from gcs_monitor.evaluation.runner import run_parallel
from gcs_monitor.evaluation.runs import feed_packets
from gcs_monitor.evaluation.scenarios import (
    CAMPAIGN_SEED,
    FULL_DURATION_S,
    campaign_scenarios,
    preset,
)
from gcs_monitor.evaluation.scoring import tables_of
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState
from gcs_monitor.fdi.metrics import MetricsRow
from gcs_monitor.fdi.records import StepOutput
from gcs_monitor.monitor import Monitor
from sim_vehicle.faults.profiles import FaultInjector
from sim_vehicle.run import iter_run
from sim_vehicle.scenario import Scenario, list_presets

IMU_HZ = (10.0, 25.0, 50.0, 100.0, 200.0)
AIR_HZ = (5.0, 10.0, 20.0, 50.0)
GPS_HZ = (1.0, 5.0, 10.0)
QUICK = ((10.0, 5.0, 1.0), (25.0, 10.0, 5.0), (50.0, 50.0, 10.0), (100.0, 20.0, 10.0),
         (200.0, 20.0, 10.0))
SWEEP_PRESETS = ("demo_airdata_faults", "lu2016_turbulence")
_IMU = re.compile(r"^imu(\d)\.(acc|gyro)\.([xyzpqr])$")
_AIR = re.compile(r"^(aoa|cas)(\d)$")
SCORED = (AlarmKind.SENSOR_FAULT, AlarmKind.SET_LOST, AlarmKind.ACTUATOR_FAULT)
GRACE_US = 1_000_000
# alarm channel kinds of the actuator family: the servo tier's surfaces, the aircraft tier's
# actuators (instance = the simulator's actuator index: aileron, elevator, rudder, engine)
ACTUATOR_KINDS = ("surface", "actuator")


def truth_channel(name: str) -> ChannelId | None:
    """A simulator fault channel (``aoa1``, ``imu0.acc.z``) as the monitor's ChannelId."""
    m = _AIR.match(name)
    if m:
        return ChannelId(m.group(1), int(m.group(2)))
    m = _IMU.match(name)
    if m:
        return ChannelId(m.group(2), int(m.group(1)), m.group(3))
    return None


@dataclass
class RunOutcome:
    """One monitored flight against its truth."""

    name: str
    coverage: dict[str, float] = field(default_factory=dict)  # family -> share of flight judged
    state: dict[str, str] = field(default_factory=dict)  # family -> final state
    degraded: dict[str, int] = field(default_factory=dict)  # family -> monitor_degraded raises
    reasons: dict[str, str] = field(default_factory=dict)  # family -> why not judged (last)
    faults: int = 0
    detected: int = 0
    delays_s: list[float] = field(default_factory=list)
    false_alarms: list[str] = field(default_factory=list)  # channels raised without a fault
    air_false: int = 0  # false alarms on the air-data channels


def _with_rates(sc: Scenario, imu_hz: float, air_hz: float, gps_hz: float) -> Scenario:
    rates = dataclasses.replace(sc.sensors.rates, imu_hz=imu_hz, attitude_hz=imu_hz,
                                airdata_hz=air_hz, baro_hz=air_hz, gps_hz=gps_hz,
                                static_hz=min(air_hz, sc.sensors.rates.static_hz))
    dt = min(sc.dt_s, 1.0 / imu_hz)
    return dataclasses.replace(sc, sensors=dataclasses.replace(sc.sensors, rates=rates),
                               dt_s=dt, name=f"{sc.name}@imu{imu_hz:g}/air{air_hz:g}/"
                               f"gps{gps_hz:g}")


def monitor_run(sc: Scenario, cfg: MonitorConfig) -> RunOutcome:
    """Simulate ``sc``, monitor its MAVLink bytes with ``cfg``, score against its faults."""
    last: dict[str, Any] = {}

    def on_step(sysid: int, frame: Any, out: StepOutput) -> None:
        for c in out.coverage:
            last[c.family] = c

    mon = Monitor(cfg, on_step=on_step)
    feed_packets(mon, (pkt for _, _, pkt in iter_run(sc)))
    return score(sc.name, sc, mon.events, last)


def score(name: str, sc: Scenario, events: Sequence[AlarmEvent],
          coverage: dict[str, Any]) -> RunOutcome:
    out = RunOutcome(name)
    for fam, c in coverage.items():
        out.coverage[fam] = c.overall
        out.state[fam] = c.state
        out.reasons[fam] = c.reason
    truth: dict[ChannelId, list[tuple[int, int | None]]] = {}
    for f in sc.faults:
        ch = truth_channel(f.channel)
        if ch is not None:
            end = None if f.t_end_s is None else round(f.t_end_s * 1e6)
            truth.setdefault(ch, []).append((round(f.t_start_s * 1e6), end))
    # actuator faults (Lu2017 classes on a surface, or aircraft-level faults on a surface or
    # the engine): found by an alarm of either tier of the actuator family on that actuator
    act_truth: dict[int, list[tuple[int, int | None]]] = {}
    for af in sc.actuator_faults:
        end = None if af.t_end_s is None else round(af.t_end_s * 1e6)
        act_truth.setdefault(af.surface, []).append((round(af.t_start_s * 1e6), end))
    raised = [e for e in events if e.state is AlarmState.RAISED]
    for e in raised:
        if e.kind is AlarmKind.MONITOR_DEGRADED:
            out.degraded[e.channel.axis] = out.degraded.get(e.channel.axis, 0) + 1
    for ch, spans in truth.items():
        for t0, t1 in spans:
            out.faults += 1
            hit = next((e.t_us for e in raised if e.kind in SCORED and e.channel == ch
                        and e.t_us >= t0 and (t1 is None or e.t_us <= t1 + GRACE_US)), None)
            if hit is not None:
                out.detected += 1
                out.delays_s.append((hit - t0) * 1e-6)
    for k, spans in act_truth.items():
        for t0, t1 in spans:
            out.faults += 1
            hit = next((e.t_us for e in raised if e.kind in SCORED
                        and e.channel.kind in ACTUATOR_KINDS and e.channel.instance == k
                        and e.t_us >= t0 and (t1 is None or e.t_us <= t1 + GRACE_US)), None)
            if hit is not None:
                out.detected += 1
                out.delays_s.append((hit - t0) * 1e-6)
    for e in raised:
        if e.kind not in SCORED:
            continue
        ch = e.channel
        if ch.kind in ACTUATOR_KINDS and ch.instance in act_truth:
            continue
        base = ChannelId(ch.kind, ch.instance, ch.axis) if ch.instance >= 0 else ch
        if base not in truth and not any(t.kind == ch.kind for t in truth if ch.instance < 0):
            out.false_alarms.append(str(ch))
            if ch.kind in ("aoa", "cas"):
                out.air_false += 1
    return out


def _fmt_cov(o: RunOutcome, fam: str) -> str:
    c = o.coverage.get(fam)
    if c is None or not math.isfinite(c):
        st = o.state.get(fam, "-")
        return st if st != "-" else "-"
    mark = " (degraded)" if o.degraded.get(fam) else ""
    return f"{100 * c:.0f} %{mark}"


def _sweep_job(job: tuple[str, float, float, float, float]) -> RunOutcome:
    name, imu_hz, air_hz, gps_hz, duration = job
    sc = preset(name, duration_s=duration if duration > 0 else None)
    return monitor_run(_with_rates(sc, imu_hz, air_hz, gps_hz), MonitorConfig())


def rate_sweep(out: Path, jobs: int = 2, quick: bool = False) -> str:
    """The demo and Lu2016 turbulence scenarios at every IMU x air-data x GPS rate, default
    configuration: coverage per family, monitor_degraded, faults detected, false alarms."""
    grid = QUICK if quick else [(i, a, g) for i in IMU_HZ for a in AIR_HZ for g in GPS_HZ]
    duration = 0.0
    job_list = [(n, i, a, g, duration) for n in SWEEP_PRESETS for i, a, g in grid]
    res = run_parallel(_sweep_job, job_list, jobs, desc="rate sweep")
    out.mkdir(parents=True, exist_ok=True)
    header = ["scenario", "IMU Hz", "air Hz", "GPS Hz", "imu coverage", "airdata coverage",
              "faults detected", "mean delay s", "false alarms", "not judged (why)"]
    rows = []
    for (n, i, a, g, _), o in zip(job_list, res, strict=True):
        why = "; ".join(f"{f}: {r}" for f, r in o.reasons.items() if r and (
            o.degraded.get(f) or o.state.get(f) in ("degraded", "starting", "unavailable")))
        delay = f"{sum(o.delays_s) / len(o.delays_s):.2f}" if o.delays_s else "-"
        rows.append([n, f"{i:g}", f"{a:g}", f"{g:g}", _fmt_cov(o, "imu"),
                     _fmt_cov(o, "airdata"), f"{o.detected}/{o.faults}", delay,
                     ", ".join(o.false_alarms) or "0", why or "-"])
    write_csv(out / "rate_sweep.csv", header, rows)
    n_false = sum(1 for r in res if r.false_alarms)
    n_missed = sum(r.faults - r.detected for r in res)
    return (f"Rate sweep ({len(res)} runs, default configuration): {n_false} runs with a false "
            f"alarm, {n_missed} faults missed in total.\n\n" + md_table(header, rows))


# ------------------------------------------------------------------------------------------------
# fault-free IMU fault estimates against the GPS rate
# ------------------------------------------------------------------------------------------------

ACCURACY_PRESET = "demo_airdata_faults"  # manoeuvres, air-data faults only: f_hat is all error
ACCURACY_IMU_AIR_HZ = (100.0, 20.0)


def _with_gps_imu_shape(cfg: MonitorConfig, on: bool) -> MonitorConfig:
    imu = cfg.families["imu"]
    est = dataclasses.replace(imu.ts.estimator, gps_imu_shape=on)
    fam = dataclasses.replace(imu, ts=dataclasses.replace(imu.ts, estimator=est))
    return dataclasses.replace(cfg, families={**cfg.families, "imu": fam})


def _accuracy_job(job: tuple[float, bool, float]) -> list[float]:
    """RMS and max |f_hat| of imu_ts's accelerometer channels (x, y, z; m/s^2) after the
    family's warm-up, on a flight without IMU faults."""
    gps_hz, shape, duration = job
    imu_hz, air_hz = ACCURACY_IMU_AIR_HZ
    sc = _with_rates(preset(ACCURACY_PRESET, duration_s=duration if duration > 0 else None),
                     imu_hz, air_hz, gps_hz)
    cfg = _with_gps_imu_shape(MonitorConfig(), shape)
    warm_us = round(cfg.families["imu"].warmup_s * 1e6)
    f: list[list[float]] = []

    def on_step(sysid: int, frame: Any, out: StepOutput) -> None:
        for e in out.estimates:
            if e.name == "imu_ts" and e.numerics_ok and e.faults and frame.t_us >= warm_us:
                f.append(list(e.faults.values())[:3])

    feed_packets(Monitor(cfg, on_step=on_step), (pkt for _, _, pkt in iter_run(sc)))
    if not f:
        return [math.nan] * 6
    cols = list(zip(*f, strict=True))
    return ([math.sqrt(math.fsum(x * x for x in c) / len(c)) for c in cols]
            + [max(abs(x) for x in c) for c in cols])


RMSE_PRESET = "lu2016_turbulence"  # Lu2016 Table 2 faults on all six channels, 10-30 s
RMSE_WINDOW_S = (10.5, 30.0)  # the first 0.5 s is the response to the 3 m/s^2, 3 deg/s steps
_IMU_FAULT_CHANNELS = ("imu0.acc.x", "imu0.acc.y", "imu0.acc.z", "imu0.gyro.p", "imu0.gyro.q",
                       "imu0.gyro.r")


def _rmse_job(job: tuple[float, bool]) -> list[float]:
    """RMSE of imu_ts's six fault estimates against the injected Lu2016 Table 2 faults over
    :data:`RMSE_WINDOW_S` (acc m/s^2, gyro rad/s)."""
    gps_hz, shape = job
    imu_hz, air_hz = ACCURACY_IMU_AIR_HZ
    sc = _with_rates(preset(RMSE_PRESET), imu_hz, air_hz, gps_hz)
    inj = FaultInjector(tuple(sc.faults), sc.seed)
    t0_us, t1_us = (round(x * 1e6) for x in RMSE_WINDOW_S)
    sq = [0.0] * 6
    n = 0

    def on_step(sysid: int, frame: Any, out: StepOutput) -> None:
        nonlocal n
        if not t0_us < frame.t_us < t1_us:
            return
        for e in out.estimates:
            if e.name == "imu_ts" and e.numerics_ok and e.faults:
                t_s = frame.t_us * 1e-6
                for i, (c, f) in enumerate(zip(_IMU_FAULT_CHANNELS, e.faults.values(),
                                               strict=True)):
                    sq[i] += (f - inj.apply(c, t_s, 0.0, 0.0)) ** 2
                n += 1

    cfg = _with_gps_imu_shape(MonitorConfig(), shape)
    feed_packets(Monitor(cfg, on_step=on_step), (pkt for _, _, pkt in iter_run(sc)))
    return [math.sqrt(x / n) if n else math.nan for x in sq]


def gps_rate_accuracy(out: Path, jobs: int = 2, quick: bool = False) -> str:
    """imu_ts's accelerometer fault estimates on the demo flight (no IMU fault) at GPS 1 / 5 /
    10 Hz (IMU 100 Hz, air data 20 Hz), with and without the IMU-measured interpolation error
    taken out of the GPS velocity (``gps_imu_shape``): how the estimate's accuracy depends on
    the GPS rate (issue 15)."""
    duration = 30.0 if quick else 0.0
    job_list = [(g, shape, duration) for g in GPS_HZ for shape in (False, True)]
    res = run_parallel(_accuracy_job, job_list, jobs, desc="gps rate accuracy")
    header = ["GPS Hz", "gps_imu_shape", "RMS f_Ax", "RMS f_Ay", "RMS f_Az", "max abs f_Ax",
              "max abs f_Ay", "max abs f_Az"]
    rows = [[f"{g:g}", "on" if shape else "off", *(f"{v:.3f}" for v in r)]
            for (g, shape, _), r in zip(job_list, res, strict=True)]
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "gps_rate_accuracy.csv", header, rows)
    rjobs = [(g, shape) for g in GPS_HZ for shape in (False, True)]
    rres = run_parallel(_rmse_job, rjobs, jobs, desc="gps rate rmse")
    rheader = ["GPS Hz", "gps_imu_shape", "RMSE f_Ax", "RMSE f_Ay", "RMSE f_Az", "RMSE f_p",
               "RMSE f_q", "RMSE f_r"]
    rrows = [[f"{g:g}", "on" if shape else "off", *(f"{v:.3f}" for v in r[:3]),
              *(f"{math.degrees(v):.3f}" for v in r[3:])]
             for (g, shape), r in zip(rjobs, rres, strict=True)]
    write_csv(out / "gps_rate_rmse.csv", rheader, rrows)
    imu_hz, air_hz = ACCURACY_IMU_AIR_HZ
    w0, w1 = RMSE_WINDOW_S
    return (f"imu_ts accelerometer fault estimates (m/s^2) on `{ACCURACY_PRESET}` (no IMU fault)"
            f" at IMU {imu_hz:g} Hz, air data {air_hz:g} Hz, after the "
            f"{MonitorConfig().families['imu'].warmup_s:g} s warm-up; default configuration "
            "but for gps_imu_shape.\n\n" + md_table(header, rows)
            + f"\n\nFault reconstruction on `{RMSE_PRESET}` (Lu2016 Table 2 faults), RMSE of "
            f"f_hat against the injected fault over {w0:g}-{w1:g} s (acc m/s^2, gyro deg/s), "
            "same rates:\n\n" + md_table(rheader, rrows))


# ------------------------------------------------------------------------------------------------
# weather the monitor was not told about
# ------------------------------------------------------------------------------------------------

def weather_presets() -> list[str]:
    """Every preset of the simulator (Lu2016, Atmaca2025, the demo, and the actuator and
    yaw-rate families' presets): none of them may raise an air-data alarm on a channel it
    does not fault."""
    return [n for n, _ in list_presets()]


def _weather_job(job: tuple[str, bool]) -> RunOutcome:
    name, declared = job
    sc = preset(name)
    cfg = MonitorConfig()
    if declared:
        cfg = with_declared_weather(cfg, sc)
    return monitor_run(sc, cfg)


def presets_without_declared_weather(out: Path, jobs: int = 2, quick: bool = False) -> str:
    """Every Lu2016 and Atmaca2025 preset (and the demo) with the defaults and no declared
    weather: the air-data family raises nothing on these IMU-fault flights."""
    names = weather_presets()
    names = [n for n in names if n.startswith("lu2016")][:3] if quick else names
    job_list = [(n, d) for n in names for d in (False, True)]
    res = run_parallel(_weather_job, job_list, jobs, desc="presets")
    header = ["preset", "weather", "air-data false alarms", "all false alarms",
              "faults detected", "imu coverage", "airdata coverage"]
    rows = [[n, "declared" if d else "estimated (defaults)", str(o.air_false),
             ", ".join(o.false_alarms) or "0", f"{o.detected}/{o.faults}", _fmt_cov(o, "imu"),
             _fmt_cov(o, "airdata")] for (n, d), o in zip(job_list, res, strict=True)]
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "presets_weather.csv", header, rows)
    bad = [r for (n, d), r in zip(job_list, res, strict=True) if not d and r.air_false]
    return (f"Presets with the defaults and no declared weather: {len(bad)} with an air-data "
            "alarm.\n\n" + md_table(header, rows))


# ------------------------------------------------------------------------------------------------
# the campaigns without a forecast
# ------------------------------------------------------------------------------------------------


def weather_campaign_markdown(title: str, tables: dict[str, dict[str, list[MetricsRow]]],
                              n_runs: int, wall_s: float, jobs: int, command: str, *,
                              both: bool = True, how: str | None = None) -> str:
    """Table IV rows of the monitor and the median vote, declared against estimated weather."""
    rows = []
    for weather, tab in tables.items():
        for m in (METHOD_MONITOR, METHOD_MEDIAN):
            for r in tab.get(m, []):
                rows.append([weather, METHOD_LABEL.get(m, m), r.group, r.n_fault_free,
                             r.n_faulty, fmt_fixed(r.far_pct), fmt_fixed(r.mdr_pct),
                             fmt_fixed(r.fir_pct), fmt_fixed(r.delay_max_s),
                             fmt_fixed(r.delay_mean_s)])
    how = how or ("each run twice (its weather declared as a forecast, and none declared: "
                  "estimated from the flight)" if both
                  else "no weather declared (estimated from the flight)")
    return (f"{title}: {n_runs} runs, default configuration, {how}; wall "
            f"{wall_s:.0f} s with {jobs} job(s). `{command}`\n\n"
            + md_table(["weather", "method", "group", "fault-free runs", "faulty runs",
                        "FAR [%]", "MDR [%]", "FIR [%]", "DetD max [s]", "DetD mean [s]"],
                       rows))


def _weather_campaign(title: str, scs: Sequence[Scenario], out: Path, jobs: int,
                      command: str, *, labels: Sequence[tuple[str, bool]] = (
                          ("declared", True), ("estimated", False))) -> str:
    t0 = time.perf_counter()
    cfg = MonitorConfig()
    tables: dict[str, dict[str, list[MetricsRow]]] = {}
    extra = ""
    for label, declare in labels:
        recs = run_records(scs, cfg, jobs, desc=f"{title} ({label})", declare_weather=declare)
        tables[label] = tables_of(recs)
        header = ["run", "scenario", "faulty", "monitor alarms", "median alarms"]
        write_csv(out / f"runs_{label}.csv", header,
                  [[r.index, r.name, r.faulty, r.raised.get(METHOD_MONITOR, 0),
                    r.raised.get(METHOD_MEDIAN, 0)] for r in recs])
        extra += "\n\n" + false_alarms_by_family(recs, scs, out / f"alarms_{label}.csv",
                                                  label)
    md = weather_campaign_markdown(title, tables, len(scs), time.perf_counter() - t0, jobs,
                                   command, both=len(labels) > 1) + extra
    (out / "weather_campaign.md").write_text(md + "\n")
    return md


def false_alarms_by_family(recs: Sequence[RunRecord], scs: Sequence[Scenario], path: Path,
                           label: str) -> str:
    """Every raise of the monitor on a channel without an injected fault (the campaign injects
    air-data faults only: any IMU, yaw-rate or actuator alarm is false; a set-level event of a
    set with an injected fault is not), written to ``path``
    with the run's manoeuvre, altitude and wind; Markdown: per estimator, the runs with such a
    raise. ``monitor_degraded`` (a family not judging) is counted apart: it is coverage, not a
    fault alarm."""
    rows: list[list[Any]] = []
    runs: dict[str, set[int]] = {}
    for r, sc in zip(recs, scs, strict=True):
        faulty = {f.channel for f in r.faults}
        faulty_sets = {f.channel.kind for f in r.faults}
        for e in r.events:
            if e.state is not AlarmState.RAISED or e.channel in faulty or (
                    e.channel.instance < 0 and e.channel.kind in faulty_sets):
                continue  # the fault, or its set's state (lost, degraded) while it is faulty
            key = "monitor_degraded" if e.kind is AlarmKind.MONITOR_DEGRADED else e.estimator
            runs.setdefault(key, set()).add(r.index)
            rows.append([r.index, r.name, sc.manoeuvre.kind, f"{sc.initial.alt_m:.0f}",
                         f"{sc.wind.kind} {sc.wind.turbulence_sigma_mps:.2f}",
                         f"{e.t_us * 1e-6:.2f}", str(e.channel), e.kind.value,
                         e.fault_type.value, e.estimator, f"{e.residual_rms:.4g}",
                         f"{e.threshold:.4g}", e.message])
    write_csv(path, ["run", "scenario", "manoeuvre", "alt [m]", "wind", "t [s]", "channel",
                     "kind", "type", "estimator", "J", "J_th", "message"], rows)
    table = [[k, len(v), fmt_fixed(100.0 * len(v) / max(len(recs), 1)),
              " ".join(str(i) for i in sorted(v)[:12]) + (" ..." if len(v) > 12 else "")]
             for k, v in sorted(runs.items())]
    return (f"Raises on channels without an injected fault ({label} weather), per estimator "
            f"(every raise: `{path.name}`):\n\n"
            + (md_table(["estimator", "runs", "runs [%]", "first runs"], table) if table
               else "none"))


def wan2018_campaign_weather(out: Path, jobs: int = 2, quick: bool = False) -> str:
    """The 249-run Wan2018 campaign (``wan2018_campaign``'s runs) with the default
    configuration, weather declared against none declared: Table IV side by side."""
    n, dur = (12, (40.0, 60.0)) if quick else (249, FULL_DURATION_S)
    out.mkdir(parents=True, exist_ok=True)
    return _weather_campaign("Wan2018 campaign", campaign_scenarios(n, CAMPAIGN_SEED, dur),
                             out, jobs, "gcs-monitor evaluate --experiment "
                             f"wan2018_campaign_weather{' --quick' if quick else ''}")


def wan2018_campaign_defaults(out: Path, jobs: int = 2, quick: bool = False) -> str:
    """The 249-run Wan2018 campaign with the default configuration and no weather declared
    (``wan2018_campaign_weather`` showed declared = estimated, run for run): Table IV and every
    false raise of every family, with the run's manoeuvre, altitude and wind."""
    n, dur = (12, (40.0, 60.0)) if quick else (249, FULL_DURATION_S)
    out.mkdir(parents=True, exist_ok=True)
    return _weather_campaign("Wan2018 campaign", campaign_scenarios(n, CAMPAIGN_SEED, dur),
                             out, jobs, "gcs-monitor evaluate --experiment "
                             f"wan2018_campaign_defaults{' --quick' if quick else ''}",
                             labels=(("estimated", False),))


def triplex_weather(out: Path, jobs: int = 2, quick: bool = False) -> str:
    """The 100-run triplex campaign (seed 0) with the default configuration, weather declared
    against none declared: Table IV side by side."""
    n = 12 if quick else 100
    out.mkdir(parents=True, exist_ok=True)
    return _weather_campaign("Triplex campaign", scenarios.preset_set("triplex", n, 0), out,
                             jobs, "gcs-monitor evaluate --experiment triplex_weather"
                             f"{' --quick' if quick else ''}")


def _actuator_job(job: tuple[int, Scenario]) -> tuple[int, str, str, list[AlarmEvent]]:
    index, sc = job
    mon = Monitor(family_alone(MonitorConfig(), "actuators"))
    feed_packets(mon, (pkt for _, _, pkt in iter_run(sc)))
    raised = [e for e in mon.events if e.kind is AlarmKind.ACTUATOR_FAULT
              and e.state is AlarmState.RAISED]
    return index, sc.name, ", ".join(f.kind for f in sc.faults) or "none", raised


def triplex_actuators(out: Path, jobs: int = 2, quick: bool = False) -> str:
    """The 100-run triplex campaign (seed 0: the transport with servo outputs, no actuator
    fault; sensor faults on the AoA and CAS sets, which the simulated autopilot flies on) with
    the default actuator family: every actuator alarm is false. Per run that raises one: the
    air-data faults of the run, and each alarm's time, channel, class and message."""
    n = 12 if quick else 100
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    res = run_parallel(_actuator_job, list(enumerate(scenarios.preset_set("triplex", n, 0))),
                       jobs, desc="triplex (actuators)")
    rows = [[str(i), name, faults, f"{e.t_us * 1e-6:.1f}", str(e.channel), e.fault_type.value,
             e.message] for i, name, faults, raised in res for e in raised]
    write_csv(out / "actuator_alarms.csv", ["run", "scenario", "air-data faults", "t [s]",
                                             "channel", "class", "message"], rows)
    n_runs = len({r[0] for r in rows})
    by_ch: dict[str, int] = {}
    for r in rows:
        by_ch[r[4]] = by_ch.get(r[4], 0) + 1
    md = (f"Triplex campaign, {n} runs (seed 0), actuator family with its defaults "
          f"(`gcs-monitor evaluate --experiment triplex_actuators{' --quick' if quick else ''}`"
          f", {time.perf_counter() - t0:.0f} s wall, {jobs} job(s)): **{n_runs} of {n} runs "
          f"raise a (false) actuator alarm**; by channel: "
          + (", ".join(f"{k} {v}" for k, v in sorted(by_ch.items())) or "none") + "\n\n"
          + md_table(["run", "scenario", "air-data faults", "t [s]", "channel", "class",
                      "message"], rows))
    (out / "triplex_actuators.md").write_text(md + "\n")
    return md


def wan2018_thin_sets(out: Path, jobs: int = 2, quick: bool = False) -> str:
    """The Wan2018 campaign's runs with two or more faults in one air-data set (the only runs
    that can leave a set with one healthy instance), the air-data family alone and no weather
    declared: the weather estimate with a thin set's quantity from kinematics (``min_healthy``
    2, the default) against learning from the set's last instance (1, the behaviour before);
    Table IV on those runs and every run whose raises differ
    (:mod:`gcs_monitor.families.airdata.weather`, "thin sets")."""
    n, dur = (12, (40.0, 60.0)) if quick else (249, FULL_DURATION_S)
    return _thin_sets("Wan2018 campaign", campaign_scenarios(n, CAMPAIGN_SEED, dur), out, jobs,
                      f"wan2018_thin_sets{' --quick' if quick else ''}")


def wan2018_thin_sets_declared(out: Path, jobs: int = 2, quick: bool = False) -> str:
    """``wan2018_thin_sets`` with each run's weather declared as a forecast (the prior of the
    weather estimate, as in ``wan2018_campaign_restart``)."""
    n, dur = (12, (40.0, 60.0)) if quick else (249, FULL_DURATION_S)
    return _thin_sets("Wan2018 campaign, weather declared",
                      campaign_scenarios(n, CAMPAIGN_SEED, dur), out, jobs,
                      f"wan2018_thin_sets_declared{' --quick' if quick else ''}", declare=True)


def triplex_thin_sets(out: Path, jobs: int = 2, quick: bool = False) -> str:
    """``wan2018_thin_sets`` on the 100-run triplex campaign (seed 0)."""
    return _thin_sets("Triplex campaign", scenarios.preset_set("triplex", 12 if quick else 100, 0),
                      out, jobs, f"triplex_thin_sets{' --quick' if quick else ''}")


def _thin_sets(title: str, scs: Sequence[Scenario], out: Path, jobs: int, name: str, *,
               declare: bool = False) -> str:
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    sel = [i for i, sc in enumerate(scs)
           if max(Counter(f.channel[:3] for f in sc.faults).values(), default=0) >= 2]
    sub = [scs[i] for i in sel]
    base = family_alone(MonitorConfig(), "airdata")
    labels = (("kinematics (min_healthy 2)", 2), ("learnt from the last instance (1)", 1))
    tables: dict[str, dict[str, list[MetricsRow]]] = {}
    recs: dict[str, list[RunRecord]] = {}
    for label, k in labels:
        cfg = with_weather_estimate(base, min_healthy=k)
        recs[label] = run_records(sub, cfg, jobs, desc=label, declare_weather=declare)
        tables[label] = tables_of(recs[label])

    def raises(r: RunRecord) -> list[str]:
        return [f"{e.t_us * 1e-6:.2f} {e.channel} {e.fault_type.value}" for e in r.events
                if e.state is AlarmState.RAISED]

    rows = []
    for j, i in enumerate(sel):
        a, b = (raises(recs[label][j]) for label, _ in labels)
        if a != b:
            faults = ", ".join(f"{f.channel} {f.kind} {f.t_start_s:.1f}"
                               for f in scs[i].faults)
            rows.append([i, faults, "; ".join(a), "; ".join(b)])
    md = (weather_campaign_markdown(
              f"{title}, the {len(sel)} of {len(scs)} runs with two or more faults in one "
              "set (air-data family alone)", tables, len(sel), time.perf_counter() - t0, jobs,
              f"gcs-monitor evaluate --experiment {name}", both=False,
              how="each run's weather declared (the estimate's prior)" if declare else None)
          + f"\n\nRuns whose raises differ ({len(rows)}):\n\n"
          + (md_table(["run", "faults (channel, kind, onset s)", f"raised, {labels[0][0]}",
                       f"raised, {labels[1][0]}"], rows) if rows else "none"))
    (out / f"{name.split()[0]}.md").write_text(md + "\n")
    return md


def experiments() -> dict[str, Callable[[Path, int, bool], str]]:
    return {"rate_sweep": rate_sweep,
            "triplex_actuators": triplex_actuators,
            "gps_rate_accuracy": gps_rate_accuracy,
            "presets_weather": presets_without_declared_weather,
            "wan2018_campaign_weather": wan2018_campaign_weather,
            "wan2018_campaign_defaults": wan2018_campaign_defaults,
            "wan2018_thin_sets": wan2018_thin_sets,
            "wan2018_thin_sets_declared": wan2018_thin_sets_declared,
            "triplex_thin_sets": triplex_thin_sets,
            "triplex_weather": triplex_weather}
