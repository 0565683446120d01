"""Actuator family, aircraft tier, on a seeded simulated campaign (issue 17).

``actuators_sim``: the small UAV (Aerosonde) in manoeuvring flight with Dryden turbulence
(:func:`sim_vehicle.campaigns.actuators`): each surface stuck at its position (Lu2017 solid
jamming), stuck at zero, or with a loss of effectiveness, the engine out, and fault-free
flights, every run through MAVLink bytes and the Monitor (only the actuator family enabled:
the others do not take part). Against a plain tracking-error threshold (what an operator
watching the autopilot's errors would do): per axis the RMS of the roll error (nav_roll -
roll), the pitch error, the lateral specific force (the coordination error a stuck rudder
leaves) and the airspeed error (aspd_error: too slow), each with the same window and
confirmation as the monitor and isolated by axis.

Thresholds, of the monitor's three checks and of the baseline's four axes alike: 1.25 x the
largest value their RMS reaches on fault-free flights of *calibration* seeds (the same flights
generator, another seed; no fault, no tuning on the evaluation runs). Metrics (Wan2018 sec.
VI-B, :mod:`gcs_monitor.fdi.metrics`): FAR over fault-free runs, MDR, false isolation (another
actuator raised), wrong class (the right actuator raised with a wrong class: stuck for both
stuck kinds, loss of effectiveness for a loss or the engine out), detection delay.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gcs_monitor.config import MonitorConfig
from gcs_monitor.core.types import ChannelId
from gcs_monitor.evaluation.report import md_table, pyplot, write_csv
from gcs_monitor.evaluation.runner import run_parallel
from gcs_monitor.families.actuators.aircraft import CHANNELS, EFF_CHANNELS, ESTIMATOR
from gcs_monitor.families.actuators.config import ResidualCheckConfig
from gcs_monitor.fdi.alarms import AlarmStateMachine
from gcs_monitor.fdi.config import samples_in
from gcs_monitor.fdi.confirmation import Confirmation, ConfirmationParams
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState, FaultType
from gcs_monitor.fdi.metrics import evaluate_run, metrics_table
from gcs_monitor.fdi.residuals import ResidualRms, RmsWindowParams
from gcs_monitor.monitor import Monitor
from gcs_monitor.telemetry.frame import Frame
from sim_vehicle.actuators.faults import ACTUATORS as SIM_ACTUATORS
from sim_vehicle.campaigns import generate_set
from sim_vehicle.run import RunState, iter_run

OPEN_THRESHOLD = 1.0e9  # no residual reaches it: calibration runs never alarm or freeze
MARGIN = 1.25  # threshold = MARGIN x the worst fault-free RMS (Wan2018 sec. VI-B rule)
CHECKS = ("surface", "engine", "effectiveness")
BASELINE = "tracking_error"
BASELINE_SIGNALS = ("roll error [rad]", "pitch error [rad]", "lateral specific force [m/s^2]",
                    "airspeed error [m/s]")
CALIBRATION_SEED = 101
EVAL_SEED = 1
CHUNK = 64
EXPECTED = {"solid_jam": FaultType.STUCK, "stuck_at_zero": FaultType.STUCK,
            "loss_of_effectiveness": FaultType.LOSS_OF_EFFECTIVENESS,
            "engine_out": FaultType.LOSS_OF_EFFECTIVENESS}
CASE_LABEL = {"solid_jam": "stuck", "stuck_at_zero": "stuck at zero",
              "loss_of_effectiveness": "loss of effectiveness", "engine_out": "out"}


# ------------------------------------------------------------------------------------------------
# configuration
# ------------------------------------------------------------------------------------------------


def actuator_config(thresholds: dict[str, float] | None = None) -> MonitorConfig:
    """The monitor with only the actuator family's aircraft tier, its three checks' J_th from
    ``thresholds``
    (``surface``, ``engine``, ``effectiveness``; None: thresholds no residual reaches)."""
    th = thresholds or dict.fromkeys(CHECKS, OPEN_THRESHOLD)
    base = MonitorConfig().with_family("imu", enabled=False).with_family(
        "airdata", enabled=False).with_family("yaw_rate", enabled=False)
    fam = base.family("actuators")
    ac = fam.aircraft
    fdi = dataclasses.replace(
        ac.fdi, **{k: dataclasses.replace(getattr(ac.fdi, k), threshold=th[k]) for k in CHECKS})
    # the aircraft tier alone: the servo tier's campaign is lu2017_campaign
    return base.with_family("actuators", aircraft=dataclasses.replace(ac, fdi=fdi),
                            servo=dataclasses.replace(fam.servo, enabled=False))


# ------------------------------------------------------------------------------------------------
# the baseline: a plain threshold on the autopilot's tracking errors
# ------------------------------------------------------------------------------------------------


def tracking_errors(frame: Frame) -> tuple[float, float, float, float] | None:
    """The baseline's four signals on a frame with a new NAV_CONTROLLER_OUTPUT, SI: roll and
    pitch errors (setpoint minus attitude), lateral specific force, airspeed error (positive:
    too slow); None without setpoints."""
    nav, imu = frame.nav, frame.primary_imu
    if nav is None or frame.euler_rad is None or imu is None:
        return None
    e = frame.euler_rad
    roll = (nav.nav_roll_rad - float(e[0]) + math.pi) % (2 * math.pi) - math.pi
    return roll, nav.nav_pitch_rad - float(e[1]), float(imu.acc_frd_mps2[1]), \
        max(nav.aspd_error_mps, 0.0)


class TrackingErrorBaseline:
    """Per axis: RMS window of the tracking error, threshold, n_D-of-N confirmation and an
    ``actuator_fault`` alarm on that axis's actuator (class unknown: it cannot tell)."""

    def __init__(self, thresholds: Sequence[float], check: ResidualCheckConfig,
                 period_s: float, vehicle: int = 1) -> None:
        n = samples_in(check.window_s, period_s)
        self.th = list(thresholds)
        self.rms = [ResidualRms(RmsWindowParams(rms_window_n=n)) for _ in range(4)]
        self.conf = [Confirmation(ConfirmationParams(
            detect_n=max(1, round(check.detect_ratio * n)), eval_n=n,
            clear_ratio=check.clear_ratio, clear_n=samples_in(check.clear_s, period_s),
            latch=False)) for _ in range(4)]
        self.alarms = [AlarmStateMachine(c, AlarmKind.ACTUATOR_FAULT, BASELINE, vehicle=vehicle)
                       for c in CHANNELS]
        self.j_max = [0.0] * 4
        self.events: list[AlarmEvent] = []

    def step(self, t_us: int, errors: Sequence[float], judged: bool) -> None:
        for i, e in enumerate(errors):
            if not math.isfinite(e):
                continue
            j = self.rms[i].update(e)
            if not judged:
                continue
            self.j_max[i] = max(self.j_max[i], j)
            faulty = self.conf[i].update(j, self.th[i])
            if faulty or self.alarms[i].active:
                self.events += self.alarms[i].step(t_us, faulty, magnitude=e, rms=j,
                                                   threshold=self.th[i])


