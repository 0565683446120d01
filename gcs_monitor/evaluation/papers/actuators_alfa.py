"""Actuator family on ALFA's real failures (CMU AirLab; Keipour, Mousaei, Scherer 2019/2021).

``actuators_alfa``: every ALFA flight in the real-data folder (the 13 of ``alfa/`` and the 3 at
its top: engine, left/right/both ailerons, rudder, elevator, no failure) converted by
``gcs_monitor.convert`` (commanded attitude = measured + ``delta_*`` as NAV_CONTROLLER_OUTPUT,
the failure status as truth beside the tlog) and replayed through the Monitor with the actuator
family alone, in setpoint mode (ALFA has no servo outputs and no throttle).

ONE configuration for all flights. Its thresholds are set, per check (surfaces, engine,
effectiveness), to 1.25 x the largest J the check reaches on healthy flight: the no-failure
flights and the parts of the failure flights before the failure, replayed with thresholds no
residual reaches (no alarm, no freezing). The false positives are therefore counted on the
data the thresholds came from; a leave-one-flight-out table (thresholds from the other flights
only) and the simulator-calibrated defaults show what that costs.

Metrics per flight, as Keipour et al. use them: a failure flight is a true positive when the
first actuator alarm comes at or after the failure, a false positive when one comes before
it, a false negative when none comes; a no-failure flight is a false positive with any alarm,
else a true negative. Precision TP / (TP + FP), recall TP / (TP + FN), accuracy (TP + TN) / N;
detection time = first alarm minus failure onset (the first non-zero status row). Besides,
the component the first alarm names (the published RLS baseline names none).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gcs_monitor.config import MonitorConfig
from gcs_monitor.convert.writer import convert_file, load_failure_truth, truth_path_of
from gcs_monitor.evaluation.papers.actuators import CHECKS, MARGIN, actuator_config
from gcs_monitor.evaluation.report import md_table, pyplot
from gcs_monitor.evaluation.runner import run_parallel
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState
from gcs_monitor.link.transports import TlogSource
from gcs_monitor.monitor import Monitor

# Keipour et al., ICRA 2019 (RLS on commanded/measured pairs, 22 ALFA flights), as the data
# README quotes them: it detects, it does not say which surface
PUBLISHED = {"precision_pct": 88.23, "recall_pct": 88.23, "accuracy_pct": 86.36,
             "delay_mean_s": 2.02, "delay_max_s": 5.6}
US = 1_000_000


def alfa_files(data_dir: Path) -> list[Path]:
    """Every ALFA CSV of the real-data folder: the top level's and ``alfa/``'s."""
    return sorted(list(Path(data_dir).glob("carbonZ_*.csv"))
                  + list((Path(data_dir) / "alfa").glob("carbonZ_*.csv")))


def setpoint_config(thresholds: dict[str, float] | None = None) -> MonitorConfig:
    """The actuator family alone, commands from the setpoints (ALFA has no servo outputs)."""
    cfg = actuator_config(thresholds)
    ac = cfg.family("actuators").aircraft
    return cfg.with_family("actuators", aircraft=dataclasses.replace(ac,
                                                                     command_source="setpoint"))


def with_thresholds(cfg: MonitorConfig, th: dict[str, float]) -> MonitorConfig:
    ac = cfg.family("actuators").aircraft
    fdi = dataclasses.replace(
        ac.fdi, **{k: dataclasses.replace(getattr(ac.fdi, k), threshold=th[k]) for k in CHECKS})
    return cfg.with_family("actuators", aircraft=dataclasses.replace(ac, fdi=fdi))


@dataclass
class AlfaFlight:
    name: str
    tlog: Path
    component: str  # "" for a no-failure flight
    kind: str
    t_fail_s: float  # NaN without a failure
    duration_s: float


@dataclass
class Replay:
    events: list[AlarmEvent]
    j: dict[str, np.ndarray]  # check -> (n, 2) [t_s, J] over every axis of that check


def convert_all(data_dir: Path, out_dir: Path) -> list[AlfaFlight]:
    out_dir.mkdir(parents=True, exist_ok=True)
    flights = []
    for csv in alfa_files(data_dir):
        tlog = out_dir / f"{csv.stem}.tlog"
        res = convert_file(csv, tlog)
        tr = load_failure_truth(truth_path_of(tlog))
        comp = str(tr["failure_component"])
        ev = tr["fault_events"]
        t_fail = float(ev[0]["t_start_s"]) if ev else math.nan  # type: ignore[index]
        flights.append(AlfaFlight(csv.stem, tlog, comp, str(tr["failure_kind"]), t_fail,
                                  res.duration_s))
    return flights


def replay(tlog: Path, cfg: MonitorConfig) -> Replay:
    """A converted flight through the Monitor; the alarm events and every check's J."""
    rows: dict[str, list[tuple[float, float]]] = {k: [] for k in CHECKS}

    def on_step(sysid: int, frame: Any, step: Any) -> None:
        for c in step.channels:
            if c.channel.kind == "actuator":
                k = "engine" if c.channel.axis == "engine" else "surface"
            elif c.channel.kind == "actuator_effectiveness":
                k = "effectiveness"
            else:
                continue
            rows[k].append((frame.t_us / US, c.rms))

    mon = Monitor(cfg, on_step=on_step)
    with TlogSource(tlog) as src:
        for chunk, _ in src:
            mon.feed(chunk)
    mon.finish()
    return Replay(list(mon.events), {k: np.asarray(v, dtype=float).reshape(-1, 2)
                                     for k, v in rows.items()})


