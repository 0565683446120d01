"""The servo level of the actuator family: Lu2017's fault reconstruction per control surface,
where the telemetry reports surface and rod position (the SURF convention, docs/telemetry.md).

Per SURF sample and surface (aileron, elevator, rudder), :class:`ServoTier`

* **predict** -- steps the surface's IOTSEKF (input faults: liquid and solid OFC, Lu2017 eqs.
  14-36) and RTS-EKF (output faults: liquid and solid jam, runaway, eqs. 37-48) on the closed
  servo loop (``servo_filters.py``, ``models/servo.py``);
* **judge** -- windows two detector values per surface (Wan2018 eq. 18 with r = the value, the
  fdi layer's :class:`~gcs_monitor.fdi.residuals.ResidualRms` and
  :class:`~gcs_monitor.fdi.confirmation.Confirmation` sized by
  :func:`~gcs_monitor.fdi.config.channel_params` with the measured SURF period): the input
  fault estimate ``f_hat^i`` (valve units) against a J_th that grows with the unseen-command
  spread the filters estimate (``input_per_jitter``: commands that jump between SURF samples
  leave the model uncertain, papers-notes; over a command step that saturates the valve, the
  nominal servo's timing envelope, held over the RMS window), and the output fault in sigmas
  of the RTS-EKF's own ``P^f`` (eq. 43, plus the nominal servo's timing envelope) -- the rod
  sensor's deviation from the nominal servo or the rod-surface disagreement, the larger; when
  either confirms, it classifies the surface's fault (``servo_classify.py``) and raises one
  ``actuator_fault`` alarm on ``ChannelId("surface", k, "input" | "output")`` with the case in
  the message, the fault type (oscillation, bias, stuck, runaway) and the magnitude (OFC
  amplitude in valve units, rod-sensor bias or stuck rod position in m, runaway rate in m/s);
  while active it is re-classified every ``reclassify_s`` (an OFC needs its cycles: it is
  raised as an input fault of pending class and updated);
* **update** -- returns the filters' estimates of the sample.

One alarm per surface, on the axis the classification decides: both detectors usually see a
fault (an OFC moves the rod away from the nominal servo too), so the detection is the fdi
layer's, per channel, and the decision between input and output is the surface's. That is why
the tier uses the fdi building blocks and its own :class:`~gcs_monitor.fdi.alarms.
AlarmStateMachine`\\ s rather than two :class:`~gcs_monitor.fdi.monitor.ChannelMonitor`\\ s, which
would each raise their own alarm with the generic residual classifier.

The filters run at the SURF rate with the measured interval between samples (the SURF sample
instant is the Frame time minus the sample's age); windows in seconds become sample counts
with the measured SURF period when judging starts. Without SURF in the telemetry the tier
reports itself unavailable (``inputs=False``); with stale SURF, a restart or during the
filters' warm-up it reports why it does not judge.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from gcs_monitor.core.params import DisplayUnit, param, section
from gcs_monitor.core.types import ChannelId
from gcs_monitor.families.actuators.servo_classify import (
    CASE_LABELS,
    INPUT_CASES,
    ServoClass,
    ServoClassifierConfig,
    ServoWindow,
    classify_servo,
)
from gcs_monitor.families.actuators.servo_filters import (
    N_OUT,
    O_ENV,
    O_F_IN,
    O_F_ROD,
    O_F_SURF,
    O_JIT,
    O_LEAD,
    O_N1,
    O_N3,
    O_NU,
    O_Q_COM,
    O_SF_D,
    O_SF_ROD,
    O_U,
    O_X1,
    O_X3,
    O_Y_ROD,
    ServoFilterBank,
    ServoFilterConfig,
    ServoSensors,
)
from gcs_monitor.families.base import FamilyContext, Verdict
from gcs_monitor.fdi.alarms import AlarmStateMachine
from gcs_monitor.fdi.config import ChannelSetConfig, channel_params
from gcs_monitor.fdi.confirmation import Confirmation
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, ChannelStatus
from gcs_monitor.fdi.monitor import ChannelMonitorParams
from gcs_monitor.fdi.records import Estimate, FamilyStatus
from gcs_monitor.fdi.residuals import ResidualRms
from gcs_monitor.models.servo import ServoLoopParams, ServoParams
from gcs_monitor.telemetry.frame import Frame
from gcs_monitor.telemetry.period import SamplePeriod

US_PER_S = 1_000_000
SURFACES = ("aileron", "elevator", "rudder")  # SURF index k (docs/telemetry.md)
SURFACE_KIND = "surface"  # ChannelId kind of the servo channels
# the lever check of the warm-up (ServoTier._check_lever): relative gain mismatch that means
# another airframe's servo model (surfaces that moved give 0-3 % on the simulator's Lu2017 and
# demo flights; the UAV's lever is 3.6x the transport's), and the rod motion (RMS) below which a
# surface cannot tell (a barely moving aileron gave 25 %, its sensor noise)
LEVER_TOLERANCE = 0.2
LEVER_MIN_RMS_M = 5.0e-3
AXES = ("input", "output")
IOTSEKF_NAME = "servo_iotsekf"
RTSEKF_NAME = "servo_rtsekf"
ESTIMATORS = {"input": IOTSEKF_NAME, "output": RTSEKF_NAME}
# rates of the SURF stream the tier is valid for: the servo's closed loop (~40 rad/s poles,
# 56 rad/s hydraulic mode) must be sampled, the model is integrated in substeps in between
RATE_HZ = (20.0, 1000.0)

VALVE = DisplayUnit("valve", "valveps", 1.0)  # the valve command's own unit (-, |u| <= 1)
SIGMA = DisplayUnit("sigma", "sigmaps", 1.0)  # standard deviations of the filter's own P^f


def servo_channel(surface: int, axis: str) -> ChannelId:
    """The alarm channel of one surface's input or output faults."""
    return ChannelId(SURFACE_KIND, surface, axis)