# ------------------------------------------------------------------------------------------------
# one run
# ------------------------------------------------------------------------------------------------


@dataclass
class ActuatorRun:
    """What one simulated flight gave the scores."""

    name: str
    description: str
    faults: list[tuple[ChannelId, str, float, float]]  # channel, kind, start s, amplitude
    events: list[AlarmEvent]
    baseline_events: list[AlarmEvent]
    j_max: dict[str, float]  # check -> largest J after the warm-up
    baseline_j_max: list[float]
    duration_s: float
    series: dict[str, np.ndarray] = field(default_factory=dict)


class _Capture:
    """``Monitor.on_step``: the checks' J, the baseline on every new setpoint sample, and (for
    the example figure) the actuator estimates."""

    def __init__(self, baseline: TrackingErrorBaseline, warmup_s: float,
                 keep_series: bool) -> None:
        self.baseline = baseline
        self.warmup_us = round(warmup_s * 1e6)
        self.j_max = dict.fromkeys(CHECKS, 0.0)
        self.nav_t = -1
        self.keep = keep_series
        self.rows: list[list[float]] = []

    def __call__(self, sysid: int, frame: Frame, step: Any) -> None:
        for c in step.channels:
            if c.channel.kind == "actuator":
                k = "engine" if c.channel.instance == 3 else "surface"
            elif c.channel.kind == "actuator_effectiveness":
                k = "effectiveness"
            else:
                continue
            self.j_max[k] = max(self.j_max[k], c.rms)
        nav = frame.nav
        if nav is not None and nav.t_us != self.nav_t:
            self.nav_t = nav.t_us
            err = tracking_errors(frame)
            if err is not None:
                self.baseline.step(frame.t_us, err, frame.t_us >= self.warmup_us)
        if self.keep:
            est = next((e for e in step.estimates if e.name == ESTIMATOR), None)
            if est is not None and est.t_us == frame.t_us:
                j = {c.channel: c.rms for c in step.channels}
                self.rows.append(
                    [frame.t_us * 1e-6, *est.states["command_rad"].tolist(),
                     *est.states["measured_position_rad"].tolist(),
                     *est.states["estimated_position_rad"].tolist(),
                     *est.states["effectiveness"].tolist(),
                     *(j.get(c, math.nan) for c in CHANNELS),
                     *(j.get(c, math.nan) for c in EFF_CHANNELS)])


