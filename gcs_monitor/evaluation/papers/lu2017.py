"""Lu2017 experiments: the servo level of the actuator family on simulated hydraulic servos.

* ``lu2017`` -- Lu2017's five scenarios and the fault-free case (presets ``lu2017_s0`` ..
  ``lu2017_s5``: faults on the elevator at t = 12 s during a repeated 3-2-1-1 command): state and
  fault estimation RMSE before and after the fault, the class the alarm names, detection and
  classification delays, and figures in the layout of Lu2017 Figs. 2-7;
* ``lu2017_calibration`` -- the detection thresholds of the servo tier and of the baseline from
  fault-free runs of the servo campaign (calibration seed);
* ``lu2017_campaign`` -- the seeded campaign (:func:`sim_vehicle.actuators.campaign.
  servo_campaign`: every surface, the five cases, turbulence, five manoeuvres; evaluation
  seed): false-alarm, missed-detection and false-isolation rates (wrong surface or wrong case)
  and delays of the servo tier, against a fixed threshold on command minus surface position.

Every run goes simulator -> MAVLink bytes -> :class:`~gcs_monitor.monitor.Monitor` with the
:class:`~gcs_monitor.families.actuators.servo.ServoTier` as its one family (the actuator
family's wrapper is built on another branch); the truth comes from the simulator's servo bank
(plant and reference states at every step) and from a fault-free copy of it driven by the same
commands (the nominal servo the output faults are measured against, Lu2017 sec. V).

Truth of the estimates (Lu2017 defines the faults, we define what they are compared with):

* the IOTSEKF's state is the servo's physical state, its input fault the valve command applied
  minus the NDI command of the true state (a liquid OFC: the sinusoid; a solid OFC: the
  sinusoid minus the loop's ignored command);
* the RTS-EKF's state is the *nominal* servo's (the fault-free copy), its output faults the
  rod sensor and the surface position minus the nominal rod (Lu2017's output fault
  ``y = x1 + f^o`` with x the unfaulted servo).

Commands and measured tables: docs/results.md, "Actuator family: Lu2017 servo level".
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from gcs_monitor.evaluation.report import fmt_fixed, md_table, pyplot, write_csv
from gcs_monitor.evaluation.runner import run_parallel
from gcs_monitor.evaluation.runs import feed_packets
from gcs_monitor.families.actuators.servo import (
    SURFACE_KIND,
    SURFACES,
    ServoTier,
    ServoTierConfig,
    axis_of_case,
    case_of,
)
from gcs_monitor.families.actuators.servo_classify import CASE_LABELS
from gcs_monitor.families.actuators.servo_filters import (
    N_OUT,
    O_F_IN,
    O_F_ROD,
    O_F_SURF,
    O_JIT,
    O_N1,
    O_N3,
    O_Q_COM,
    O_SF_D,
    O_SF_ROD,
    O_X1,
    O_X3,
    O_Y_ROD,
)
from gcs_monitor.families.base import FamilyContext
from gcs_monitor.fdi.config import ChannelSetConfig, window_samples
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState
from gcs_monitor.models.servo import ndi_control, reference_model_derivative
from gcs_monitor.monitor import Monitor
from sim_vehicle.actuators.campaign import servo_campaign
from sim_vehicle.actuators.faults import SERVO_FAULT_KINDS, apply_to_valve, fault_effect
from sim_vehicle.actuators.servo_bank import ServoBank
from sim_vehicle.run import iter_run, make_simulation
from sim_vehicle.scenario import Scenario, load_scenario

LU2017_PRESETS = tuple(f"lu2017_s{i}" for i in range(6))
SCENARIO_LABEL = {0: "fault-free", 1: "liquid OFC", 2: "solid OFC", 3: "liquid jam",
                  4: "solid jam", 5: "runaway"}
T_FAULT_S = 12.0  # Lu2017 Table 1
BASELINE = "cmd_minus_pos"
CAL_SEED = 1  # calibration runs (thresholds) and evaluation runs never share a seed
EVAL_SEED = 2
# figure-of-merit windows: the filters' warm-up is over by PRE_FROM_S, and the fault estimates
# are compared with the truth from POST_FROM_S after the fault's start
PRE_FROM_S = 3.0
POST_DELAY_S = 0.5


# ------------------------------------------------------------------------------------------------
# one run
# ------------------------------------------------------------------------------------------------


@dataclass
class ServoRun:
    """What one simulated run gives the scores (arrays per SURF sample, surfaces on axis 1).

    t_s : (N,) SURF sample instants (s)
    rows : (N, 3, N_OUT) the tier's filter outputs (``servo_filters.O_*``)
    x_true : (N, 3, 3) the servo's physical state [q, q_dot, dP/P_s]
    x_nom : (N, 3, 3) the nominal (fault-free copy's) state
    f_in_true : (N, 3) valve command applied minus the NDI command of the true state
    rod_true, surf_true : (N, 3) rod sensor (bias included, no noise) and surface position in m of
        rod (noise-free)
    cmd_minus_pos : (N, 3) surface command minus measured surface position (rad), the baseline
    events : every alarm event of the tier
    faults : the scenario's actuator faults as (surface, kind, t_start_s)
    """

    name: str
    t_s: np.ndarray
    rows: np.ndarray
    x_true: np.ndarray
    x_nom: np.ndarray
    f_in_true: np.ndarray
    rod_true: np.ndarray
    surf_true: np.ndarray
    cmd_minus_pos: np.ndarray
    events: list[AlarmEvent]
    faults: list[tuple[int, str, float]]
    period_s: float = math.nan
    extra: dict[str, Any] = field(default_factory=dict)


class _Truth:
    """Per simulation step: the servo bank's states, a fault-free copy driven by the same
    commands, and the input fault actually applied to each valve."""

    def __init__(self, sc: Scenario) -> None:
        self.sc = sc
        self.sim: Any = None
        self.nominal: ServoBank | None = None
        self.t_prev_s = 0.0
        self.at: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}

    def factory(self, sc: Scenario) -> Any:
        sim: Any = make_simulation(sc)
        sv = sim.servos
        self.sim = sim
        self.nominal = ServoBank(sv.geo, tuple(sv.deflection_rad(i) for i in range(3)),
                                 params=sv.p, loop=sv.lp)
        return sim

    def step(self, t_us: int) -> None:
        sv = self.sim.servos
        nom = self.nominal
        assert nom is not None
        t_s = t_us * 1e-6
        if t_us > 0:
            nom.step(self.t_prev_s, t_s - self.t_prev_s, tuple(sv.cmd_rad))
        self.t_prev_s = t_s
        f_in = np.zeros(3)
        geo = sv.geo
        for k in range(3):
            eff = fault_effect(sv.faults, k, t_s)
            if eff.jammed or (eff.u_replace is None and eff.u_add == 0.0
                              and eff.runaway_dir == 0.0):
                continue
            x = sv.x[k]
            q_com = max(-geo.rod_stroke_m, min(geo.rod_stroke_m, sv.cmd_rad[k] /
                                               geo.rod_gain_radpm))
            _, _, rddd = reference_model_derivative(x[3], x[4], x[5], q_com, sv.lp)
            u = ndi_control(x[0] + eff.sensor_bias_m, x[1], x[2], (x[3], x[4], x[5], rddd),
                            sv.p, sv.lp)
            f_in[k] = apply_to_valve(u, eff) - u
        self.at[t_us] = (sv.x[:, :3].copy(), nom.x[:, :3].copy(), f_in)


def simulate_servo(sc: Scenario, cfg: ServoTierConfig | None = None) -> ServoRun:
    """Run ``sc`` through the MAVLink path into a monitor whose one family is the servo tier;
    returns the per-sample record (see :class:`ServoRun`)."""
    cfg = cfg or ServoTierConfig()
    truth = _Truth(sc)
    tiers: list[ServoTier] = []
    t_list: list[int] = []
    rows: list[np.ndarray] = []
    cmp_: list[np.ndarray] = []

    def families(ctx: FamilyContext) -> list[Any]:
        tier = ServoTier(cfg, ctx)
        tiers.append(tier)
        return [tier]

    def on_step(sysid: int, frame: Any, out: Any) -> None:
        if not any(e.name == "servo_iotsekf" for e in out.estimates):
            return
        t_list.append(frame.t_us - round(frame.surf_age_s * 1e6))
        rows.append(tiers[-1]._rows.copy())
        cmp_.append(np.asarray(frame.surf_cmd_rad) - np.asarray(frame.surf_pos_rad))

    mon = Monitor(families_for=families, on_step=on_step)
    feed_packets(mon, (pkt for _, _, pkt in iter_run(sc, simulation_factory=truth.factory,
                                                 on_step=truth.step)))
    t_us = np.array(t_list, dtype=np.int64)
    gain = truth.sim.servos.geo.rod_gain_radpm
    xt = np.array([truth.at[int(t)][0] for t in t_us])
    xn = np.array([truth.at[int(t)][1] for t in t_us])
    fin = np.array([truth.at[int(t)][2] for t in t_us])
    rod = np.empty((t_us.size, 3))
    for i, t in enumerate(t_us):
        for k in range(3):
            eff = fault_effect(truth.sim.servos.faults, k, t * 1e-6)
            rod[i, k] = xt[i, k, 0] + eff.sensor_bias_m
    return ServoRun(sc.name, t_us * 1e-6, np.array(rows).reshape(-1, 3, N_OUT), xt, xn, fin, rod,
                    xt[:, :, 0].copy(), np.array(cmp_).reshape(-1, 3), list(mon.events),
                    [(f.surface, f.kind, f.t_start_s) for f in sc.actuator_faults],
                    period_s=tiers[-1].period_s if tiers else math.nan,
                    extra={"gain": gain})


# ------------------------------------------------------------------------------------------------
# scores of one run
# ------------------------------------------------------------------------------------------------


def _rmse(e: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(e)))) if e.size else math.nan


def tier_events(run: ServoRun) -> list[AlarmEvent]:
    return [e for e in run.events if e.kind is AlarmKind.ACTUATOR_FAULT
            and e.channel.kind == SURFACE_KIND]


@dataclass(frozen=True, slots=True)
class Detection:
    """The tier's answer for one faulty surface: first raise after the fault's start, the case
    named then and finally, and when the right case was first named."""

    detected: bool
    delay_s: float
    first_case: str
    final_case: str
    class_delay_s: float
    wrong_surface: bool
    false_alarm_before: bool


def detection_of(events: Sequence[AlarmEvent], surface: int | None, kind: str | None,
                 t0_s: float) -> Detection:
    """Score the tier's events for a fault ``kind`` on ``surface`` from ``t0_s`` (None, None:
    a fault-free run; every raise is then a false alarm)."""
    raised = [e for e in events if e.state is AlarmState.RAISED]
    before = any(e.t_us * 1e-6 < t0_s for e in raised) if surface is not None else bool(raised)
    if surface is None:
        return Detection(False, math.nan, "", "", math.nan, False, before)
    mine = [e for e in events if e.channel.instance == surface and e.t_us * 1e-6 >= t0_s]
    wrong = any(e.channel.instance != surface and e.t_us * 1e-6 >= t0_s for e in raised)
    first = next((e for e in mine if e.state is AlarmState.RAISED), None)
    if first is None:
        return Detection(False, math.nan, "", "", math.nan, wrong, before)
    live = [e for e in mine if e.state is not AlarmState.CLEARED]
    final = case_of(live[-1]) if live else case_of(first)
    right = next((e for e in live if case_of(e) == kind
                  and e.channel.axis == axis_of_case(kind)), None)
    return Detection(True, first.t_us * 1e-6 - t0_s, case_of(first), final,
                     right.t_us * 1e-6 - t0_s if right is not None else math.nan, wrong, before)


def baseline_events(run: ServoRun, threshold_rad: float, ch: ChannelSetConfig) -> list[
        tuple[int, float]]:
    """The baseline's raises: (surface, time) when the RMS of command minus surface position
    over the same window as the tier's exceeds ``threshold_rad`` for the same share of it."""
    n = window_samples(ch, run.period_s)
    need = max(1, round(ch.detect_ratio * n))
    out: list[tuple[int, float]] = []
    for k in range(3):
        r = run.cmd_minus_pos[:, k]
        c = np.concatenate([[0.0], np.cumsum(r * r)])
        J = np.sqrt(np.maximum(c[n:] - c[:-n], 0.0) / n)
        over = J > threshold_rad
        cnt = np.convolve(over.astype(int), np.ones(n, dtype=int))[:over.size]
        hit = np.flatnonzero((cnt >= need) & (run.t_s[n - 1:] >= PRE_FROM_S))
        if hit.size:
            out.append((k, float(run.t_s[n - 1 + hit[0]])))
    return out