def input_channels(threshold: float) -> ChannelSetConfig:
    """Input-fault channels: 0.2 s windows (10 samples at 50 Hz), half of them above J_th
    confirm, a fault clears after 5 s below half of J_th; 4 s of history for the classifier
    (two periods of a 0.5 Hz OFC), re-classified every 0.5 s while active."""
    return ChannelSetConfig(threshold=threshold, window_s=0.2, detect_ratio=0.5, clear_s=5.0,
                            latch=False, noise_sigma=0.005, runaway_rate=1.0, history_s=4.0,
                            reclassify_s=0.5)


def output_channels(threshold_sigma: float) -> ChannelSetConfig:
    """Output-fault channels (sigmas of the RTS-EKF's P^f), as :func:`input_channels`."""
    return ChannelSetConfig(threshold=threshold_sigma, window_s=0.2, detect_ratio=0.5,
                            clear_s=5.0, latch=False, noise_sigma=1.0, runaway_rate=1.0,
                            history_s=4.0, reclassify_s=0.5)


# Thresholds: 1.5 x the worst fault-free residual RMS over fault-free runs of the servo campaign
# (every manoeuvre, turbulence; calibration seeds, not the evaluation seeds) and the Lu2017
# fault-free preset: `gcs-monitor evaluate --experiment lu2017_calibration` prints them.
INPUT_THRESHOLD = 0.026
INPUT_PER_JITTER = 9.3  # valve per m of unseen-command spread
OUTPUT_THRESHOLD_SIGMA = 3.5
OUTPUT_PER_JITTER = 0.0  # sigmas per m: the RTS-EKF's P^f carries the command uncertainty
ENV_SIGMA = 1.0 / math.sqrt(12.0)  # sigma of a uniform spread over the timing envelope