def simulate(sc: Any, cfg: MonitorConfig, baseline_th: Sequence[float], *,
             keep_series: bool = False) -> ActuatorRun:
    """One scenario through the simulator's MAVLink bytes, the Monitor and the baseline."""
    ac = cfg.family("actuators").aircraft
    cap = _Capture(TrackingErrorBaseline(baseline_th, ac.fdi.surface, 1.0 / sc.output.nav_hz),
                   ac.model.warmup_s, keep_series)
    mon = Monitor(cfg, on_step=cap)
    rs = RunState()
    rs_truth = keep_series
    buf: list[bytes] = []
    for _, _, pkt in iter_run(sc, record_truth=rs_truth, run_state=rs):
        buf.append(pkt)
        if len(buf) >= CHUNK:
            mon.feed(b"".join(buf))
            buf = []
    mon.feed(b"".join(buf))
    mon.finish()
    faults = [(ChannelId("actuator", f.surface, SIM_ACTUATORS[f.surface]), f.kind, f.t_start_s,
               f.amplitude) for f in sc.actuator_faults]
    series: dict[str, np.ndarray] = {}
    if keep_series and cap.rows and rs.truth is not None:
        series["monitor"] = np.asarray(cap.rows)
        tr = rs.truth.arrays()
        series["truth_t"] = tr["state.t_s"]
        series["truth_pos"] = tr["state.surf_pos_rad"]
        series["truth_eff"] = tr["state.effectiveness"]
    return ActuatorRun(f"{sc.name}", sc.description, faults, list(mon.events),
                       list(cap.baseline.events), cap.j_max, list(cap.baseline.j_max),
                       sc.duration_s, series)


def _run_job(job: tuple[Any, MonitorConfig, list[float], bool]) -> ActuatorRun:
    sc, cfg, bth, keep = job
    return simulate(sc, cfg, bth, keep_series=keep)


# ------------------------------------------------------------------------------------------------
# calibration and scores
# ------------------------------------------------------------------------------------------------


def calibrate(n_runs: int, jobs: int, seed: int = CALIBRATION_SEED,
              echo: Callable[[str], None] = print) -> tuple[dict[str, float], list[float]]:
    """J_th of the monitor's checks and of the baseline's axes from fault-free flights."""
    scs = generate_set("actuators_fault_free", n_runs, seed)
    runs = run_parallel(_run_job, [(sc, actuator_config(), [OPEN_THRESHOLD] * 4, False)
                                   for sc in scs], jobs, desc="calibrate")
    worst = {k: max(r.j_max[k] for r in runs) for k in CHECKS}
    bworst = [max(r.baseline_j_max[i] for r in runs) for i in range(4)]
    th = {k: MARGIN * v for k, v in worst.items()}
    bth = [MARGIN * v for v in bworst]
    echo(f"calibration: {len(runs)} fault-free flights (actuators_fault_free, seed {seed}), "
         f"J_th = {MARGIN:g} x the worst J after the warm-up")
    for k in CHECKS:
        echo(f"  monitor {k}: worst J {worst[k]:.3g} -> J_th {th[k]:.3g}")
    for name, w, t in zip(BASELINE_SIGNALS, bworst, bth, strict=True):
        echo(f"  baseline {name}: worst RMS {w:.3g} -> threshold {t:.3g}")
    return th, bth


def _truth(run: ActuatorRun) -> dict[ChannelId, list[tuple[int, int | None]]]:
    return {ch: [(round(t0 * 1e6), None)] for ch, _, t0, _ in run.faults}


def final_class(events: Sequence[AlarmEvent], ch: ChannelId, t0_us: int) -> FaultType | None:
    """The class of the first alarm raised on ``ch`` after ``t0_us``, as its last raised or
    updated event says (None when none was raised)."""
    label = None
    started = False
    for e in events:
        if e.channel != ch or e.kind is not AlarmKind.ACTUATOR_FAULT:
            continue
        if e.state is AlarmState.RAISED and e.t_us >= t0_us:
            started = True
        if not started:
            continue
        if e.state is AlarmState.CLEARED:
            break
        label = e.fault_type
    return label