def _replay_job(job: tuple[Path, MonitorConfig]) -> Replay:
    return replay(*job)


def healthy_max(f: AlfaFlight, r: Replay) -> dict[str, float]:
    """The largest J per check over the flight's healthy part (all of a no-failure flight)."""
    out = {}
    for k, a in r.j.items():
        m = a[:, 0] < f.t_fail_s if math.isfinite(f.t_fail_s) else np.ones(len(a), bool)
        out[k] = float(a[m, 1].max()) if m.any() else 0.0
    return out


def thresholds_from(maxima: Sequence[dict[str, float]]) -> dict[str, float]:
    return {k: MARGIN * max(m[k] for m in maxima) for k in CHECKS}


@dataclass
class Outcome:
    flight: AlfaFlight
    label: str  # TP, FP, FN, TN
    first_t_s: float  # first actuator alarm (NaN: none)
    delay_s: float  # first alarm minus the failure onset (TP only)
    named: str  # the component the first alarm after the onset names
    classes: str


def outcome(f: AlfaFlight, events: Sequence[AlarmEvent]) -> Outcome:
    raised = [e for e in events if e.kind is AlarmKind.ACTUATOR_FAULT
              and e.state is AlarmState.RAISED]
    first = raised[0].t_us / US if raised else math.nan
    failed = math.isfinite(f.t_fail_s)
    if not failed:
        label = "FP" if raised else "TN"
    elif not raised:
        label = "FN"
    else:
        label = "TP" if first >= f.t_fail_s else "FP"
    after = [e for e in raised if failed and e.t_us / US >= f.t_fail_s]
    named = after[0].channel.axis if after else "-"
    delay = first - f.t_fail_s if label == "TP" else math.nan
    classes = ", ".join(dict.fromkeys(
        f"{e.channel.axis} {e.fault_type.value}" for e in after[:3])) if after else "-"
    return Outcome(f, label, first, delay, named, classes)


def keipour_metrics(outs: Sequence[Outcome]) -> dict[str, float]:
    n = {k: sum(o.label == k for o in outs) for k in ("TP", "FP", "FN", "TN")}
    tp, fp, fn, tn = n["TP"], n["FP"], n["FN"], n["TN"]
    d = [o.delay_s for o in outs if o.label == "TP"]
    right = sum(1 for o in outs if o.label == "TP" and o.named == o.flight.component)
    return {**{k: float(v) for k, v in n.items()},
            "precision_pct": 100.0 * tp / (tp + fp) if tp + fp else math.nan,
            "recall_pct": 100.0 * tp / (tp + fn) if tp + fn else math.nan,
            "accuracy_pct": 100.0 * (tp + tn) / len(outs) if outs else math.nan,
            "delay_mean_s": float(np.mean(d)) if d else math.nan,
            "delay_max_s": float(np.max(d)) if d else math.nan,
            "isolated_pct": 100.0 * right / tp if tp else math.nan}


def _metrics_row(name: str, m: dict[str, float]) -> list[Any]:
    return [name, f"{m['precision_pct']:.2f}", f"{m['recall_pct']:.2f}",
            f"{m['accuracy_pct']:.2f}", f"{m['delay_mean_s']:.2f}", f"{m['delay_max_s']:.2f}",
            f"{m['isolated_pct']:.0f}" if math.isfinite(m["isolated_pct"]) else "-",
            f"{m['TP']:.0f}/{m['FP']:.0f}/{m['FN']:.0f}/{m['TN']:.0f}"]


