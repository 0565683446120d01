"""Per-set and per-channel FDI monitors (Wan2018 sec. III-A, Steps 1-2).

:class:`RedundantSetMonitor` watches a redundant set (triplex AoA, triplex CAS, IMU
instances of one axis): residuals against a model reference (Wan2018 eq. 17) or, without
one, against the set's own consensus (rules and limits in :mod:`gcs_monitor.fdi.isolation`),
residual RMS (eq. 18), n_D-of-N_eval confirmation, adaptive weighted fusion (eq. 19) and
the output configuration (Table I), with alarm transitions per instance and SET_LOST for
the set.

:class:`ChannelMonitor` watches one scalar estimator output (e.g. a reconstructed
accelerometer fault) with the same RMS / threshold / confirmation chain.

Both are deterministic: no clocks, no I/O; time is the vehicle's ``t_us``.  Per-sample
work uses Python floats and lists (faster than numpy for n = 3); classification (numpy)
runs only when an alarm is raised and every ``reclassify_every_n`` samples while active. The
fault type is decided at the raise and changed only on decisive evidence
(:class:`~gcs_monitor.fdi.classify.LabelHysteresis`, one per channel).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np

from gcs_monitor.core.kernels import load_kernels
from gcs_monitor.core.types import ChannelId
from gcs_monitor.fdi.alarms import AlarmParams, AlarmStateMachine
from gcs_monitor.fdi.classify import (
    Classification,
    ClassifierParams,
    ClassifierShape,
    LabelHysteresis,
    TypeFit,
    classify_residual,
    relabel_wins_n,
)
from gcs_monitor.fdi.confirmation import Confirmation, ConfirmationParams
from gcs_monitor.fdi.events import (
    SET_INSTANCE,
    AlarmEvent,
    AlarmKind,
    ChannelStatus,
    FaultType,
    SetStatus,
)
from gcs_monitor.fdi.isolation import consensus_residuals
from gcs_monitor.fdi.residuals import ResidualRms, RmsWindowParams
from gcs_monitor.fdi.voting import SetConfiguration, adaptive_weights, rms_floor_from_noise


@dataclass(frozen=True, slots=True)
class SetMonitorParams:
    """Parameters of one redundant-set monitor.

    threshold : J_th, SI (Wan2018 sec. VI-B: 2.9 deg for AoA, 12 kt for CAS, set from the
        worst fault-free residual RMS of its estimator; without a model reference the
        residual is a sensor-to-sensor difference and J_th scales with the sensor noise)
    noise_sigma : 1-sigma sensor noise, SI: J floor in eq. 19 and classifier noise level
    runaway_rate_per_s : drift/runaway boundary for the classifier, SI/s
    dt_s : nominal sample interval (classification time axis), s
    history_n : residual samples kept per instance for classification
    reclassify_every_n : samples between two reclassifications of an active alarm
    classifier : the classifier's shape tests (common to every channel)
    stuck_n : window of the frozen-signal check, samples (0 disables it; see
        :class:`FrozenSignalCheck`)
    stuck_ratio : an instance is frozen when the mean square of its sample-to-sample changes
        over ``stuck_n`` samples is below ``stuck_ratio`` times the most active healthy peer's
    no_data_n : samples an instance that has delivered before may go without a valid value
        while a peer delivers, before it is isolated with fault type ``no_data`` (0 disables
        it). A silent or out-of-range sensor is failed; Wan2018 (eq. 17) never sees it,
        because an instance without a value has no residual.
    restart_peers : when an instance is isolated, restart the residual windows and the
        confirmation counts of its healthy peers (ours, not Wan2018): their residuals were
        taken against a reference the isolated instance was still pulling (through the eq. 19
        fusion into the model, or into the consensus), so they judge the faulty peer as much
        as themselves. A peer that is faulty too is confirmed again from fresh residuals.
    """

    threshold: float
    noise_sigma: float
    runaway_rate_per_s: float
    dt_s: float = 0.01
    rms: RmsWindowParams = field(default_factory=RmsWindowParams)
    confirmation: ConfirmationParams = field(default_factory=ConfirmationParams)
    alarm: AlarmParams = field(default_factory=AlarmParams)
    history_n: int = 200
    reclassify_every_n: int = 50
    classifier: ClassifierShape = field(default_factory=ClassifierShape)
    stuck_n: int = 0
    stuck_ratio: float = 1.0e-3
    no_data_n: int = 0
    restart_peers: bool = False

    def __post_init__(self) -> None:
        if not self.threshold > 0.0:
            raise ValueError(f"threshold must be > 0, got {self.threshold}")
        if self.history_n < 4:
            raise ValueError(f"history_n must be >= 4, got {self.history_n}")
        if self.stuck_n < 0 or (self.stuck_n and self.stuck_n < 4):
            raise ValueError(f"stuck_n must be 0 (off) or >= 4, got {self.stuck_n}")
        if self.no_data_n < 0:
            raise ValueError(f"no_data_n must be >= 0 (0 = off), got {self.no_data_n}")
        if not 0.0 < self.stuck_ratio < 1.0:
            raise ValueError(f"stuck_ratio must be in (0, 1), got {self.stuck_ratio}")


class FrozenSignalCheck:
    """Frozen-signal (jammed sensor) check of a redundant set; not in Wan2018.

    A jammed vane or a blocked probe outputs ``y = x(t0)``: it stops following the flow, so its
    sample-to-sample changes collapse to the electrical noise, while a healthy peer keeps
    changing with the flight condition, turbulence and its own noise. Wan2018's residual (eq. 17)
    sees a jam only once the true value has moved by J_th (its worst detection delay, 19.16 s in
    Table IV, is a jam), so the set monitor adds this check.

    ``D_i = mean over the last n samples of (y_i[k] - y_i[k-1])^2``. Instance i is frozen when
    both hold:

    * its activity collapsed against its own past: ``D_i < ratio * median(D_i of its last
      ``past_n`` complete, non-overlapping windows)`` (at least two of them), and
    * against its peers: ``D_i < ratio * max_j D_j`` over the other instances with a full
      window, and that peer is active at all (``max_j D_j > floor``).

    The first condition keeps a healthy instance from looking frozen next to a peer with a
    noise or oscillation fault (its own activity has not changed); the second keeps a set that
    calms down as a whole (turbulence ends, or the aircraft is parked) from being flagged. With
    ``ratio = 1e-3`` (the default of :class:`SetMonitorParams`) the change RMS must fall to 3 %
    of both: white noise alone keeps a healthy sensor near 1. For a window of n = 10 samples
    (0.5 s at 20 Hz) the chance that white noise falls below 1e-3 of its mean square is
    2.5e-13 per test (small-ball bound for the quadratic form of the n differences, with
    ``ratio = 0.01`` it would be 2.5e-8: about one false "stuck" per few hundred
    instance-hours of pure-noise calm air); a jammed sensor's changes are exactly zero. Two
    jammed instances of a triplex are both found while one moves; three are left to the
    residual test. A sensor whose quantisation step exceeds its noise repeats values in calm
    air: give it a longer window.
    """

    __slots__ = ("n", "ratio", "floor", "past_n", "_prev", "_sq", "_sum", "_idx", "_count",
                 "_since", "_past")

    def __init__(self, n_inst: int, n: int, ratio: float, floor: float,
                 past_n: int = 8) -> None:
        self.n, self.ratio, self.floor, self.past_n = n, ratio, floor, past_n
        self._prev = [math.nan] * n_inst
        self._sq = [[0.0] * n for _ in range(n_inst)]
        self._sum = [0.0] * n_inst
        self._idx = [0] * n_inst
        self._count = [0] * n_inst
        self._since = [0] * n_inst
        self._past: list[list[float]] = [[] for _ in range(n_inst)]

    def update(self, m: Sequence[float], usable: Sequence[bool]) -> None:
        """Add one sample per instance (an unusable sample restarts that instance's windows)."""
        n = self.n
        for i, (x, u) in enumerate(zip(m, usable, strict=True)):
            prev = self._prev[i]
            if not u:
                self._prev[i] = math.nan
                self._count[i] = self._since[i] = 0
                self._sum[i] = 0.0
                self._past[i] = []
                continue
            self._prev[i] = x
            if prev != prev:
                continue
            d2 = (x - prev) * (x - prev)
            k = self._idx[i]
            buf = self._sq[i]
            if self._count[i] == n:
                self._sum[i] -= buf[k]
            else:
                self._count[i] += 1
            buf[k] = d2
            self._sum[i] += d2
            self._idx[i] = 0 if k + 1 == n else k + 1
            self._since[i] += 1
            if self._since[i] == n:  # one more complete, non-overlapping window
                self._since[i] = 0
                past = self._past[i]
                past.append(max(self._sum[i], 0.0) / n)
                if len(past) > self.past_n:
                    del past[0]

    def activity(self) -> list[float]:
        """``D_i`` per instance, NaN until its window is full."""
        n = self.n
        return [max(s, 0.0) / n if c == n else math.nan  # running sums may round below 0
                for s, c in zip(self._sum, self._count, strict=True)]

    def frozen(self) -> list[bool]:
        """Per instance: frozen against its own past and its most active peer."""
        d = self.activity()
        out = [False] * len(d)
        ratio = self.ratio
        # the two largest D (their values: the largest peer of each instance is one of them)
        top = top2 = -math.inf
        i_top = -1
        for j, x in enumerate(d):
            if x > top:
                top, top2, i_top = x, top, j
            elif x > top2:
                top2 = x
        for i, di in enumerate(d):
            past = self._past[i]
            # the newest stored window may already be the frozen one; judge against the older
            n_older = len(past) - 1 if self._since[i] == 0 else len(past)
            if di != di or n_older < 2:
                continue
            peer = top2 if i == i_top else top  # max over the others' D, 0 without any
            if peer == -math.inf:
                peer = 0.0
            if not (peer > self.floor and di < ratio * peer):
                continue  # an active instance: its own past need not be sorted
            srt = sorted(past[:n_older])
            mid = n_older // 2
            own = srt[mid] if n_older % 2 else 0.5 * (srt[mid - 1] + srt[mid])
            out[i] = di < ratio * own
        return out


class _History:
    """Ring buffer of the last ``n`` (residual, measurement) pairs of one instance."""

    __slots__ = ("r", "m", "idx", "count", "n")

    def __init__(self, n: int) -> None:
        self.n = n
        self.r = [0.0] * n
        self.m = [0.0] * n
        self.idx = 0
        self.count = 0

    def push(self, r: float, m: float) -> None:
        i = self.idx
        self.r[i] = r
        self.m[i] = m
        i += 1
        self.idx = 0 if i == self.n else i
        if self.count < self.n:
            self.count += 1

    def ordered(self) -> tuple[list[float], list[float]]:
        if self.count < self.n:
            return self.r[: self.count], self.m[: self.count]
        i = self.idx
        return self.r[i:] + self.r[:i], self.m[i:] + self.m[:i]


def _classify(r: Sequence[float], cp: ClassifierParams, dt_s: float,
              m: Sequence[float] | None = None) -> Classification:
    """The window's classification (oldest first); unknown below four samples."""
    if len(r) < 4:
        return Classification(FaultType.UNKNOWN, r[-1] if len(r) else math.nan)
    return classify_residual(np.asarray(r), dt_s, cp,
                             measured=None if m is None else np.asarray(m))


class RedundantSetMonitor:
    """FDI of one redundant set (Wan2018 sec. III-A Steps 1-2 and Table I).

    Parameters
    ----------
    name : set name, also the ChannelId kind of its instances (``"aoa"``, ``"cas"``)
    n : number of instances
    params : thresholds and windows
    estimator : name put in alarm events; ``"voting"`` when residuals are set-internal,
        the model estimator's name when a reference is supplied
    vehicle : MAVLink sysid stamped on events

    Instances are ``ChannelId(name, i)`` for i in 0..n-1; SET_LOST alarms are raised on
    ``ChannelId(name, SET_INSTANCE)``.
    """

    def __init__(
        self,
        name: str,
        n: int,
        params: SetMonitorParams,
        *,
        estimator: str = "voting",
        vehicle: int = 1,
        axis: str = "",
    ) -> None:
        if n < 1:
            raise ValueError(f"a redundant set needs >= 1 instance, got {n}")
        self.name = name
        self.n = n
        self.p = params
        self.estimator = estimator
        self._floor = rms_floor_from_noise(params.noise_sigma)
        self._cp = ClassifierParams.of(params.noise_sigma, params.runaway_rate_per_s,
                                       params.classifier)
        self._rms = [ResidualRms(params.rms) for _ in range(n)]
        self._conf = [Confirmation(params.confirmation) for _ in range(n)]
        self._hist = [_History(params.history_n) for _ in range(n)]
        wins_n = relabel_wins_n(params.classifier.relabel_windows, params.history_n,
                                params.reclassify_every_n)
        self._label = [LabelHysteresis(self._cp, wins_n) for _ in range(n)]
        self._alarm = [
            AlarmStateMachine(ChannelId(name, i, axis), AlarmKind.SENSOR_FAULT, estimator,
                              params=params.alarm, vehicle=vehicle)
            for i in range(n)
        ]
        self._set_alarm = AlarmStateMachine(ChannelId(name, SET_INSTANCE, axis), AlarmKind.SET_LOST,
                                            estimator, params=params.alarm, vehicle=vehicle)
        self._J = [0.0] * n
        self._faulty = [False] * n
        self._since_class = [0] * n
        self._range = range(n)
        self._n_active = 0
        self._labels: dict[tuple[int, bool, bool], str] = {}
        # floor: a peer must change by more than a hundredth of the noise sigma per sample
        self._frozen = (FrozenSignalCheck(n, params.stuck_n, params.stuck_ratio,
                                          (0.01 * params.noise_sigma) ** 2)
                        if params.stuck_n and n > 1 else None)
        self._stuck = [False] * n
        self._seen = [False] * n  # delivered a valid value at least once
        self._no_data_count = [0] * n
        self._no_data = [False] * n
        self._usable = [False] * n

    @property
    def faulty(self) -> tuple[bool, ...]:
        return tuple(self._faulty)

    @property
    def suspected(self) -> bool:
        """Some healthy, usable instance has its residual RMS above J_th (not yet confirmed)."""
        th = self.p.threshold
        return any(u and not f and j > th
                   for u, f, j in zip(self._usable, self._faulty, self._J, strict=True))

    @property
    def healthy(self) -> int:
        """Instances usable on the last sample and not isolated as faulty."""
        return sum(1 for u, f in zip(self._usable, self._faulty, strict=True) if u and not f)

    def set_threshold(self, threshold: float) -> None:
        """A new J_th from now on (scheduled on the estimated turbulence)."""
        if threshold != self.p.threshold:
            self.p = dataclasses.replace(self.p, threshold=threshold)

    def step(
        self,
        t_us: int,
        measured: np.ndarray | Sequence[float],
        valid: np.ndarray | Sequence[bool],
        reference: float | None = None,
    ) -> tuple[SetStatus, list[AlarmEvent]]:
        """Process one sample of the set.

        Parameters
        ----------
        t_us : vehicle time, µs
        measured : (n,) measurement per instance, SI (NaN allowed where invalid)
        valid : (n,) instance delivered a fresh, valid value
        reference : model prediction of the measured quantity (Wan2018 eq. 17), SI, or
            None to use the set's own consensus (:mod:`gcs_monitor.fdi.isolation`)
        """
        m = measured.tolist() if isinstance(measured, np.ndarray) else list(measured)
        vl = valid.tolist() if isinstance(valid, np.ndarray) else list(valid)
        usable = [v and x == x for v, x in zip(vl, m, strict=True)]
        has_ref = reference is not None and reference == reference
        ref, r = self._residuals(m, usable, reference if has_ref else None)
        changed = self._isolate(m, usable, r)
        weights, fused, n_healthy, all_faulty = self._fuse(m, usable, ref, has_ref)
        events: list[AlarmEvent] = []
        if changed or self._n_active:
            events = self._alarm_step(t_us, self._faulty, self._J, self.p.threshold, has_ref,
                                      all_faulty)
        label = self._labels.get((n_healthy, all_faulty, has_ref))
        if label is None:
            label = SetConfiguration(n_healthy, self.n, all_faulty, has_ref).label
            self._labels[(n_healthy, all_faulty, has_ref)] = label
        status = SetStatus(name=self.name, t_us=t_us, measured=tuple(m), reference=ref,
                           fused=fused, weights=tuple(weights), rms=tuple(self._J),
                           threshold=self.p.threshold, faulty=tuple(self._faulty),
                           configuration=label)
        return status, events

    def _residuals(self, m: list[float], usable: list[bool],
                   reference: float | None) -> tuple[float, list[float]]:
        """Stage 1, Wan2018 eq. 17: each usable instance minus the model reference, or minus the
        set's consensus without one; NaN for the others."""
        if reference is not None:
            ref = float(reference)
            return ref, [x - ref if u else math.nan for x, u in zip(m, usable, strict=True)]
        healthy = [u and not f for u, f in zip(usable, self._faulty, strict=True)]
        return consensus_residuals(m, usable, healthy)

    def _isolate(self, m: list[float], usable: list[bool], r: list[float]) -> bool:
        """Stage 2: frozen-signal and no-data checks, residual RMS (eq. 18) and n_D-of-N_eval
        confirmation per instance; restarts the healthy peers' windows when one is isolated.
        Returns whether any instance's decision changed."""
        th = self.p.threshold
        J = self._J
        rms = self._rms
        conf = self._conf
        hist = self._hist
        faulty = self._faulty
        changed = False
        stuck = self._stuck
        fr = self._frozen
        if fr is not None:  # jams (FrozenSignalCheck)
            fr.update(m, usable)
            latch = self.p.confirmation.latch
            for i, f in enumerate(fr.frozen()):
                if f:
                    stuck[i] = True
                elif not latch:
                    stuck[i] = False
        no_data = self._no_data
        if self.p.no_data_n:
            self._no_data_update(usable)
        isolated = False
        for i in self._range:
            ri = r[i]
            if ri == ri:
                j = rms[i].update(ri)
                J[i] = j
                hist[i].push(ri, m[i])
                if (conf[i].update(j, th) or stuck[i] or no_data[i]) != faulty[i]:
                    faulty[i] = not faulty[i]
                    changed = True
                    isolated |= faulty[i]
            elif (stuck[i] or no_data[i]) and not faulty[i]:
                faulty[i] = changed = isolated = True
        if isolated and self.p.restart_peers:
            for i in self._range:
                if not faulty[i]:
                    rms[i].reset()
                    conf[i].reset()
                    J[i] = 0.0
        self._usable = usable
        return changed

    def _fuse(self, m: list[float], usable: list[bool], ref: float,
              has_ref: bool) -> tuple[list[float], float, int, bool]:
        """Stage 3, eq. 19 and Table I: weights of the healthy instances, the fused value (the
        model estimate as virtual sensor when all are faulty), the healthy count and whether
        the set is lost."""
        faulty = self._faulty
        eligible = [u and not f for u, f in zip(usable, faulty, strict=True)]
        weights = adaptive_weights(self._J, eligible, self.p.threshold, self._floor)
        n_healthy = sum(eligible)
        all_faulty = all(faulty)
        if n_healthy:
            fused = 0.0
            for w, x in zip(weights, m, strict=True):
                if w:
                    fused += w * x
        elif all_faulty and has_ref:
            fused = ref  # Table I: the set is dropped, the model estimate is the virtual sensor
        else:
            fused = math.nan
        return weights, fused, n_healthy, all_faulty

    def _no_data_update(self, usable: list[bool]) -> None:
        """No-data check: count the samples each seen instance goes without a valid value while
        some peer delivers (a whole set going quiet -- a link gap -- counts for nobody)."""
        any_usable = any(usable)
        latch = self.p.confirmation.latch
        cnt, lost, seen = self._no_data_count, self._no_data, self._seen
        for i, u in enumerate(usable):
            if u:
                seen[i] = True
                cnt[i] = 0
                if not latch:
                    lost[i] = False
            elif seen[i] and any_usable:
                cnt[i] += 1
                if cnt[i] >= self.p.no_data_n:
                    lost[i] = True

    def _alarm_step(self, t_us: int, faulty: list[bool], J: list[float], th: float,
                    has_ref: bool, all_faulty: bool) -> list[AlarmEvent]:
        """Alarm transitions; runs only while some instance is faulty or alarmed."""
        events: list[AlarmEvent] = []
        for i in self._range:
            sm = self._alarm[i]
            if faulty[i]:
                self._since_class[i] += 1
                if not sm.active or self._since_class[i] >= self.p.reclassify_every_n:
                    self._since_class[i] = 0
                    r, m = self._hist[i].ordered()
                    c = _classify(r, self._cp, self.p.dt_s, m)
                    frozen = self._stuck[i] and J[i] <= th  # raised by the frozen-signal check
                    if self._no_data[i] and not self._usable[i]:
                        c = Classification(FaultType.NO_DATA, math.nan, confidence=1.0)
                    elif frozen:  # an observation of the measurement: certain
                        mag = c.fits[FaultType.STUCK].magnitude if c.fits else c.magnitude
                        c = dataclasses.replace(
                            c, fault_type=FaultType.STUCK, magnitude=mag, confidence=1.0,
                            fits={**c.fits, FaultType.STUCK: TypeFit(math.nan, mag)})
                    lab = (self._label[i].update(c) if sm.active
                           else self._label[i].decide(c))
                    if lab.fault_type is FaultType.NO_DATA:
                        msg = (f"no valid value for {self._no_data_count[i]} samples while a "
                               "peer delivers")
                    elif lab.fault_type is FaultType.STUCK and frozen:
                        msg = (f"stuck: frozen for {self.p.stuck_n} samples while a peer "
                               f"varies, residual {lab.magnitude:.4g}")
                    else:
                        msg = lab.message()
                    events += sm.step(t_us, True, fault_type=lab.fault_type,
                                      magnitude=lab.magnitude, rms=J[i], threshold=th,
                                      message=msg, confidence=lab.confidence)
            elif sm.active:
                events += sm.step(t_us, False, rms=J[i], threshold=th)
        if all_faulty != self._set_alarm.active:
            msg = ("all instances faulty: virtual sensor (model estimate)" if has_ref
                   else "all instances faulty, no model reference: no valid output")
            events += self._set_alarm.step(t_us, all_faulty, fault_type=FaultType.UNKNOWN,
                                           magnitude=math.nan, rms=max(J), threshold=th,
                                           message=msg if all_faulty else "")
        self._n_active = sum(sm.active for sm in self._alarm) + self._set_alarm.active
        return events


@dataclass(frozen=True, slots=True)
class ChannelMonitorParams:
    """Parameters of one estimator-channel monitor (threshold from :func:`calibrate`).

    Confirmation does not latch by default: a reconstructed fault can return to zero.
    """

    threshold: float
    noise_sigma: float
    runaway_rate_per_s: float
    dt_s: float = 0.01
    rms: RmsWindowParams = field(default_factory=RmsWindowParams)
    confirmation: ConfirmationParams = field(
        default_factory=lambda: ConfirmationParams(latch=False))
    alarm: AlarmParams = field(default_factory=AlarmParams)
    history_n: int = 200
    reclassify_every_n: int = 50
    classifier: ClassifierShape = field(default_factory=ClassifierShape)


class ChannelMonitor:
    """RMS window + threshold + confirmation + alarm on one scalar estimator output.

    The value is already a residual or a reconstructed fault (zero when healthy), so it is
    windowed directly (Wan2018 eq. 18 with r = value).
    """

    def __init__(
        self,
        channel: ChannelId,
        params: ChannelMonitorParams,
        *,
        estimator: str,
        kind: AlarmKind = AlarmKind.SENSOR_FAULT,
        vehicle: int = 1,
    ) -> None:
        self.channel = channel
        self.p = params
        self.estimator = estimator
        self._cp = ClassifierParams.of(params.noise_sigma, params.runaway_rate_per_s,
                                       params.classifier)
        self._rms = ResidualRms(params.rms)
        self._conf = Confirmation(params.confirmation)
        self._hist = _History(params.history_n)
        self._label = LabelHysteresis(self._cp, relabel_wins_n(
            params.classifier.relabel_windows, params.history_n, params.reclassify_every_n))
        self._alarm = AlarmStateMachine(channel, kind, estimator, params=params.alarm,
                                        vehicle=vehicle)
        self._J = 0.0
        self._faulty = False
        self._since_class = 0

    def retire(self, t_us: int, why: str) -> list[AlarmEvent]:
        """The channel is no longer monitored (its sensor stopped being the one judged): an
        active alarm is cleared with ``why``; nothing otherwise."""
        if not self._alarm.active:
            return []
        return self._alarm.step(t_us, False, rms=self._J, threshold=self.p.threshold,
                                message=why)

    def set_threshold(self, threshold: float) -> None:
        """A new J_th from now on (imu: raised by the measured reference error)."""
        if threshold != self.p.threshold:
            self.p = dataclasses.replace(self.p, threshold=threshold)

    @property
    def in_alarm(self) -> bool:
        """Confirmed faulty or its alarm still raised (a scheduled J_th is frozen then)."""
        return self._faulty or self._alarm.active

    def step(self, t_us: int, value: float, valid: bool) -> tuple[ChannelStatus, list[AlarmEvent]]:
        """Process one sample; an invalid or non-finite value holds J and the decision."""
        events = self.update(t_us, value, valid)
        status = ChannelStatus(self.channel, t_us, value, self._J, self.p.threshold,
                               self._faulty, self.estimator)
        return status, events

    def update(self, t_us: int, value: float, valid: bool) -> list[AlarmEvent]:
        """:meth:`step` without building the :class:`ChannelStatus` (when nobody reads it)."""
        if valid and value == value and abs(value) != math.inf:
            self._J = self._rms.update(value)
            self._hist.push(value, math.nan)
            was = self._faulty
            self._faulty = self._conf.update(self._J, self.p.threshold)
            if self._faulty or was:
                return self._transitions(t_us, value, was, None)
        return []

    def _transitions(self, t_us: int, value: float, was: bool,
                     residuals: Callable[[], Sequence[float]] | None) -> list[AlarmEvent]:
        """Alarm transitions after the decision ``self._faulty`` (was ``was``) at ``t_us``;
        ``residuals`` gives the history oldest first (None: this monitor's own)."""
        th = self.p.threshold
        if self._faulty:
            self._since_class += 1
            if not was or self._since_class >= self.p.reclassify_every_n:
                self._since_class = 0
                r = self._hist.ordered()[0] if residuals is None else residuals()
                c = _classify(r, self._cp, self.p.dt_s)
                if len(r) < 4:
                    c = dataclasses.replace(c, magnitude=value)
                lab = self._label.update(c) if was else self._label.decide(c)
                return self._alarm.step(t_us, True, fault_type=lab.fault_type,
                                        magnitude=lab.magnitude, rms=self._J, threshold=th,
                                        message=lab.message(), confidence=lab.confidence)
            return []
        if was:
            return self._alarm.step(t_us, False, rms=self._J, threshold=th)
        return []


class ChannelBank:
    """:meth:`ChannelMonitor.update` of several channels (one estimator's faults) in one call.

    The RMS windows, histories and confirmations live in arrays updated by one numba kernel
    (``fdi/_channels_jit.py``: the same arithmetic in the same order as :class:`ResidualRms`,
    :class:`_History` and :class:`Confirmation`, exact re-summation included); alarm
    transitions and classification run in Python through each channel's own
    :class:`ChannelMonitor` (its alarm state machine, classifier, counters). A monitor given to a
    bank is stepped only through the bank from then on (its own windows stay at their state).
    :meth:`create` returns None when there are no monitors or their window lengths differ.
    """

    def __init__(self, monitors: Sequence[ChannelMonitor], kern: Any) -> None:
        self.monitors = list(monitors)
        self._kern = kern
        p0 = self.monitors[0].p
        k = len(self.monitors)
        self._recompute = p0.rms.recompute_every_n
        self._threshold = np.array([m.p.threshold for m in self.monitors])
        self._detect_n = np.array([m.p.confirmation.detect_n for m in self.monitors])
        self._clear_ratio = np.array([m.p.confirmation.clear_ratio for m in self.monitors])
        self._clear_n = np.array([m.p.confirmation.clear_n for m in self.monitors])
        self._latch = np.array([m.p.confirmation.latch for m in self.monitors])
        self._rms_buf = np.zeros((k, p0.rms.rms_window_n))
        self._rms_sum = np.zeros(k)
        self.J = np.zeros(k)
        self._hist = np.zeros((k, p0.history_n))
        self._conf_win = np.zeros((k, p0.confirmation.eval_n), dtype=np.uint8)
        self._istate = np.zeros((k, kern.N_ISTATE), dtype=np.int64)
        self._flags = np.zeros(k, dtype=np.int64)

    @classmethod
    def create(cls, monitors: Sequence[ChannelMonitor]) -> ChannelBank | None:
        if not monitors:
            return None
        kern = load_kernels("gcs_monitor.fdi._channels_jit")
        p0 = monitors[0].p
        same = all(m.p.rms.rms_window_n == p0.rms.rms_window_n
                   and m.p.rms.recompute_every_n == p0.rms.recompute_every_n
                   and m.p.confirmation.eval_n == p0.confirmation.eval_n
                   and m.p.history_n == p0.history_n for m in monitors)
        return cls(monitors, kern) if same else None

    def set_threshold(self, c: int, threshold: float) -> None:
        """A new J_th of channel ``c`` from now on (:meth:`ChannelMonitor.set_threshold`)."""
        self.monitors[c].set_threshold(threshold)
        self._threshold[c] = threshold

    def in_alarm(self, c: int) -> bool:
        """Channel ``c`` confirmed faulty or its alarm still raised."""
        return bool(self._istate[c, self._kern.FAULTY]) or self.monitors[c].in_alarm

    def _residuals(self, c: int) -> Callable[[], Sequence[float]]:
        def ordered() -> Sequence[float]:
            ist = self._istate[c]
            n = self._hist.shape[1]
            count, idx = int(ist[self._kern.HIST_COUNT]), int(ist[self._kern.HIST_IDX])
            row = self._hist[c]
            if count < n:
                return cast(list[float], row[:count].tolist())
            return cast(list[float], row[idx:].tolist() + row[:idx].tolist())
        return ordered

    def update(self, t_us: int, values: Sequence[float], valid: bool,
               statuses: list[ChannelStatus] | None = None) -> list[AlarmEvent]:
        """One sample of every channel (``values`` in monitor order); returns the alarm events
        and, with ``statuses``, appends each channel's :class:`ChannelStatus` to it."""
        kern = self._kern
        vals = np.array(values, dtype=np.float64)
        any_flags = kern.bank_update(
            vals, valid, self._threshold, self._recompute, self._detect_n, self._clear_ratio,
            self._clear_n, self._latch, self._rms_buf, self._rms_sum, self.J, self._hist,
            self._conf_win, self._istate, self._flags)
        events: list[AlarmEvent] = []
        if any_flags & (kern.WAS_FAULTY | kern.IS_FAULTY | kern.NON_FINITE):
            for c, f in enumerate(self._flags.tolist()):
                if f & kern.NON_FINITE:
                    raise ValueError(f"non-finite residual {values[c]!r}; call skip() for "
                                     "invalid samples")
                if f & (kern.WAS_FAULTY | kern.IS_FAULTY):
                    mon = self.monitors[c]
                    mon._J = float(self.J[c])
                    mon._faulty = bool(f & kern.IS_FAULTY)
                    events += mon._transitions(t_us, values[c], bool(f & kern.WAS_FAULTY),
                                               self._residuals(c))
        if statuses is not None:
            faulty = self._istate[:, kern.FAULTY].tolist()
            for mon, v, j, fl in zip(self.monitors, values, self.J.tolist(), faulty, strict=True):
                statuses.append(ChannelStatus(mon.channel, t_us, v, j, mon.p.threshold,
                                              bool(fl), mon.estimator))
        return events


def calibrate(
    values: Sequence[float] | np.ndarray,
    *,
    rms_window_n: int = RmsWindowParams().rms_window_n,
    rule: str = "max",
    k: float | None = None,
) -> float:
    """Detection threshold J_th from a fault-free record of a channel's residual.

    Wan2018 sec. VI-B sets J_th from the worst fault-free residual RMS so that the
    fault-free runs give zero false alarms.  Two rules:

    - ``"max"`` : ``J_th = k * max_k J_k`` over the record (default k = 1.5: a margin over
      the worst case seen, since a finite record under-samples the tail);
    - ``"mean_std"`` : ``J_th = mean(J) + k * std(J)`` (default k = 6), for long records
      where a statistical margin is preferred to the single worst sample.

    Parameters
    ----------
    values : (N,) fault-free residual or fault estimate, SI; N >= rms_window_n
    rms_window_n : N_eval of the monitor that will use the threshold
    """
    x = np.asarray(values, dtype=np.float64)
    x = x[np.isfinite(x)]
    if x.size < rms_window_n:
        raise ValueError(f"need >= {rms_window_n} finite samples, got {x.size}")
    # full-window RMS only (the start-up partial windows under-estimate J)
    c = np.concatenate(([0.0], np.cumsum(x * x)))
    J = np.sqrt(np.maximum(c[rms_window_n:] - c[:-rms_window_n], 0.0) / rms_window_n)
    if rule == "max":
        return float((1.5 if k is None else k) * J.max())
    if rule == "mean_std":
        return float(J.mean() + (6.0 if k is None else k) * J.std())
    raise ValueError(f"unknown calibration rule {rule!r}: use 'max' or 'mean_std'")
