"""Post-flight fault report: one self-contained HTML page per log (``gcs-monitor report``).

In the spirit of PX4 Flight Review, for faults: the flight overview (duration, vehicle,
messages and their rates), each family's coverage (state, share of the flight judged, why
not), the alarm timeline, one figure per alarm (the measured, fused and model values of the
channel, its residual RMS against the threshold, the onset marked) and the health counters.
Figures are matplotlib PNGs embedded as base64, so the page is one file with no network use.

The log goes through :func:`gcs_monitor.link.logs.open_log` and a normal
:class:`~gcs_monitor.monitor.Monitor`; the report reads only what the monitor outputs.
"""

from __future__ import annotations

import base64
import html
import io
import math
import time
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gcs_monitor.config import MonitorConfig
from gcs_monitor.core.types import ChannelId
from gcs_monitor.fdi.events import AlarmEvent, AlarmState
from gcs_monitor.fdi.records import StepOutput
from gcs_monitor.link.logs import open_log
from gcs_monitor.monitor import Monitor

PLOT_PERIOD_US = 50_000  # series kept at 20 Hz at most
WINDOW_BEFORE_S = 20.0  # an alarm's figure: this long before the onset
WINDOW_AFTER_S = 20.0
MAX_ALARM_FIGURES = 24


@dataclass
class Series:
    t_s: list[float] = field(default_factory=list)
    measured: list[float] = field(default_factory=list)
    fused: list[float] = field(default_factory=list)
    model: list[float] = field(default_factory=list)
    rms: list[float] = field(default_factory=list)
    threshold: list[float] = field(default_factory=list)


@dataclass
class ReportData:
    """What the monitor produced on one log, as the report reads it."""

    path: Path
    info: Any
    health: dict[str, Any]
    events: list[AlarmEvent]
    series: dict[tuple[str, int, str], Series]
    wall_s: float
    t0_us: int | None


def _name(ch: ChannelId) -> str:
    if ch.instance < 0:
        return f"{ch.kind}[set]"
    return f"{ch.kind}{ch.instance}{'.' + ch.axis if ch.axis else ''}"


class _Collector:
    """``on_step`` of the Monitor: channel and set series at 20 Hz at most."""

    def __init__(self) -> None:
        self.series: dict[tuple[str, int, str], Series] = defaultdict(Series)
        self.next_us: dict[int, int] = {}
        self.t0_us: int | None = None

    def __call__(self, sysid: int, frame: Any, out: StepOutput) -> None:
        t = frame.t_us
        if self.t0_us is None:
            self.t0_us = t
        if t < self.next_us.get(sysid, -1) and not out.events:
            return
        self.next_us[sysid] = t + PLOT_PERIOD_US
        ts = (t - self.t0_us) * 1e-6
        for c in out.channels:
            s = self.series[(c.channel.kind, c.channel.instance, c.channel.axis)]
            s.t_s.append(ts)
            s.measured.append(c.value)
            s.fused.append(math.nan)
            s.model.append(math.nan)
            s.rms.append(c.rms)
            s.threshold.append(c.threshold)
        for st in out.sets:
            for i, m in enumerate(st.measured):
                s = self.series[(st.name, i, "")]
                s.t_s.append(ts)
                s.measured.append(m)
                s.fused.append(st.fused)
                s.model.append(st.reference)
                s.rms.append(st.rms[i] if i < len(st.rms) else math.nan)
                s.threshold.append(st.threshold)


def run_log(path: Path, *, cfg: MonitorConfig | None = None, fmt: str | None = None,
            column_map: Path | None = None, imu_rate_hz: float | None = None) -> ReportData:
    """Replay one log through a Monitor that records what the report shows."""
    opened = open_log(path, fmt, column_map=column_map, imu_rate_hz=imu_rate_hz)
    col = _Collector()
    mon = Monitor(cfg or MonitorConfig(), on_step=col)
    t0 = time.monotonic()
    src = opened.source
    for data, wall in src:
        mon.feed(data, wall)
    mon.finish()
    mon.close()
    info = opened.info
    if info.fmt == "tlog":
        info.messages = {k: n for st in mon.decoder.stats.values()
                         for k, n in st.per_type.items()}
    return ReportData(Path(path), info, mon.health(), list(mon.events), dict(col.series),
                      time.monotonic() - t0, col.t0_us)