@dataclass
class Score:
    """One method on a set of runs."""

    n_fault_free: int
    n_faulty: int
    far_pct: float
    mdr_pct: float
    fir_pct: float
    wrong_class_pct: float
    delay_mean_s: float
    delay_max_s: float


def score(runs: Sequence[ActuatorRun], method: str) -> tuple[Score, list[dict[str, Any]]]:
    """Wan2018 Table IV metrics (one group: the actuators) plus the wrong-class rate, and one
    row per run."""
    outcomes = []
    rows: list[dict[str, Any]] = []
    wrong_class = 0
    for r in runs:
        ev = r.events if method == "monitor" else r.baseline_events
        o = evaluate_run(ev, _truth(r), groups=("actuator",))["actuator"]
        outcomes.append({"actuator": o})
        cls = None
        if r.faults:
            ch, kind, t0, _ = r.faults[0]
            cls = final_class(ev, ch, round(t0 * 1e6))
            if method == "monitor" and not o.missed and cls is not EXPECTED[kind]:
                wrong_class += 1
        rows.append({"run": r.name, "method": method,
                     "fault": (f"{r.faults[0][0].axis} {r.faults[0][1]}" if r.faults else "none"),
                     "false_alarm": o.false_alarm, "missed": o.missed,
                     "false_isolation": o.false_isolation, "delay_s": o.delay_s,
                     "class": cls.value if cls is not None else "-"})
    m = metrics_table(outcomes)[0]
    n_det = sum(1 for r, row in zip(runs, rows, strict=True) if r.faults and not row["missed"])
    wc = 100.0 * wrong_class / n_det if method == "monitor" and n_det else math.nan
    return Score(m.n_fault_free, m.n_faulty, m.far_pct, m.mdr_pct, m.fir_pct, wc,
                 m.delay_mean_s, m.delay_max_s), rows


def _per_case(runs: Sequence[ActuatorRun], rows: Sequence[dict[str, Any]]) -> list[list[Any]]:
    """Per (actuator, fault kind): detected / runs, false isolations, mean delay, classes."""
    cases: dict[str, list[tuple[ActuatorRun, dict[str, Any]]]] = {}
    for r, row in zip(runs, rows, strict=True):
        if r.faults:
            ch, kind, _, _ = r.faults[0]
            cases.setdefault(f"{ch.axis} {CASE_LABEL[kind]}", []).append((r, row))
    out = []
    for case in sorted(cases):
        items = cases[case]
        det = [row for _, row in items if not row["missed"]]
        d = [row["delay_s"] for row in det if math.isfinite(row["delay_s"])]
        kind = items[0][0].faults[0][1]
        right = sum(1 for row in det if row["class"] == EXPECTED[kind].value)
        out.append([case, f"{len(det)}/{len(items)}",
                    sum(row["false_isolation"] for _, row in items),
                    float(np.mean(d)) if d else math.nan,
                    f"{right}/{len(det)}" if items[0][1]["method"] == "monitor" else "-"])
    return out


# ------------------------------------------------------------------------------------------------
# figures
# ------------------------------------------------------------------------------------------------