# ------------------------------------------------------------------------------------------------
# lu2017: the paper's scenarios
# ------------------------------------------------------------------------------------------------


def _lu_run(job: tuple[str, bool]) -> ServoRun:
    name, blend = job
    cfg = ServoTierConfig()
    if not blend:  # Lu2017 eq. 17 as printed (papers-notes)
        cfg = replace(cfg, filters=replace(cfg.filters, bias_free_from_blend=False))
    return simulate_servo(load_scenario(name), cfg)


def lu2017(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """Lu2017's five scenarios and the fault-free case (presets lu2017_s0..s5, elevator, t = 12
    s, 3-2-1-1 command): state and fault estimation RMSE before and after the fault, the named
    case, detection and classification delays, figures like Lu2017 Figs. 2-7.

    ``quick`` changes nothing (six 30 s runs).
    """
    out_dir = Path(out_dir)
    jobs_ = [(p, True) for p in LU2017_PRESETS] + [("lu2017_s2", False)]
    runs = run_parallel(_lu_run, jobs_, jobs, desc="lu2017")
    printed = runs.pop()
    header = ["scenario", "filter", "q pre [mm]", "q post [mm]", "q_dot pre [mm/s]",
              "q_dot post [mm/s]", "dP/Ps pre", "dP/Ps post", "fault pre", "fault post",
              "fault unit", "case named (first -> final)", "detection delay [s]",
              "class delay [s]"]
    rows: list[list[Any]] = []
    for i, run in enumerate(runs):
        scen = i
        k = 1  # the elevator
        t = run.t_s
        pre = (t >= PRE_FROM_S) & (t < T_FAULT_S)
        post = t >= T_FAULT_S + POST_DELAY_S
        if scen <= 2:
            filt = "IOTSEKF"
            ex = run.rows[:, k, O_X1:O_X3 + 1] - run.x_true[:, k]
            ef = run.rows[:, k, O_F_IN] - run.f_in_true[:, k]
            unit = "valve"
        else:
            filt = "RTS-EKF"
            ex = run.rows[:, k, O_N1:O_N3 + 1] - run.x_nom[:, k]
            ef = run.rows[:, k, O_F_ROD] - (run.rod_true[:, k] - run.x_nom[:, k, 0])
            unit = "mm (rod)"
        sc_ = 1e3 if scen > 2 else 1.0
        kind = None if scen == 0 else SERVO_FAULT_KINDS[scen - 1]
        det = detection_of(tier_events(run), None if kind is None else k, kind, T_FAULT_S)
        if kind is None:
            named = "none (no alarm)" if not det.false_alarm_before else "false alarm"
            dd = cd = "-"
        else:
            named = (f"{CASE_LABELS.get(det.first_case, det.first_case)} -> "
                     f"{CASE_LABELS.get(det.final_case, det.final_case)}"
                     if det.detected else "missed")
            dd, cd = fmt_fixed(det.delay_s), fmt_fixed(det.class_delay_s)
        rows.append([f"S{scen} {SCENARIO_LABEL[scen]}", filt,
                     1e3 * _rmse(ex[pre, 0]), 1e3 * _rmse(ex[post, 0]),
                     1e3 * _rmse(ex[pre, 1]), 1e3 * _rmse(ex[post, 1]),
                     _rmse(ex[pre, 2]), _rmse(ex[post, 2]),
                     sc_ * _rmse(ef[pre]), sc_ * _rmse(ef[post]), unit, named, dd, cd])
        _figure(run, scen, out_dir / f"lu2017_fig_s{scen}.png")
    write_csv(out_dir / "lu2017.csv", header, rows)
    # the IOTSEKF's bias-free prediction: eq. 17 as printed against ours, scenario 2
    abl = []
    for label, run in (("eq. 17 as printed (f^i = 0)", printed),
                       ("from the blended prediction (ours)", runs[2])):
        post = run.t_s >= T_FAULT_S + POST_DELAY_S
        ex = run.rows[post, 1, O_X1:O_X3 + 1] - run.x_true[post, 1]
        ef = run.rows[post, 1, O_F_IN] - run.f_in_true[post, 1]
        abl.append([label, 1e3 * _rmse(ex[:, 0]), 1e3 * _rmse(ex[:, 1]), _rmse(ex[:, 2]),
                    _rmse(ef)])
    h_abl = ["S2 solid OFC, IOTSEKF bias-free prediction", "q [mm]", "q_dot [mm/s]",
             "dP/Ps", "f^i [valve]"]
    events = []
    for i, run in enumerate(runs):
        for e in tier_events(run):
            events.append([f"S{i}", f"{e.t_us * 1e-6:.2f}", e.state.value, str(e.channel),
                           e.fault_type.value, f"{e.magnitude:.4g}", e.message])
    write_csv(out_dir / "lu2017_events.csv",
              ["scenario", "t [s]", "state", "channel", "fault type", "magnitude", "message"],
              events)
    return (f"RMSE of the estimates against the truth (module docstring) before the fault "
            f"({PRE_FROM_S:g}-{T_FAULT_S:g} s) and from {POST_DELAY_S:g} s after it to the end "
            f"(30 s); the elevator; IOTSEKF states against the physical servo, RTS-EKF states "
            f"against the nominal servo; the case the alarm names when raised and at the end, "
            f"detection delay (first actuator_fault raised on the elevator) and classification "
            f"delay (first event naming the right case on the right channel):\n\n"
            + md_table(header, rows) + "\n\nAlarm events: lu2017_events.csv; figures "
            "lu2017_fig_s0.png .. lu2017_fig_s5.png (Lu2017 Figs. 2-7 layout).\n\n"
            "RMSE after the fault, scenario 2, with Lu2017 eq. 17 as printed and with the "
            "bias-free state predicted from the blended one (papers-notes):\n\n"
            + md_table(h_abl, abl) + "\n")


def _figure(run: ServoRun, scen: int, path: Path) -> None:
    """Lu2017 Figs. 2-7 layout: (a) command and response, (b)-(d) true and estimated q, q_dot,
    dP/Ps, (e) fault estimate (and truth), (f) its error."""
    plt = pyplot()
    k = 1
    t = run.t_s
    iots = scen <= 2
    fig, ax = plt.subplots(3, 2, figsize=(11, 9), sharex=True)
    ax = ax.ravel()
    ax[0].plot(t, 1e3 * run.rows[:, k, O_Q_COM], label="rod command")
    ax[0].plot(t, 1e3 * run.x_true[:, k, 0], label="rod (true)")
    ax[0].plot(t, 1e3 * run.rows[:, k, O_Y_ROD], lw=0.6, alpha=0.6, label="rod sensor")
    ax[0].set_ylabel("q [mm]")
    ax[0].set_title("(a) command and response")
    ax[0].legend(fontsize=7)
    est = run.rows[:, k, O_X1:O_X3 + 1] if iots else run.rows[:, k, O_N1:O_N3 + 1]
    tru = run.x_true[:, k] if iots else run.x_nom[:, k]
    what = "" if iots else " (nominal servo)"
    for j, (lab, sc_) in enumerate((("q [mm]", 1e3), ("q_dot [mm/s]", 1e3), ("dP/Ps [-]", 1.0))):
        a = ax[1 + j]
        a.plot(t, sc_ * tru[:, j], label="true" + what)
        a.plot(t, sc_ * est[:, j], "--", label="IOTSEKF" if iots else "RTS-EKF")
        a.set_ylabel(lab)
        a.set_title(f"({'bcd'[j]}) true and estimated {lab.split(' ')[0]}")
        a.legend(fontsize=7)
    if iots:
        f_est, f_tru, unit = run.rows[:, k, O_F_IN], run.f_in_true[:, k], "f^i [valve]"
        sc_ = 1.0
    else:
        f_est = run.rows[:, k, O_F_ROD]
        f_tru = run.rod_true[:, k] - run.x_nom[:, k, 0]
        unit, sc_ = "f^o (rod sensor) [mm]", 1e3
        ax[4].plot(t, sc_ * run.rows[:, k, O_F_SURF], lw=0.6, alpha=0.7,
                   label="f^o (surface sensor)")
    ax[4].plot(t, sc_ * f_est, label="estimated")
    ax[4].plot(t, sc_ * f_tru, "--", label="true")
    ax[4].set_ylabel(unit)
    ax[4].set_title("(e) fault estimate")
    ax[4].legend(fontsize=7)
    ax[5].plot(t, sc_ * (f_est - f_tru))
    ax[5].set_ylabel("error")
    ax[5].set_title("(f) fault estimation error")
    for a in ax:
        a.axvline(T_FAULT_S, color="k", lw=0.5, ls=":")
        a.grid(alpha=0.3)
    for a in ax[4:]:
        a.set_xlabel("t [s]")
    fig.suptitle(f"Lu2017 scenario {scen}: {SCENARIO_LABEL[scen]} (elevator, "
                 f"{'IOTSEKF' if iots else 'RTS-EKF'})")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)