@dataclass(frozen=True, slots=True)
class ServoFdiSets:
    """The two detectors of every surface."""

    input: ChannelSetConfig = section(lambda: input_channels(INPUT_THRESHOLD),
                                      "input-fault channels: the IOTSEKF's f^i (valve units)",
                                      unit=VALVE)
    output: ChannelSetConfig = section(
        lambda: output_channels(OUTPUT_THRESHOLD_SIGMA),
        "output-fault channels: the RTS-EKF's rod output fault or the rod-surface sensor "
        "disagreement over its standard deviation (P^f, Lu2017 eq. 43), whichever is larger "
        "(sigmas)", unit=SIGMA)
    input_per_jitter: float = param(
        INPUT_PER_JITTER, "growth of the input J_th per m of unseen-command spread (the rod "
        "command's jumps between SURF samples, see servo_filters.ServoFilters; over a "
        "saturated slew, the nominal servo's timing envelope / sqrt(12), the larger over the "
        "RMS window)")
    output_per_jitter: float = param(
        OUTPUT_PER_JITTER, "growth of the output J_th (sigmas) per m of unseen-command spread")


@dataclass(frozen=True, slots=True)
class ServoTierConfig:
    """Lu2017 servo-level fault reconstruction where SURF feedback is reported."""

    enabled: bool = param(True, "run the servo level where the telemetry reports surface and "
                          "rod positions")
    warmup_s: float = param(2.0, "the filters' estimates are judged this long after a "
                            "(re)start", positive=True)
    max_gap_s: float = param(0.1, "after a longer gap between SURF samples the filters restart",
                             positive=True)
    max_gap_periods: float = param(2.5, "the gap limit is at least this many measured SURF "
                                   "periods", positive=True)
    servo: ServoParams = section(ServoParams, "the hydraulic servo (Lu2017 sec. II.A)")
    loop: ServoLoopParams = section(ServoLoopParams, "its NDI position loop and reference "
                                    "model (Lu2017 sec. III, values ours)")
    sensors: ServoSensors = section(ServoSensors, "lever, stroke and position sensors")
    filters: ServoFilterConfig = section(ServoFilterConfig, "IOTSEKF and RTS-EKF settings")
    fdi: ServoFdiSets = section(ServoFdiSets, "detection thresholds and windows")
    classifier: ServoClassifierConfig = section(ServoClassifierConfig,
                                                "the five Lu2017 cases")


@dataclass(frozen=True, slots=True)
class ServoPrediction:
    """What :meth:`ServoTier.predict` gave for one Frame.

    new : the Frame carried a new SURF sample and the filters stepped on it
    rows : (3, N_OUT) per surface the filters' output row (``servo_filters.O_*``)
    earlier : the rows of the Frame's earlier SURF samples (Frames slower than SURF)
    reinit : why the filters (re)started on this sample ("" when they stepped)
    """

    new: bool
    rows: np.ndarray | None = None
    reinit: str = ""
    # the output rows (as Python floats) of the SURF samples this Frame brought before its
    # newest one (Frame.surf_new), oldest first: judged before ``rows``
    earlier: tuple[list[list[float]], ...] = ()


NO_SAMPLE = ServoPrediction(False)  # the Frames without a new SURF sample (most of them)


class _History:
    """Ring buffer of the last ``n`` rows of one surface (columns: the filter outputs)."""

    __slots__ = ("buf", "n", "idx", "count")

    def __init__(self, n: int) -> None:
        self.buf = np.zeros((n, N_OUT))
        self.n = n
        self.idx = 0
        self.count = 0

    def push(self, row: np.ndarray | list[float]) -> None:
        self.buf[self.idx] = row
        self.idx = (self.idx + 1) % self.n
        self.count = min(self.count + 1, self.n)

    def last(self, k: int) -> np.ndarray:
        """The newest ``min(k, count)`` rows, oldest first."""
        k = min(k, self.count)
        i = self.idx
        idx = (np.arange(i - k, i)) % self.n
        return self.buf[idx]

    def clear(self) -> None:
        self.idx = 0
        self.count = 0