def plot_example(run: ActuatorRun, path: Path) -> None:
    """One faulty run: command, true and estimated position of the faulty surface, the checks'
    J against their thresholds, the effectiveness against the truth."""
    s = run.series
    if "monitor" not in s or not run.faults:
        return
    m = s["monitor"]
    ch, kind, t0, _ = run.faults[0]
    i = ch.instance
    plt = pyplot()
    fig, axs = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
    t = m[:, 0]
    deg = 180.0 / math.pi
    if i < 3:
        axs[0].plot(t, m[:, 1 + i] * deg, lw=0.8, label="command (SERVO_OUTPUT_RAW)")
        axs[0].plot(s["truth_t"], s["truth_pos"][:, i] * deg, "k", lw=1.5, label="true position")
        axs[0].plot(t, m[:, 7 + i] * deg, lw=0.6, alpha=0.7, label="estimated position")
        axs[0].set_ylabel(f"{ch.axis} [deg]")
    axs[1].plot(t, m[:, 14 + i], label=f"residual check J ({ch.axis})")
    axs[1].plot(t, m[:, 18 + i], label="effectiveness check J")
    axs[1].set_yscale("log")
    axs[1].set_ylabel("J (normalised)")
    axs[2].plot(t, m[:, 10 + i], label="estimated effectiveness (kappa)")
    axs[2].plot(s["truth_t"], s["truth_eff"][:, i], "k", label="true effectiveness")
    axs[2].set_ylim(-0.5, 1.5)
    axs[2].set_xlabel("t [s]")
    for a in axs:
        a.axvline(t0, color="r", lw=0.8)
        a.grid(True, alpha=0.3)
        a.legend(fontsize=7, loc="upper left")
    for e in run.events:
        if e.state is AlarmState.RAISED and e.kind is AlarmKind.ACTUATOR_FAULT:
            axs[1].axvline(e.t_us * 1e-6, color="g", ls="--", lw=0.8)
    axs[0].set_title(f"{run.name}: {ch.axis} {CASE_LABEL[kind]} at {t0:g} s")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_delays(per_case: dict[str, list[list[Any]]], path: Path) -> None:
    """Mean detection delay per fault case, monitor against the baseline."""
    plt = pyplot()
    cases = [r[0] for r in per_case["monitor"]]
    fig, ax = plt.subplots(figsize=(10, 4))
    x = np.arange(len(cases))
    for k, (method, rows) in enumerate(per_case.items()):
        d = {r[0]: r[3] for r in rows}
        ax.bar(x + 0.4 * k - 0.2, [d.get(c, math.nan) for c in cases], 0.4, label=method)
    ax.set_xticks(x, cases, rotation=30, ha="right", fontsize=8)
    ax.set_ylabel("mean detection delay [s]")
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


# ------------------------------------------------------------------------------------------------
# the experiment
# ------------------------------------------------------------------------------------------------


def actuators_sim(out_dir: Path, jobs: int = 1, quick: bool = False, *,
                  n_runs: int | None = None, n_calibration: int | None = None,
                  img_dir: Path | None = None) -> str:
    """Aircraft tier on a seeded campaign (all surfaces and the engine, manoeuvring flight in
    turbulence) against a plain tracking-error threshold; thresholds from fault-free flights
    of calibration seeds. ``quick``: 14 runs, 6 calibration flights."""
    out_dir = Path(out_dir)
    lines: list[str] = []
    n_cal = n_calibration or (6 if quick else 20)
    n = n_runs or (14 if quick else 60)
    th, bth = calibrate(n_cal, jobs, echo=lines.append)
    cfg = actuator_config(th)
    scs = generate_set("actuators", n, EVAL_SEED)
    example = next(i for i, sc in enumerate(scs) if sc.actuator_faults)
    runs = run_parallel(_run_job, [(sc, cfg, bth, i == example) for i, sc in enumerate(scs)],
                        jobs, desc="actuators")
    header = ["method", "fault-free runs", "faulty runs", "FAR [%]", "MDR [%]",
              "false isolation [%]", "wrong class [%]", "delay mean [s]", "delay max [s]"]
    table = []
    per_case: dict[str, list[list[Any]]] = {}
    all_rows = []
    for method in ("monitor", BASELINE):
        sc_, rows = score(runs, method)
        all_rows += rows
        label = "aircraft tier (RLS per axis)" if method == "monitor" else \
            "tracking-error threshold (baseline)"
        table.append([label, sc_.n_fault_free, sc_.n_faulty, sc_.far_pct, sc_.mdr_pct,
                      sc_.fir_pct, sc_.wrong_class_pct, sc_.delay_mean_s, sc_.delay_max_s])
        per_case[method] = _per_case(runs, rows)
    write_csv(out_dir / "actuators_sim_runs.csv", list(all_rows[0]),
              [list(r.values()) for r in all_rows])
    img = Path(img_dir) if img_dir is not None else out_dir
    img.mkdir(parents=True, exist_ok=True)
    plot_example(runs[example], img / "actuators_sim_example.png")
    plot_delays(per_case, img / "actuators_sim_delays.png")
    case_header = ["fault", "detected", "false isolations", "mean delay [s]", "right class"]
    return ("Calibration:\n\n```\n" + "\n".join(lines) + "\n```\n\n"
            f"Evaluation: {n} runs of `actuators` (seed {EVAL_SEED}):\n\n"
            + md_table(header, table) + "\n\nPer fault case, aircraft tier:\n\n"
            + md_table(case_header, per_case["monitor"]) + "\n\nPer fault case, baseline:\n\n"
            + md_table(case_header, per_case[BASELINE]) + "\n")


def experiments() -> dict[str, Callable[[Path, int, bool], str]]:
    return {"actuators_sim": actuators_sim}
