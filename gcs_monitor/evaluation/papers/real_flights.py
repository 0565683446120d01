"""Every real flight, with the defaults and calibrated on its own kind (issue 15).

The flights of the real-data folder (``--data-dir``; ``../shared/data/real`` by default) fall
into sets by airframe and source: the Zipline launches, the ALFA Carbon-Z flights, the OnSpeed
stall run, the ArduCopter tlog, the ArduPilot DataFlash logs and the PX4 ULogs. None of them
has a known *sensor* fault (ALFA's failures are of the engine and the control surfaces), so any
sensor_fault or set_lost alarm is false. Each flight is replayed through its reader
(:func:`gcs_monitor.link.logs.open_log`: MAVLink bytes, as ``gcs-monitor replay``):

* with the **defaults**: per family the share of the flight it judged (coverage), its final
  state, the monitor_degraded alarms and the reason it did not judge, and the false alarms;
* **calibrated**: ``gcs-monitor calibrate`` (:func:`gcs_monitor.calibrate.calibrate`) on every
  other flight of the set (``flights[0::2]``) and tested on the others (``flights[1::2]``); a
  set of one flight cannot be split and is reported as such.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gcs_monitor.calibrate import calibrate
from gcs_monitor.config import MonitorConfig
from gcs_monitor.convert.logbase import LogError
from gcs_monitor.evaluation.report import md_table, write_csv
from gcs_monitor.evaluation.runner import run_parallel
from gcs_monitor.fdi.events import AlarmKind, AlarmState, FaultType
from gcs_monitor.fdi.records import StepOutput
from gcs_monitor.link.logs import open_log
from gcs_monitor.monitor import Monitor

FALSE_KINDS = (AlarmKind.SENSOR_FAULT, AlarmKind.SET_LOST)
COVERAGE_TARGET = 0.95  # issue 15: coverage at least 95 % wherever the rates allow
FAMILIES = ("imu", "airdata")


def flight_sets(data_dir: Path) -> dict[str, list[Path]]:
    """The real flights by set, each sorted by name (the split is by position in it)."""
    d = Path(data_dir)

    def files(*patterns: str) -> list[Path]:
        return sorted({p for pat in patterns for p in d.glob(pat)}, key=lambda p: p.name)

    sets = {
        "zipline": files("zipline_launch/flight_*.csv"),
        "alfa": files("alfa/carbonZ_*.csv", "carbonZ_*.csv"),
        "onspeed": files("onspeed_*.csv"),
        "tlog": files("*.tlog"),
        "dataflash": files("ardupilot_bin/*.bin", "ardupilot_bin/*.BIN"),
        "ulog": files("px4_ulog/*.ulg"),
    }
    return {k: v for k, v in sets.items() if v}


@dataclass
class FlightResult:
    """One flight monitored with one configuration."""

    set_name: str
    flight: str
    config: str  # "defaults" or "calibrated"
    duration_s: float = math.nan
    coverage: dict[str, float] = field(default_factory=dict)  # family -> share judged
    state: dict[str, str] = field(default_factory=dict)
    reason: dict[str, str] = field(default_factory=dict)
    degraded: dict[str, int] = field(default_factory=dict)  # family -> monitor_degraded raises
    false_alarms: list[str] = field(default_factory=list)  # "channel (type) at t s"
    # no_data raises: an instance that stopped delivering (a real gap is no false alarm)
    no_data: list[str] = field(default_factory=list)
    error: str = ""


def monitor_flight(path: Path, cfg: MonitorConfig, set_name: str, label: str) -> FlightResult:
    """Replay ``path`` with ``cfg`` (as ``gcs-monitor replay``) and score it: no sensor fault."""
    res = FlightResult(set_name, path.name, label)
    last: dict[str, Any] = {}
    t: list[int] = [0, 0]  # first and last Frame time, µs

    def on_step(sysid: int, frame: Any, out: StepOutput) -> None:
        if not t[0]:
            t[0] = frame.t_us
        t[1] = frame.t_us
        for c in out.coverage:
            last[c.family] = c

    try:
        opened = open_log(path)
    except LogError as exc:
        res.error = str(exc)
        return res
    mon = Monitor(cfg, on_step=on_step)
    with opened.source as src:
        for data, _ in src:
            mon.feed(data)
    mon.finish()
    for fam, c in last.items():
        res.coverage[fam] = c.overall
        res.state[fam] = c.state
        res.reason[fam] = c.reason
    t0 = t[0]
    for e in mon.events:
        if e.state is not AlarmState.RAISED:
            continue
        if e.kind is AlarmKind.MONITOR_DEGRADED:
            res.degraded[e.channel.axis] = res.degraded.get(e.channel.axis, 0) + 1
        elif e.kind in FALSE_KINDS and e.fault_type is FaultType.NO_DATA:
            res.no_data.append(f"{e.channel} at {(e.t_us - t0) * 1e-6:.1f} s")
        elif e.kind in FALSE_KINDS:
            res.false_alarms.append(f"{e.channel} ({e.fault_type}) at {(e.t_us - t0) * 1e-6:.1f} s")
    res.duration_s = (t[1] - t[0]) * 1e-6
    return res


def _flight_job(job: tuple[Path, MonitorConfig, str, str]) -> FlightResult:
    path, cfg, set_name, label = job
    return monitor_flight(path, cfg, set_name, label)


def _calibrate_job(job: tuple[str, list[Path]]) -> tuple[str, MonitorConfig | None, str]:
    """Calibrate on a set's first half; (set, config or None, what happened)."""
    set_name, paths = job
    try:
        cal = calibrate(paths)
    except Exception as exc:  # reported in the table: a set the calibration cannot use
        return set_name, None, f"calibrate failed: {exc}"
    th = ", ".join(f"{k} {v:.3g}" for k, v in sorted(cal.thresholds.items()))
    return set_name, cal.config, f"J_th {th}" if th else "no residual to calibrate"