class _SurfaceFdi:
    """Detectors, history and the one alarm of one surface (module docstring)."""

    def __init__(self, surface: int, p_in: ChannelMonitorParams, p_out: ChannelMonitorParams,
                 fdi: ServoFdiSets, tier: ServoTier) -> None:
        self.k = surface
        self.p = {"input": p_in, "output": p_out}
        self.rms = {a: ResidualRms(self.p[a].rms) for a in AXES}
        self.conf = {a: Confirmation(self.p[a].confirmation) for a in AXES}
        self.J = {a: 0.0 for a in AXES}
        self.faulty = {a: False for a in AXES}
        # |timing envelope| of the samples in the input RMS window (m of rod)
        self.env: deque[float] = deque(maxlen=p_in.rms.rms_window_n)
        ctx = tier.ctx
        self.alarm = {a: AlarmStateMachine(servo_channel(surface, a), AlarmKind.ACTUATOR_FAULT,
                                           ESTIMATORS[a], params=ctx.alarm, vehicle=ctx.vehicle)
                      for a in AXES}
        self.hist = _History(p_in.history_n)
        self.tier = tier
        self.per_jitter = {"input": fdi.input_per_jitter, "output": fdi.output_per_jitter}
        self.th = {a: self.p[a].threshold for a in AXES}  # the scheduled J_th of this sample
        self.active_axis: str | None = None
        self.onset_n = 0  # history rows since the detection's onset
        self.since_class = 0
        self.last_class: ServoClass | None = None
        # per axis, what step() reads (made once: the step runs at the SURF rate)
        self._axes = [(a, self.rms[a], self.conf[a], self.p[a].threshold, self.per_jitter[a],
                       servo_channel(surface, a), ESTIMATORS[a]) for a in AXES]

    def step(self, t_us: int, row: list[float], statuses: list[ChannelStatus] | None,
             row_array: np.ndarray | None = None) -> list[AlarmEvent]:
        """Judge one output row (``O_*``, as Python floats) of the surface's filters
        (``row_array``: the same row as an array, when the caller has it: the history copies
        it faster than the floats)."""
        f_rod = row[O_F_ROD]
        # the output detector in sigmas of the RTS-EKF's own P^f (eq. 43): the rod sensor's
        # deviation from the nominal servo, or the rod-surface disagreement, the larger
        z_rod = f_rod / row[O_SF_ROD]
        z_d = (f_rod - row[O_F_SURF]) / row[O_SF_D]
        v_out = z_rod if abs(z_rod) >= abs(z_d) else z_d
        self.hist.push(row if row_array is None else row_array)
        # the command's unknown profile as a rod spread: unseen samples (jit) and when a
        # change took effect inside the interval, whose effect the linearised timing noise
        # misses while the valve saturates (the envelope: uniform, sigma env / sqrt(12)); the
        # envelope of every sample in the window counts, as each sample's error does in J
        env = self.env
        env.append(abs(row[O_ENV]))
        e = max(env) * ENV_SIGMA
        jit = math.sqrt(row[O_JIT] ** 2 + e * e) if e > 0.0 else row[O_JIT]
        J, th_now, faulty = self.J, self.th, self.faulty
        for (a, rms, conf, threshold, per_jitter, channel, estimator), value in zip(
                self._axes, (row[O_F_IN], v_out), strict=True):
            j = rms.update(value)
            J[a] = j
            th = threshold + per_jitter * jit
            th_now[a] = th
            faulty[a] = f = conf.update(j, th)
            if statuses is not None:
                statuses.append(ChannelStatus(channel, t_us, value, j, th, f, estimator))
        detected = faulty["input"] or faulty["output"]
        if not detected:
            self.onset_n = 0
            if self.active_axis is None:
                return []
            return self._clear(t_us, "")
        if self.active_axis is None:
            # onset: the samples of the detection window that confirmed it
            self.onset_n = self.p["input"].rms.rms_window_n
        else:
            self.onset_n += 1
        self.since_class += 1
        if self.active_axis is not None and (
                self.since_class < self.p["input"].reclassify_every_n
                or not any(self.J[a] > self.th[a] for a in AXES)):
            # re-classified every reclassify_s, and only while a detector sees the fault (a
            # confirmed fault is held for clear_s below the clear level: nothing to learn then)
            return []
        self.since_class = 0
        c = self._settle(self._classify())
        self.last_class = c
        events: list[AlarmEvent] = []
        if self.active_axis is not None and self.active_axis != c.axis:
            events += self._clear(t_us, f"re-classified: {CASE_LABELS[c.case]}")
        self.active_axis = c.axis
        msg = f"{SURFACES[self.k]} {c.message}"
        events += self.alarm[c.axis].step(t_us, True, fault_type=c.fault_type,
                                          magnitude=c.magnitude, rms=self.J[c.axis],
                                          threshold=self.th[c.axis], message=msg)
        return events

    def _settle(self, c: ServoClass) -> ServoClass:
        """The classification of an active fault does not go back to ``unknown`` (a window
        without the signature -- an OFC's trough, a jam while the command passes the stuck
        position -- does not undo it), and a runaway keeps the steepest rate it was seen at
        (the ramp leaves the history once the rod rests at the stop)."""
        prev = self.last_class
        if prev is None or self.active_axis is None:
            return c
        if c.case == "unknown":
            return prev
        if c.case == "runaway" and prev.case == "runaway" and \
                abs(prev.rate_mps) > abs(c.rate_mps):
            return prev
        return c

    def _classify(self) -> ServoClass:
        tier = self.tier
        n = max(self.onset_n, round(tier.cfg.classifier.recent_s / tier.period_s))
        h = self.hist.last(n)
        w = ServoWindow(dt_s=tier.period_s, f_in=h[:, O_F_IN], u=h[:, O_U], y_rod=h[:, O_Y_ROD],
                        f_rod=h[:, O_F_ROD], f_surf=h[:, O_F_SURF], x_nom=h[:, O_N1],
                        valve_rate_mps=tier.valve_rate_mps,
                        stroke_m=tier.cfg.sensors.rod_stroke_m,
                        rod_sigma_m=tier.cfg.sensors.rod_sigma_m)
        return classify_servo(w, tier.cfg.classifier,
                              input_ratio=self.J["input"] / self.th["input"],
                              output_ratio=self.J["output"] / self.th["output"])

    def _clear(self, t_us: int, why: str) -> list[AlarmEvent]:
        a = self.active_axis
        self.active_axis = None
        self.since_class = 0
        if a is None or not self.alarm[a].active:
            return []
        return self.alarm[a].step(t_us, False, rms=self.J[a], threshold=self.th[a],
                                  message=why)

    def retire(self, t_us: int, why: str) -> list[AlarmEvent]:
        """Judging stops (restart, stale SURF): an active alarm is cleared with ``why``."""
        ev = self._clear(t_us, why)
        for a in AXES:
            self.rms[a].reset()
            self.conf[a].reset()
            self.J[a] = 0.0
            self.faulty[a] = False
        self.hist.clear()
        self.env.clear()
        self.onset_n = 0
        return ev