# -- figures -------------------------------------------------------------------------------------
def _png(fig: Any) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    import matplotlib.pyplot as plt

    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _alarm_figure(ev: AlarmEvent, s: Series, t0_us: int) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    onset = (ev.t_us - t0_us) * 1e-6
    t = np.asarray(s.t_s)
    sel = (t >= onset - WINDOW_BEFORE_S) & (t <= onset + WINDOW_AFTER_S)
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8.0, 4.6), sharex=True)
    is_set = ev.channel.axis == "" and any(math.isfinite(x) for x in s.model)
    a1.plot(t[sel], np.asarray(s.measured)[sel], lw=1.0,
            label="measured" if is_set else "reconstructed fault")
    if any(math.isfinite(x) for x in s.fused):
        a1.plot(t[sel], np.asarray(s.fused)[sel], lw=1.0, label="fused (eq. 19)")
    if any(math.isfinite(x) for x in s.model):
        a1.plot(t[sel], np.asarray(s.model)[sel], lw=1.0, ls="--", label="model / reference")
    a1.set_ylabel(f"{_name(ev.channel)} (SI)")
    a1.legend(loc="best", fontsize=8)
    a2.plot(t[sel], np.asarray(s.rms)[sel], lw=1.0, label="residual RMS")
    a2.plot(t[sel], np.asarray(s.threshold)[sel], lw=1.0, ls="--", color="r", label="threshold")
    a2.set_ylabel("RMS (SI)")
    a2.set_xlabel("time since the first frame (s)")
    a2.legend(loc="best", fontsize=8)
    for ax in (a1, a2):
        ax.axvline(onset, color="k", lw=0.8)
        ax.grid(alpha=0.3)
    a1.set_title(f"{_name(ev.channel)}: {ev.kind.value} {ev.fault_type.value}, onset "
                 f"t = {onset:.2f} s", fontsize=10)
    return _png(fig)


def _timeline_figure(events: list[AlarmEvent], t0_us: int, duration_s: float) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names: list[str] = []
    spans: dict[str, list[tuple[float, float, str]]] = {}
    open_: dict[str, tuple[float, str]] = {}
    for ev in events:
        n = _name(ev.channel)
        if n not in names:
            names.append(n)
        t = (ev.t_us - t0_us) * 1e-6
        if ev.state == AlarmState.RAISED and n not in open_:
            open_[n] = (t, ev.kind.value)
        elif ev.state == AlarmState.CLEARED and n in open_:
            t_on, kind = open_.pop(n)
            spans.setdefault(n, []).append((t_on, t, kind))
    for n, (t_on, kind) in open_.items():
        spans.setdefault(n, []).append((t_on, duration_s, kind))
    colors = {"sensor_fault": "tab:orange", "set_lost": "tab:red", "actuator_fault": "tab:red",
              "monitor_degraded": "tab:gray", "estimator": "tab:purple", "link": "tab:blue"}
    fig, ax = plt.subplots(figsize=(8.0, 0.45 * len(names) + 1.2))
    for k, n in enumerate(names):
        for a, b, kind in spans.get(n, []):
            ax.barh(k, max(b - a, duration_s / 400), left=a, color=colors.get(kind, "k"),
                    height=0.6)
    ax.set_yticks(range(len(names)), names, fontsize=8)
    ax.set_xlim(0, max(duration_s, 1.0))
    ax.set_xlabel("time since the first frame (s)")
    ax.invert_yaxis()
    ax.grid(axis="x", alpha=0.3)
    return _png(fig)


# -- page ----------------------------------------------------------------------------------------
CSS = """body{font-family:system-ui,sans-serif;margin:24px;max-width:1100px;color:#222}
h1{font-size:22px}h2{font-size:18px;border-bottom:1px solid #ccc;padding-bottom:4px}
table{border-collapse:collapse;font-size:13px;margin:8px 0}
td,th{border:1px solid #ddd;padding:3px 8px;text-align:left}th{background:#f3f3f3}
.judging{color:#1a7f37}.degraded{color:#b35900}.unavailable,.starting{color:#888}
.raised{color:#b00}.cleared{color:#1a7f37}.warn{color:#b35900}img{max-width:100%}
.small{color:#666;font-size:12px}"""


def _table(head: list[str], rows: list[list[Any]]) -> str:
    h = "".join(f"<th>{html.escape(str(x))}</th>" for x in head)
    body = "".join("<tr>" + "".join(f"<td>{x}</td>" for x in r) + "</tr>" for r in rows)
    return f"<table><tr>{h}</tr>{body}</table>"