def _cov(r: FlightResult, fam: str) -> str:
    c = r.coverage.get(fam)
    if c is None or not math.isfinite(c):
        st = r.state.get(fam, "-")
        return f"{st} ({r.reason[fam]})" if r.reason.get(fam) else st
    mark = f" (degraded x{r.degraded[fam]}: {r.reason.get(fam) or '?'})" if r.degraded.get(
        fam) else ""
    return f"{100 * c:.0f} %{mark}"


def _summary_rows(results: Sequence[FlightResult]) -> list[list[str]]:
    """Per set and configuration: flights, flights with a false alarm, false alarms, coverage
    of each family (median, min) and flights that raised monitor_degraded."""
    groups: dict[tuple[str, str], list[FlightResult]] = {}
    for r in results:
        groups.setdefault((r.set_name, r.config), []).append(r)
    rows = []
    for (s, label), rs in groups.items():
        ok = [r for r in rs if not r.error]
        cells = [s, label, str(len(ok)) + (f" ({len(rs) - len(ok)} unreadable)"
                                           if len(ok) < len(rs) else ""),
                 str(sum(1 for r in ok if r.false_alarms)), str(sum(len(r.false_alarms)
                                                                   for r in ok))]
        for fam in FAMILIES:
            vals = sorted(r.coverage[fam] for r in ok
                          if math.isfinite(r.coverage.get(fam, math.nan)))
            if not vals:
                if not any(fam in r.state for r in ok):
                    cells.append("not run")
                    continue
                # a family that never judged says why: each state and reason, with its count
                why: dict[str, int] = {}
                for r in ok:
                    st = r.state.get(fam, "-")
                    key = f"{st}: {r.reason[fam]}" if r.reason.get(fam) else st
                    why[key] = why.get(key, 0) + 1
                cells.append("; ".join(f"{k} (x{n})" if len(ok) > 1 else k
                                       for k, n in why.items()))
                continue
            below = sum(1 for v in vals if v < COVERAGE_TARGET)
            deg = sum(1 for r in ok if r.degraded.get(fam))
            cells.append(f"{100 * vals[len(vals) // 2]:.0f} % (min {100 * vals[0]:.0f} %; "
                         f"{below} below 95 %, {deg} degraded)")
        rows.append(cells)
    return rows