# ------------------------------------------------------------------------------------------------
# campaign: calibration and evaluation
# ------------------------------------------------------------------------------------------------


def _windowed_rms(v: np.ndarray, n: int) -> np.ndarray:
    """RMS over the trailing ``n`` samples (ResidualRms's value once its window is full)."""
    c = np.concatenate([[0.0], np.cumsum(v * v)])
    out: np.ndarray = np.sqrt(np.maximum(c[n:] - c[:-n], 0.0) / n)
    return out


def detector_series(run: ServoRun, cfg: ServoTierConfig | None = None
                    ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """Per surface, after the filters' warm-up: the input and output detectors' J, the
    baseline's RMS of command minus position, and the unseen-command spread the tier schedules
    its thresholds on (m), aligned on the detectors' windows."""
    cfg = cfg or ServoTierConfig()
    n = window_samples(cfg.fdi.input, run.period_s)
    keep = run.t_s[n - 1:] >= PRE_FROM_S
    out = []
    for k in range(3):
        r = run.rows[:, k]
        z_rod = r[:, O_F_ROD] / r[:, O_SF_ROD]
        z_d = (r[:, O_F_ROD] - r[:, O_F_SURF]) / r[:, O_SF_D]
        v_out = np.where(np.abs(z_rod) >= np.abs(z_d), z_rod, z_d)
        out.append((_windowed_rms(r[:, O_F_IN], n)[keep], _windowed_rms(v_out, n)[keep],
                    _windowed_rms(run.cmd_minus_pos[:, k], n)[keep],
                    r[n - 1:, O_JIT][keep]))
    return out


def _fault_free_runs(n: int, seed: int) -> list[Scenario]:
    """``n`` fault-free runs of the servo campaign's mix (manoeuvres, turbulence)."""
    out: list[Scenario] = []
    i = 0
    while len(out) < n:
        for sc in servo_campaign(max(8, 4 * n), seed + 1000 * i):
            if not sc.actuator_faults and len(out) < n:
                out.append(sc)
        i += 1
    return out


def _sim_run(sc: Scenario) -> ServoRun:
    return simulate_servo(sc)


def calibrate(runs: Sequence[ServoRun], margin: float = 1.5, smooth_m: float = 1.0e-3
              ) -> dict[str, float]:
    """Thresholds from fault-free runs (Wan2018 sec. VI-B's rule, as the IMU family's):

    * input: ``J_th = th0 + slope * spread`` (the tier's scheduling on the unseen-command
      spread) with ``th0`` = ``margin`` x the worst fault-free J while the spread is below
      ``smooth_m`` and ``slope`` the smallest that keeps ``margin`` x every fault-free J below
      the line;
    * output: ``margin`` x its worst fault-free J (already in sigmas of the RTS-EKF's P^f, which
      carries the command uncertainty: no scheduling);
    * baseline: ``margin`` x its worst fault-free RMS of command minus position.
    """
    series = [s for r in runs for s in detector_series(r)]
    jit = np.concatenate([s[3] for s in series])
    calm, rough = jit < smooth_m, jit >= smooth_m
    res: dict[str, float] = {}
    J = np.concatenate([s[0] for s in series])
    th0 = margin * float(J[calm].max()) if calm.any() else margin * float(J.max())
    slope = float(np.max((margin * J[rough] - th0) / jit[rough])) if rough.any() else 0.0
    res.update(input=th0, input_per_jitter=max(slope, 0.0), worst_input=float(J.max()),
               worst_input_calm=float(J[calm].max()) if calm.any() else math.nan)
    J = np.concatenate([s[1] for s in series])
    res.update(output=margin * float(J.max()), output_per_jitter=0.0,
               worst_output=float(J.max()),
               worst_output_calm=float(J[calm].max()) if calm.any() else math.nan)
    jb = max(float(s[2].max()) for s in series)
    res["baseline_rad"] = margin * jb
    res["worst_baseline_rad"] = jb
    return res


def lu2017_calibration(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """Detection thresholds of the servo tier (J_th and its growth with the unseen-command
    spread) and of the command-minus-position baseline, from fault-free runs of the servo
    campaign's mix (calibration seed) and the Lu2017 fault-free preset. ``quick``: 6 runs, else
    20."""
    n = 6 if quick else 20
    scs = _fault_free_runs(n, CAL_SEED) + [load_scenario("lu2017_s0")]
    runs = run_parallel(_sim_run, scs, jobs, desc="lu2017_calibration")
    th = calibrate(runs)
    rows = [["input (f^i)", "valve", th["worst_input_calm"], th["worst_input"], th["input"],
             f"{th['input_per_jitter']:.3g} valve/m"],
            ["output (f^o or rod - surface, normalised)", "sigma", th["worst_output_calm"],
             th["worst_output"], th["output"], f"{th['output_per_jitter']:.3g} sigma/m"],
            ["baseline: command - position", "deg", math.nan,
             math.degrees(th["worst_baseline_rad"]), math.degrees(th["baseline_rad"]), "-"]]
    header = ["detector", "unit", "worst J, spread < 1 mm", "worst J", "J_th (1.5x)",
              "growth per m of spread"]
    write_csv(Path(out_dir) / "lu2017_calibration.csv", header, rows)
    return (f"{len(runs)} fault-free runs (servo campaign mix, seed {CAL_SEED}, and "
            f"lu2017_s0); J over the detectors' {ServoTierConfig().fdi.input.window_s:g} s "
            "windows after the filters' warm-up; the unseen-command spread is the filters' "
            "estimate of the command samples the 50 Hz stream did not carry (half the RMS of "
            "the rod command's second differences, the two largest left out, over "
            f"{ServoTierConfig().filters.command_jitter_window_s:g} s):\n\n"
            + md_table(header, rows) + "\n")


def lu2017_campaign(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """Seeded servo campaign (every surface, Lu2017's five cases, turbulence; evaluation seed):
    FAR, MDR, false isolation (wrong surface or wrong case) and delays of the servo tier with its
    default thresholds, against a fixed threshold on command minus surface position (its
    threshold calibrated like the tier's, by ``lu2017_calibration``'s rule on the same
    calibration runs). ``quick``: 20 runs, else 60."""
    out_dir = Path(out_dir)
    n = 20 if quick else 60
    scs = servo_campaign(n, EVAL_SEED)
    cal = _fault_free_runs(6 if quick else 20, CAL_SEED) + [load_scenario("lu2017_s0")]
    runs = run_parallel(_sim_run, list(scs) + cal, jobs, desc="lu2017_campaign")
    ev_runs, cal_runs = runs[:len(scs)], runs[len(scs):]
    th_b = calibrate(cal_runs)["baseline_rad"]  # the tier runs with its defaults
    ch = ServoTierConfig().fdi.input
    per_run: list[list[Any]] = []
    tier_f: list[tuple[Detection, str]] = []
    tier_ff: list[Detection] = []
    base_f: list[Detection] = []
    base_ff: list[Detection] = []
    for sc, run in zip(scs, ev_runs, strict=True):
        evs = tier_events(run)
        braised = baseline_events(run, th_b, ch)
        if sc.actuator_faults:
            f = sc.actuator_faults[0]
            d = detection_of(evs, f.surface, f.kind, f.t_start_s)
            tier_f.append((d, f.kind))
            hit = [t for s, t in braised if s == f.surface and t >= f.t_start_s]
            base_f.append(Detection(bool(hit), (min(hit) - f.t_start_s) if hit else math.nan,
                                    "", "", math.nan,
                                    any(s != f.surface and t >= f.t_start_s
                                        for s, t in braised), False))
            per_run.append([sc.name, SURFACES[f.surface], f.kind, f"{f.t_start_s:g}",
                            _fault_params(f), d.detected, fmt_fixed(d.delay_s),
                            d.first_case, d.final_case, fmt_fixed(d.class_delay_s),
                            d.wrong_surface, base_f[-1].detected,
                            fmt_fixed(base_f[-1].delay_s), base_f[-1].wrong_surface])
        else:
            d = detection_of(evs, None, None, 0.0)
            tier_ff.append(d)
            base_ff.append(Detection(False, math.nan, "", "", math.nan, False, bool(braised)))
            per_run.append([sc.name, "-", "fault-free", "-", "-", d.false_alarm_before, "-", "",
                            "", "-", False, bool(braised), "-", False])
    write_csv(out_dir / "lu2017_campaign_runs.csv",
              ["run", "surface", "case", "t0 [s]", "parameters", "tier detected",
               "tier delay [s]", "case first", "case final", "class delay [s]",
               "tier wrong surface", "baseline detected", "baseline delay [s]",
               "baseline wrong surface"], per_run)
    header = ["method", "fault-free runs", "faulty runs", "FAR [%]", "MDR [%]",
              "false isolation [%]", "of which wrong surface [%]", "wrong case [%]",
              "DetD max [s]", "DetD mean [s]", "class delay mean [s]"]
    rows = [_metrics("servo tier (IOTSEKF + RTS-EKF)", tier_f, tier_ff, True),
            _metrics(f"baseline: command - position > {math.degrees(th_b):.2f} deg",
                     [(d, "") for d in base_f], base_ff, False)]
    kinds_rows = []
    base_kinds = [k for _, k in tier_f]
    for kind in SERVO_FAULT_KINDS:
        r = _metrics(f"tier: {CASE_LABELS[kind]}", [x for x in tier_f if x[1] == kind], [], True)
        kinds_rows.append([r[0], r[2]] + r[4:])
        r = _metrics(f"baseline: {CASE_LABELS[kind]}",
                     [(d, k) for d, k in zip(base_f, base_kinds, strict=True) if k == kind], [],
                     False)
        kinds_rows.append([r[0], r[2]] + r[4:])
    write_csv(out_dir / "lu2017_campaign.csv", header, rows)
    h2 = [header[0], header[2]] + header[4:]
    return (f"{len(scs)} runs of servo_campaign (seed {EVAL_SEED}; {len(tier_ff)} fault-free, "
            f"{len(tier_f)} faulty), 40 s each; a detection is the first actuator_fault raised "
            "on the faulty surface after the fault's start; false isolation: an alarm on another "
            "surface, or (tier) the case named at the end differs from the injected one; the "
            "baseline names no case. Baseline threshold: 1.5x its worst fault-free RMS over "
            f"{len(cal_runs)} calibration runs (seed {CAL_SEED}).\n\n"
            + md_table(header, rows) + "\n\nPer case:\n\n" + md_table(h2, kinds_rows)
            + "\n\nPer run: lu2017_campaign_runs.csv.\n")


def _fault_params(f: Any) -> str:
    if f.kind.endswith("_ofc"):
        return f"amplitude {f.amplitude:g}, {f.frequency_hz:g} Hz"
    if f.kind == "liquid_jam":
        return f"bias {1e3 * f.amplitude:+.1f} mm"
    if f.kind == "runaway":
        return f"direction {f.amplitude:+g}"
    return ""


def _metrics(label: str, faulty: Sequence[tuple[Detection, str]], free: Sequence[Detection],
             with_class: bool) -> list[Any]:
    n_f, n_ff = len(faulty), len(free)

    def pct(k: int, n: int) -> float:
        return 100.0 * k / n if n else math.nan

    far = pct(sum(d.false_alarm_before for d in free), n_ff)
    mdr = pct(sum(not d.detected for d, _ in faulty), n_f)
    wrong_surf = sum(d.wrong_surface for d, _ in faulty)
    wrong_case = sum(d.detected and d.final_case != k for d, k in faulty) if with_class else 0
    fir = pct(sum(d.wrong_surface or (with_class and d.detected and d.final_case != k)
                  for d, k in faulty), n_f)
    delays = [d.delay_s for d, _ in faulty if d.detected]
    cdel = [d.class_delay_s for d, _ in faulty if math.isfinite(d.class_delay_s)]
    return [label, n_ff, n_f, far, mdr, fir, pct(wrong_surf, n_f),
            pct(wrong_case, n_f) if with_class else math.nan,
            max(delays) if delays else math.nan, float(np.mean(delays)) if delays else math.nan,
            float(np.mean(cdel)) if (cdel and with_class) else math.nan]


def experiments() -> dict[str, Callable[[Path, int, bool], str]]:
    return {"lu2017": lu2017, "lu2017_calibration": lu2017_calibration,
            "lu2017_campaign": lu2017_campaign}