def render(data: ReportData) -> str:
    """The HTML page of one report."""
    info = data.info
    h = data.health
    vehicles = h.get("vehicles", {})
    dur = info.duration_s or max((v["vehicle_time_s"] for v in vehicles.values()), default=0.0)
    esc = html.escape
    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>Fault report: "
             f"{esc(data.path.name)}</title><style>{CSS}</style></head><body>",
             f"<h1>Fault report: {esc(data.path.name)}</h1>",
             f"<p class='small'>gcs-monitor report; replayed in {data.wall_s:.1f} s "
             f"({dur / data.wall_s if data.wall_s else 0:.0f}x real time)</p>"]
    # overview
    n_msg = sum(info.messages.values())
    parts.append("<h2>Flight overview</h2>")
    parts.append(_table(["", ""], [
        ["file", esc(str(data.path))], ["format", esc(info.fmt)],
        ["vehicle", esc(info.vehicle or "-")], ["duration", f"{dur:.1f} s"],
        ["MAVLink messages given to the monitor", f"{n_msg}"],
        ["log records read", f"{sum(info.records.values())}" if info.records else "-"]]))
    for w in info.warnings:
        parts.append(f"<p class='warn'>{esc(w)}</p>")
    if info.messages:
        rows = [[esc(k), n, f"{n / dur:.1f}" if dur else "-"]
                for k, n in sorted(info.messages.items(), key=lambda kv: -kv[1])]
        parts.append(_table(["message", "count", "rate (Hz)"], rows))
    # coverage
    parts.append("<h2>Coverage per family</h2>")
    rows = []
    for sysid, v in vehicles.items():
        for name, fam in v["families"].items():
            cov = fam.get("coverage_overall", math.nan)
            rows.append([f"{sysid}", esc(name), f"<span class='{fam['state']}'>{fam['state']}"
                         "</span>", f"{100 * cov:.1f} %" if math.isfinite(cov) else "-",
                         esc(fam.get("reason", "")), esc(fam.get("title", ""))])
    parts.append(_table(["vehicle", "family", "state", "share judged", "why not", "what"],
                        rows))
    # alarms
    parts.append("<h2>Alarm timeline</h2>")
    t0 = data.t0_us or 0
    if data.events:
        parts.append(f"<img alt='alarm timeline' src='data:image/png;base64,"
                     f"{_timeline_figure(data.events, t0, dur)}'>")
        rows = [[f"{(e.t_us - t0) * 1e-6:.2f}", f"<span class='{e.state.value}'>"
                 f"{e.state.value}</span>", esc(_name(e.channel)), esc(e.kind.value),
                 esc(e.fault_type.value),
                 f"{e.magnitude:+.3g}" if math.isfinite(e.magnitude) else "-",
                 f"{e.residual_rms:.3g} / {e.threshold:.3g}"
                 if math.isfinite(e.residual_rms) else "-", esc(e.estimator),
                 esc(e.message)]
                for e in data.events if e.state != AlarmState.UPDATED]
        parts.append(_table(["t (s)", "state", "channel", "kind", "type", "magnitude (SI)",
                             "RMS / threshold", "estimator", "message"], rows))
    else:
        parts.append("<p>No alarms.</p>")
    # one figure per alarm
    figs: list[str] = []
    seen: set[tuple[str, int, str]] = set()
    for e in data.events:
        key = (e.channel.kind, e.channel.instance, e.channel.axis)
        if e.state != AlarmState.RAISED or key in seen or key not in data.series:
            continue
        seen.add(key)
        if len(figs) < MAX_ALARM_FIGURES:
            figs.append(f"<img alt='{esc(_name(e.channel))}' src='data:image/png;base64,"
                        f"{_alarm_figure(e, data.series[key], t0)}'>")
    if figs:
        parts.append("<h2>Alarms in detail</h2>")
        parts.append("<p class='small'>Per alarm: the channel's values (measured, fused, the "
                     "model's prediction; for the IMU family the reconstructed fault) and its "
                     "residual RMS against the threshold; the vertical line is the onset.</p>")
        parts += figs
    # health counters
    parts.append("<h2>Health counters</h2>")
    rows = [[esc(k), v] for k, v in h.get("link", {}).items()]
    for sysid, v in vehicles.items():
        lk = v["link"]
        for k in ("messages", "lost", "loss_pct", "duplicates", "reordered", "reboots",
                  "bad_values_total", "time_backwards", "primary_imu_switches"):
            if k in lk:
                val = lk[k]
                rows.append([f"vehicle {sysid} {k}",
                             f"{val:.2f}" if isinstance(val, float) else val])
    parts.append(_table(["counter", "value"], rows))
    parts.append("</body></html>")
    return "\n".join(parts)


def write_report(path: Path, out_dir: Path, **kw: Any) -> Path:
    """Replay ``path`` and write ``out_dir/<log name>.html``; return the page's path."""
    data = run_log(Path(path), **kw)
    out_dir.mkdir(parents=True, exist_ok=True)
    page = out_dir / f"{Path(path).stem}.html"
    page.write_text(render(data), encoding="utf-8")
    return page