class ServoTier:
    """Lu2017 servo-level FDI of one vehicle's three surfaces (module docstring); the
    :class:`~gcs_monitor.families.base.Family` protocol."""

    name = "servo"

    def __init__(self, cfg: ServoTierConfig, ctx: FamilyContext) -> None:
        self.cfg = cfg
        self.ctx = ctx
        self.bank = ServoFilterBank(len(SURFACES), cfg.servo, cfg.loop, cfg.sensors,
                                    cfg.filters)
        self.filters = self.bank.filters
        self._period = SamplePeriod()
        self.period_s = math.nan  # SURF period the windows were sized with
        # rod rate per unit valve command at no load, phi_n / A_p (Lu2017 eq. 4)
        self.valve_rate_mps = cfg.servo.max_valve_flow_m3ps / cfg.servo.piston_area_m2
        self._fdi: list[_SurfaceFdi] | None = None
        self._last_us: int | None = None  # instant of the last SURF sample stepped on
        self._seen = False  # SURF has been in the telemetry
        self._judge_from_us: int | None = None
        self._rows = np.zeros((len(SURFACES), N_OUT))
        self._row_lists: list[list[float]] = []  # self._rows as Python floats
        self._est_t_us: int | None = None  # the Frame whose SURF sample self._rows holds
        # the estimates' keys, made once (built per sample, they showed in replay profiles)
        self._keys = [(f"{name}_x", f"{name}_x_nominal", servo_channel(k, "input"),
                       ChannelId(SURFACE_KIND, k, "output_rod"),
                       ChannelId(SURFACE_KIND, k, "output_surface"),
                       ChannelId(SURFACE_KIND, k, "rod"), ChannelId(SURFACE_KIND, k, "valve"),
                       ChannelId(SURFACE_KIND, k, "rod_command"),
                       ChannelId(SURFACE_KIND, k, "command_lead"))
                      for k, name in enumerate(SURFACES)]
        self._why = ""  # why the last new sample was not stepped on (restart)
        # the lever the telemetry shows: sum(pos * rod), sum(rod^2) and the sample count per
        # surface over the warm-up, checked against the configured rod gain (_check_lever)
        self._lever = [[0.0, 0.0, 0] for _ in SURFACES]
        self._misfit = ""  # why the configured servo model does not fit ("" = it fits)

    # -- predict ---------------------------------------------------------------------------------
    def predict(self, frame: Frame) -> ServoPrediction:
        """Both filters of every surface on each new SURF sample of the Frame, oldest first
        (module docstring): a Frame slower than SURF brings several (``Frame.surf_new``), and
        every one is stepped on and judged; none is skipped."""
        if frame.surf_new:
            samples = frame.surf_new
        else:  # a Frame made without the backlog (tests, tools): its newest sample
            cmd, pos, rod = frame.surf_cmd_rad, frame.surf_pos_rad, frame.rod_pos_m
            if cmd is None or pos is None or rod is None:
                return NO_SAMPLE
            samples = ((frame.t_us - round(frame.surf_age_s * US_PER_S), cmd, pos, rod),)
        pred = NO_SAMPLE
        earlier: list[list[list[float]]] = []
        for t_s, cmd, pos, rod in samples:
            last = self._last_us
            if last is not None and t_s <= last:
                continue
            if pred.rows is not None:
                earlier.append(self._row_lists)
            elif pred.new:  # a restart: what came before it is not judged
                earlier.clear()
            pred = self._step_sample(frame.t_us, t_s, cmd, pos, rod)
        if earlier and pred.rows is not None:
            return ServoPrediction(True, pred.rows, earlier=tuple(earlier))
        return pred

    def _step_sample(self, t_us: int, t_s: int, cmd: np.ndarray, pos: np.ndarray,
                     rod: np.ndarray) -> ServoPrediction:
        """Both filters of every surface on one new SURF sample of time ``t_s`` (Frame time
        ``t_us``)."""
        last = self._last_us
        self._seen = True
        self._last_us = t_s
        self._period.add(t_s)
        cmd_l, pos_l, rod_l = cmd.tolist(), pos.tolist(), rod.tolist()
        if not all(map(math.isfinite, cmd_l + pos_l + rod_l)):
            self._restart(t_s, "surface sample not finite")
            return ServoPrediction(True, None, "surface sample not finite")
        dt = (t_s - last) / US_PER_S if last is not None else math.inf
        period = self._period.seconds()
        gap = max(self.cfg.max_gap_s, self.cfg.max_gap_periods * period) \
            if math.isfinite(period) else self.cfg.max_gap_s
        f0 = self.filters[0]
        if not f0.started or dt > gap:
            why = "start" if not f0.started else f"SURF gap {dt:.2f} s"
            self._restart(t_s, why)
            for k, f in enumerate(self.filters):
                f.start(cmd_l[k], rod_l[k])
            return ServoPrediction(True, None, why)
        rows = self._rows
        if self._fdi is not None:  # a surface in alarm teaches the command timing nothing
            for k, fdi in enumerate(self._fdi):
                self.bank.freeze_lead(k, fdi.active_axis is not None)
        failed = self.bank.step(dt, cmd, rod, pos, rows)
        if failed >= 0:
            why = f"{SURFACES[failed]}: numerical failure"
            self._restart(t_s, why)
            for j, g in enumerate(self.filters):
                g.start(cmd_l[j], rod_l[j])
            return ServoPrediction(True, None, why)
        self._row_lists = rows.tolist()  # judge() and update() read the rows as floats
        if self._fdi is None:  # still in the warm-up: the lever the data show
            for acc, p_k, q_k in zip(self._lever, pos_l, rod_l, strict=True):
                acc[0] += p_k * q_k
                acc[1] += q_k * q_k
                acc[2] += 1
        self._est_t_us = t_us  # estimates made in update(), from the same rows
        return ServoPrediction(True, rows)

    def _restart(self, t_s_us: int, why: str) -> None:
        self._judge_from_us = t_s_us + round(self.cfg.warmup_s * US_PER_S)
        self._why = why
        self._est_t_us = None
        self._period.gap()

    # -- judge -----------------------------------------------------------------------------------
    def judge(self, frame: Frame, prediction: ServoPrediction) -> Verdict:
        t = frame.t_us
        if not self._seen:
            return Verdict(FamilyStatus(self.name, t, False, sample=False, reason=(
                "no surface feedback (SURF surface and rod positions) in the telemetry"),
                inputs=False))
        if frame.surf_pos_rad is None:
            return Verdict(FamilyStatus(self.name, t, False, sample=False,
                                        reason="surface feedback (SURF) stale"),
                           events=self._retire(t, "surface feedback stale"))
        if not prediction.new:
            return Verdict(FamilyStatus(self.name, t, False, sample=False,
                                        reason="no new surface sample"))
        if prediction.rows is None:
            return Verdict(FamilyStatus(self.name, t, False, reason=f"filters restarted: "
                                        f"{prediction.reinit}"),
                           events=self._retire(t, f"filters restarted: {prediction.reinit}"))
        period = self._period.seconds()
        if math.isfinite(period) and 1.0 / period < RATE_HZ[0]:
            return Verdict(FamilyStatus(
                self.name, t, False, reason=f"SURF at {1.0 / period:.0f} Hz, below the "
                f"{RATE_HZ[0]:g} Hz the servo level needs"),
                events=self._retire(t, "SURF too slow"))
        assert self._judge_from_us is not None
        if t - round(frame.surf_age_s * US_PER_S) < self._judge_from_us:
            return Verdict(FamilyStatus(self.name, t, False, reason="servo filters warm-up"))
        if self._fdi is None:
            self._misfit = self._check_lever()
            self._build_fdi(period)
        assert self._fdi is not None
        if self._misfit:
            return Verdict(FamilyStatus(self.name, t, False, reason=self._misfit))
        verdict = Verdict(FamilyStatus(self.name, t, True))
        statuses = verdict.channels if self.ctx.statuses else None
        for rows in prediction.earlier:
            for fdi, row in zip(self._fdi, rows, strict=True):
                ev = fdi.step(t, row, statuses)
                if ev:
                    verdict.events += ev
        # the newest sample: its rows are also self._rows (prediction.rows)
        for fdi, row, row_array in zip(self._fdi, self._row_lists, self._rows, strict=True):
            ev = fdi.step(t, row, statuses, row_array)
            if ev:
                verdict.events += ev
        return verdict

    def _check_lever(self) -> str:
        """Does the configured servo model fit the aircraft? SURF reports both the rod and the
        surface position, and the lever between them is linear (delta = rod_gain * x1, the
        model of Lu2017 sec. II with our lever): its least-squares gain over the healthy
        warm-up, sum(delta x1) / sum(x1^2), must match ``sensors.rod_gain_radpm`` within
        ``LEVER_TOLERANCE``. A servo model of another airframe (the default is the
        transport's) would otherwise read the mismatch as output faults on every surface; the
        tier does not judge and says what to set. Surfaces whose rod moved less than
        ``LEVER_MIN_RMS_M`` (RMS) over the warm-up cannot tell and are not checked."""
        gain = self.cfg.sensors.rod_gain_radpm
        for name, (s_pq, s_qq, n) in zip(SURFACES, self._lever, strict=True):
            if n == 0 or s_qq / n < LEVER_MIN_RMS_M ** 2:
                continue
            measured = s_pq / s_qq
            if abs(measured / gain - 1.0) > LEVER_TOLERANCE:
                return (f"servo model does not fit this aircraft: the {name}'s surface/rod "
                        f"gain is {measured:.2f} rad/m in the telemetry, {gain:.2f} rad/m "
                        f"configured (set [actuators.servo.sensors] rod_gain_radpm and "
                        f"rod_stroke_m for this airframe)")
        return ""

    def _build_fdi(self, period_s: float) -> None:
        """The surfaces' detectors with windows of the measured SURF period."""
        self.period_s = period_s
        ctx = self.ctx
        p_in = channel_params(self.cfg.fdi.input, period_s, alarm=ctx.alarm,
                              classifier=ctx.classifier)
        p_out = channel_params(self.cfg.fdi.output, period_s, alarm=ctx.alarm,
                               classifier=ctx.classifier)
        self._fdi = [_SurfaceFdi(k, p_in, p_out, self.cfg.fdi, self)
                     for k in range(len(SURFACES))]

    def _retire(self, t_us: int, why: str) -> list[AlarmEvent]:
        if self._fdi is None:
            return []
        events: list[AlarmEvent] = []
        for fdi in self._fdi:
            events += fdi.retire(t_us, f"not judged: {why}")
        return events

    # -- update ----------------------------------------------------------------------------------
    def update(self, frame: Frame, verdict: Verdict) -> list[Estimate]:
        """The filters' estimates of this Frame's SURF sample (none without one, and none when
        nobody reads them: only sinks and callbacks do, ``FamilyContext.statuses``)."""
        if not verdict.status.sample or self._est_t_us is None or not self.ctx.statuses:
            return []
        return self._make_estimates(self._est_t_us, self._row_lists)

    def _make_estimates(self, t_us: int, rows: list[list[float]]) -> list[Estimate]:
        iots_states: dict[str, np.ndarray] = {}
        rts_states: dict[str, np.ndarray] = {}
        f_in: dict[ChannelId, float] = {}
        f_out: dict[ChannelId, float] = {}
        res_in: dict[ChannelId, float] = {}
        virt: dict[ChannelId, float] = {}
        for (x, xn, c_in, c_rod, c_surf, c_res, c_valve, c_cmd, c_lead), r in zip(
                self._keys, rows, strict=True):
            iots_states[x] = np.array(r[O_X1:O_X3 + 1])
            rts_states[xn] = np.array(r[O_N1:O_N3 + 1])
            f_in[c_in] = r[O_F_IN]
            f_out[c_rod] = r[O_F_ROD]
            f_out[c_surf] = r[O_F_SURF]
            res_in[c_res] = r[O_NU]
            virt[c_valve] = r[O_U]
            virt[c_cmd] = r[O_Q_COM]
            virt[c_lead] = r[O_LEAD]  # s: the autopilot's servo-output period, identified
        return [Estimate(IOTSEKF_NAME, t_us, states=iots_states, faults=f_in, residuals=res_in,
                         virtual=virt),
                Estimate(RTSEKF_NAME, t_us, states=rts_states, faults=f_out)]

    # -- for evaluations and views ---------------------------------------------------------------
    @property
    def classes(self) -> list[ServoClass | None]:
        """Per surface, the latest classification of an active fault (None when healthy)."""
        if self._fdi is None:
            return [None] * len(SURFACES)
        return [f.last_class if f.active_axis is not None else None for f in self._fdi]


def case_of(event: AlarmEvent) -> str:
    """The Lu2017 case (``liquid_ofc`` ... ``runaway``, or ``unknown``) an actuator-fault event
    of this tier names (its message starts with the surface and the case's label)."""
    if event.kind is not AlarmKind.ACTUATOR_FAULT or event.channel.kind != SURFACE_KIND:
        return "unknown"
    rest = event.message.split(" ", 1)[1] if " " in event.message else ""
    for case, label in CASE_LABELS.items():
        if case != "unknown" and rest.startswith(label):
            return case
    return "unknown"


def axis_of_case(case: str) -> str:
    """``input`` for the OFCs, ``output`` for the jams and the runaway (Lu2017 secs. IV-V)."""
    return "input" if case in INPUT_CASES else "output"