def plot_flights(flights: Sequence[AlfaFlight], replays: Sequence[Replay],
                 th: dict[str, float], path: Path) -> None:
    """Per failure flight, each check's J / J_th around the failure onset."""
    failed = [(f, r) for f, r in zip(flights, replays, strict=True)
              if math.isfinite(f.t_fail_s)]
    plt = pyplot()
    cols = 3
    rows = math.ceil(len(failed) / cols)
    fig, axs = plt.subplots(rows, cols, figsize=(13, 2.6 * rows), sharey=True)
    for ax, (f, r) in zip(np.ravel(axs), failed, strict=False):
        for k in CHECKS:
            a = r.j[k]
            m = (a[:, 0] > f.t_fail_s - 30.0)
            ax.plot(a[m, 0] - f.t_fail_s, a[m, 1] / th[k], ".", ms=1.5, label=k)
        ax.axvline(0.0, color="r", lw=0.8)
        ax.axhline(1.0, color="k", lw=0.6, ls="--")
        for e in r.events:
            if e.kind is AlarmKind.ACTUATOR_FAULT and e.state is AlarmState.RAISED:
                ax.axvline(e.t_us / US - f.t_fail_s, color="g", lw=0.8, ls=":")
        ax.set_yscale("log")
        ax.set_ylim(0.05, 20.0)
        ax.set_title(f"{f.kind} ({f.name[8:27]})", fontsize=8)
        ax.grid(True, alpha=0.3)
    for ax in np.ravel(axs)[len(failed):]:
        ax.axis("off")
    np.ravel(axs)[0].legend(fontsize=7)
    fig.supxlabel("t - failure onset [s] (green: actuator alarm raised)")
    fig.supylabel("J / J_th")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def actuators_alfa(out_dir: Path, jobs: int, quick: bool, data_dir: Path, *,
                   img_dir: Path | None = None) -> str:
    """Every ALFA flight with one configuration (thresholds from healthy flight), detection time
    and isolated component per flight, Keipour's precision/recall/accuracy against the published
    RLS baseline; leave-one-flight-out and simulator-default thresholds beside it."""
    out_dir = Path(out_dir)
    flights = convert_all(data_dir, out_dir / "alfa_tlogs")
    if quick:
        flights = flights[:6]
    open_runs = run_parallel(_replay_job, [(f.tlog, setpoint_config()) for f in flights], jobs,
                             desc="calibrate")
    maxima = [healthy_max(f, r) for f, r in zip(flights, open_runs, strict=True)]
    th = thresholds_from(maxima)
    cfg = setpoint_config(th)
    runs = run_parallel(_replay_job, [(f.tlog, cfg) for f in flights], jobs, desc="alfa")
    outs = [outcome(f, r.events) for f, r in zip(flights, runs, strict=True)]
    # leave one flight out: thresholds from the other flights' healthy parts
    loo_cfgs = [setpoint_config(thresholds_from(maxima[:i] + maxima[i + 1:]))
                for i in range(len(flights))]
    loo_runs = run_parallel(_replay_job, [(f.tlog, c) for f, c in zip(flights, loo_cfgs,
                                                                        strict=True)],
                            jobs, desc="leave one out")
    loo = [outcome(f, r.events) for f, r in zip(flights, loo_runs, strict=True)]
    defaults = run_parallel(_replay_job, [(f.tlog, with_thresholds(
        setpoint_config(), {k: getattr(MonitorConfig().family("actuators").aircraft.fdi,
                                       k).threshold for k in CHECKS})) for f in flights],
        jobs, desc="defaults")
    dflt = [outcome(f, r.events) for f, r in zip(flights, defaults, strict=True)]
    img = Path(img_dir) if img_dir is not None else out_dir
    img.mkdir(parents=True, exist_ok=True)
    plot_flights(flights, runs, th, img / "actuators_alfa_flights.png")
    per_flight = [[o.flight.name.removeprefix("carbonZ_"), o.flight.component or "none",
                   f"{o.flight.t_fail_s:.2f}" if math.isfinite(o.flight.t_fail_s) else "-",
                   o.label, f"{o.delay_s:.2f}" if math.isfinite(o.delay_s) else (
                       f"(alarm at {o.first_t_s:.1f})" if o.label == "FP" else "-"),
                   o.named, o.classes, l1.label, l2.label]
                  for o, l1, l2 in zip(outs, loo, dflt, strict=True)]
    header = ["flight", "failed", "onset [s]", "outcome", "detection time [s]", "named",
              "classes", "leave-one-out", "sim defaults"]
    m_header = ["method", "precision [%]", "recall [%]", "accuracy [%]", "detection mean [s]",
                "detection max [s]", "right component [%]", "TP/FP/FN/TN"]
    pub = PUBLISHED
    metrics = [
        ["Keipour et al. 2019, RLS (published, 22 flights)", f"{pub['precision_pct']:.2f}",
         f"{pub['recall_pct']:.2f}", f"{pub['accuracy_pct']:.2f}", f"{pub['delay_mean_s']:.2f}",
         f"{pub['delay_max_s']:.2f}", "- (names none)", "-"],
        _metrics_row("aircraft tier, one configuration (healthy-flight thresholds)",
                     keipour_metrics(outs)),
        _metrics_row("the same, thresholds leaving the flight out", keipour_metrics(loo)),
        _metrics_row("the same, the simulator-calibrated defaults", keipour_metrics(dflt)),
    ]
    th_lines = "\n".join(
        f"  {k}: worst healthy J {max(m[k] for m in maxima):.3g} -> J_th {th[k]:.3g} "
        f"(default {getattr(MonitorConfig().family('actuators').aircraft.fdi, k).threshold:g})"
        for k in CHECKS)
    return (f"{len(flights)} ALFA flights ({sum(math.isfinite(f.t_fail_s) for f in flights)} "
            "with a failure); thresholds (one configuration, "
            f"{MARGIN:g} x the worst J on the no-failure flights and the pre-failure parts):"
            "\n\n```\n" + th_lines + "\n```\n\n" + md_table(m_header, metrics) + "\n\n"
            + md_table(header, per_flight) + "\n")


def real_data_experiments() -> dict[str, Callable[[Path, int, bool, Path], str]]:
    return {"actuators_alfa": actuators_alfa}
