"""``gcs-monitor demo``: a faulty preset is simulated, monitored through MAVLink bytes, and a
Rerun recording, an alarm journal, the tlog and a summary table come out in one folder.

Steps: (1) sim_vehicle writes the flight as a .tlog plus ground truth (file mode, as fast as
possible); (2) the monitor replays the .tlog (decode -> Frames -> estimators -> FDI -> sinks);
(3) the alarms are compared with the scenario's faults.
"""

from __future__ import annotations

import re
import time
from pathlib import Path
from typing import Any

from gcs_monitor.console import (
    channel_label,
    final_state,
    first_and_final,
    format_event,
    magnitude_text,
    type_text,
)
from gcs_monitor.core.types import ChannelId
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind

_SENSOR = re.compile(r"^(aoa|cas)(\d)$")
_IMU = re.compile(r"^imu(\d)\.(acc|gyro)\.([xyzpqr])$")
_ACTUATOR = re.compile(r"^actuator\.(aileron|elevator|rudder|engine)$")
_ACTUATORS = ("aileron", "elevator", "rudder", "engine")  # the simulator's actuator indices


def truth_channel(sim_channel: str) -> ChannelId | None:
    """Map a simulator fault channel name to the monitor's ChannelId (None if not monitored)."""
    m = _SENSOR.match(sim_channel)
    if m:
        return ChannelId(m.group(1), int(m.group(2)))
    m = _IMU.match(sim_channel)
    if m:
        return ChannelId(m.group(2), int(m.group(1)), m.group(3))
    m = _ACTUATOR.match(sim_channel)
    if m:
        return ChannelId("actuator", _ACTUATORS.index(m.group(1)), m.group(1))
    return None


SUMMARY_HEADER = ["channel", "injected fault", "t_start [s]", "result", "delay [s]",
                  "first raise (type, magnitude)", "final state (t, type, magnitude)"]


def _raise_cells(first: AlarmEvent, last: AlarmEvent) -> list[str]:
    kind = first.channel.kind
    return [f"{type_text(first)} {magnitude_text(kind, first.magnitude)}",
            f"{final_state(last)}, last event {last.t_us / 1e6:.2f} s: {type_text(last)} "
            f"{magnitude_text(kind, last.magnitude)}"]


def summary_rows(events: list[AlarmEvent], faults: list[dict[str, Any]]) -> list[list[str]]:
    """One row per injected fault (detected?, delay, first raise, final state), per alarm on a
    healthy channel and per lost set (columns: :data:`SUMMARY_HEADER`). No NaN: a value that
    does not exist is ``-``."""
    raised = {first.channel: (first, last) for first, last, _ in first_and_final(events)
              if first.kind in (AlarmKind.SENSOR_FAULT, AlarmKind.ACTUATOR_FAULT,
                                AlarmKind.SET_LOST)}
    rows = []
    faulty = set()
    for f in faults:
        ch = truth_channel(str(f["channel"]))
        t0 = float(f["t_start_s"])
        if ch is None:
            rows.append([str(f["channel"]), str(f["kind"]), f"{t0:.1f}", "not monitored", "-",
                         "-", "-"])
            continue
        faulty.add(ch)
        hit = raised.get(ch)
        if hit is None:
            rows.append([channel_label(ch), str(f["kind"]), f"{t0:.1f}", "MISSED", "-", "-", "-"])
        else:
            rows.append([channel_label(ch), str(f["kind"]), f"{t0:.1f}", "detected",
                         f"{hit[0].t_us / 1e6 - t0:.2f}", *_raise_cells(*hit)])
    # the actuator family names a failed surface on two tiers: the aircraft level's
    # actuator<k>.<name> and, where SURF feedback exists, the servo level's surface<k>.*
    failed_surfaces = {ch.instance for ch in faulty if ch.kind == "actuator"}
    for ch, (first, last) in raised.items():
        if ch.kind == "surface" and ch.instance in failed_surfaces:
            rows.append([channel_label(ch), "(servo level of the same surface)", "-",
                         "detected", f"t={first.t_us / 1e6:.2f}", *_raise_cells(first, last)])
            continue
        if ch not in faulty:
            result = "set lost" if first.kind is AlarmKind.SET_LOST else "FALSE ALARM"
            rows.append([channel_label(ch), "(none)", "-", result, f"t={first.t_us / 1e6:.2f}",
                         *_raise_cells(first, last)])
    return rows


def markdown_table(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def run_demo(out: Path, *, preset: str = "demo_airdata_faults") -> int:
    from dashboards.blueprints import default_blueprint, family_views
    from gcs_monitor.config import MonitorConfig
    from gcs_monitor.config.loader import load_config
    from gcs_monitor.link.transports import TlogSource
    from gcs_monitor.monitor import Monitor
    from gcs_monitor.sinks.journal import AlarmJournal
    from gcs_monitor.sinks.rerun_sink import RerunSink
    from sim_vehicle.run import run_scenario
    from sim_vehicle.scenario import load_scenario

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    sc = load_scenario(preset)
    print(f"[1/3] simulating '{preset}' ({sc.duration_s:.0f} s, {sc.airframe}) -> {out}/")
    res = run_scenario(sc, out, progress=True)
    print(f"      {sum(res.counts.values())} MAVLink messages, "
          f"{res.realtime_factor:.0f}x real time")
    journal_path = out / "alarms.jsonl"
    journal_path.unlink(missing_ok=True)
    rrd = out / "recording.rrd"
    journal = AlarmJournal(journal_path)
    # the monitor configured for the airframe it watches, where the repository has one
    # (configs/<airframe>.toml: the servo level's lever and stroke of the UAV)
    airframe_cfg = Path(__file__).resolve().parents[1] / "configs" / f"{sc.airframe}.toml"
    cfg = load_config(airframe_cfg) if airframe_cfg.is_file() else MonitorConfig()
    if airframe_cfg.is_file():
        print(f"      monitor configuration: configs/{airframe_cfg.name}")

    def sinks(sysid: int) -> list[Any]:
        return [RerunSink(sysid, rrd_path=rrd, plot_rate_hz=cfg.sinks.rerun_rate_hz,
                          blueprint=default_blueprint(sysid, family_views(cfg))), journal]

    print("[2/3] monitoring the tlog (decode -> frames -> estimators -> FDI -> Rerun/journal)")
    assert res.tlog_path is not None
    mon = Monitor(cfg, sinks_for=sinks)
    t1 = time.monotonic()
    for data, wall in TlogSource(res.tlog_path):
        mon.feed(data, wall)
    mon.finish()
    mon.close()
    t_mon = time.monotonic() - t1
    print(f"      {len(mon.events)} alarm events in {t_mon:.1f} s "
          f"({sc.duration_s / t_mon:.0f}x real time)")
    print("[3/3] alarms against the scenario's faults")
    for ev in mon.events:
        print("      " + format_event(ev))
    table = markdown_table(SUMMARY_HEADER, summary_rows(mon.events, res.fault_events))
    print()
    print(table)
    summary = out / "summary.md"
    summary.write_text(
        f"# Demo: {preset}\n\n{sc.description}\n\n{table}\n\n"
        f"Files: `{res.tlog_path.name}` (MAVLink), `{res.truth_path.name}` (ground truth), "
        f"`{rrd.name}` (Rerun: `rerun {rrd}`), `{journal_path.name}` (alarm journal).\n")
    print(f"\nwrote {rrd}, {journal_path}, {res.tlog_path}, {summary} "
          f"in {time.monotonic() - t0:.0f} s")
    return 0