def real_flights(out_dir: Path, jobs: int, quick: bool, data_dir: Path) -> str:
    """Every real flight with the defaults, and calibrated on every other flight of its set
    and tested on the rest: coverage per family, monitor_degraded and false alarms."""
    root = Path(data_dir)
    sets = flight_sets(root)
    if not sets:
        raise FileNotFoundError(f"no real flights under {root} (--data-dir)")
    if quick:
        sets = {k: v[:4] for k, v in sets.items()}
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    base = MonitorConfig()
    work: list[tuple[Path, MonitorConfig, str, str]] = [
        (p, base, s, "defaults") for s, ps in sets.items() for p in ps]
    defaults = run_parallel(_flight_job, work, jobs, desc="real flights (defaults)")
    splittable = {s: ps for s, ps in sets.items() if len(ps) >= 2}
    cals = run_parallel(_calibrate_job, [(s, ps[0::2]) for s, ps in splittable.items()],
                        jobs, desc="calibrate (half of each set)")
    notes = {s: note for s, _, note in cals}
    test_work = [(p, cfg, s, "calibrated") for s, cfg, _ in cals if cfg is not None
                 for p in splittable[s][1::2]]
    calibrated = run_parallel(_flight_job, test_work, jobs, desc="real flights (calibrated)")
    held_out = {(s, p.name) for s, ps in splittable.items() for p in ps[1::2]}
    same_half = [dataclasses.replace(r, config="defaults, test half") for r in defaults
                 if (r.set_name, r.flight) in held_out]
    header = ["set", "configuration", "flights", "flights with false alarms", "false alarms",
              "imu coverage", "airdata coverage"]
    summary = _summary_rows([*defaults, *same_half, *calibrated])
    per_flight_header = ["set", "flight", "configuration", "duration s", "imu coverage",
                         "airdata coverage", "false alarms", "no_data", "error"]
    per_flight = [[r.set_name, r.flight, r.config, f"{r.duration_s:.1f}", _cov(r, "imu"),
                   _cov(r, "airdata"), "; ".join(r.false_alarms) or "0",
                   ", ".join(r.no_data) or "-", r.error or "-"]
                  for r in [*defaults, *calibrated]]
    write_csv(out / "real_flights.csv", per_flight_header, per_flight)
    one = [s for s, ps in sets.items() if len(ps) < 2]
    cal_lines = [f"- {s}: calibrated on {len(splittable[s][0::2])} flight(s), tested on "
                 f"{len(splittable[s][1::2])}: {notes.get(s, '-')}" for s in splittable]
    md = ["Real flights (data folder `--data-dir`), default configuration and `calibrate` on "
          "every other flight of a set, tested on the others. Coverage: share of the flight "
          "each family judged (median over the set, its minimum, flights below the 95 % "
          "target, flights that raised monitor_degraded). Any sensor_fault or set_lost alarm "
          "is false (none of these flights has a known sensor fault). "
          "`gcs-monitor evaluate --experiment real_flights"
          f"{' --quick' if quick else ''}`",
          "", md_table(header, summary), "", *cal_lines]
    if one:
        md += ["", "Not split (one flight): " + ", ".join(one) + "."]
    flagged = [row for row in per_flight if row[6] != "0" or row[8] != "-"]
    if flagged:
        md += ["", "Flights with false alarms or unreadable:", "",
               md_table(per_flight_header, flagged)]
    text = "\n".join(md)
    (out / "real_flights.md").write_text(text + "\n")
    return text


def real_data_experiments() -> dict[str, Callable[[Path, int, bool, Path], str]]:
    """Named experiments on the real data (registry hook)."""
    return {"real_flights": real_flights}
