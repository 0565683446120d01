"""The IMU family: reconstructed accelerometer and gyro faults (Lu2016, Atmaca2025) judged per
channel.

``predict`` steps every enabled estimator (its reconstructed faults f_hat exist only after the
filter's update, so the whole filter step is this family's prediction); ``judge`` windows each
fault estimate (Wan2018 eq. 18 with r = f_hat), confirms, classifies and raises alarms per
channel against that estimator's own thresholds, and turns estimator re-initialisations into
operator notices; ``update`` has nothing to feed back (no redundant IMU set is fused yet) and
returns the estimates.

Channel windows are sized with the measured IMU sample period when judging starts (after the
estimator's warm-up), never with an assumed rate. The period is that of the primary IMU's *new*
samples: a held (bit-identical repeated) sample is no measurement (telemetry/assembler.py,
"Held IMU samples"), so its Frame steps no estimator and leaves the family's account as it was,
and the effective rate decides whether the family can judge at all (``RATE_HZ``). A primary that
only repeats itself for longer than ``NO_DATA_PERIODS`` of its periods (at least the telemetry's
``stale_after_s``) is not judged, and the family says so.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from gcs_monitor.core.constants import EARTH_RADIUS_M
from gcs_monitor.core.types import ChannelId
from gcs_monitor.families.base import FamilyContext, FaultEstimator, Verdict
from gcs_monitor.families.imu.config import ImuFamilyConfig, ImuFdiSets
from gcs_monitor.families.imu.gating import ReferenceConsistency
from gcs_monitor.families.imu.imu_hosm import ImuHosmEstimator
from gcs_monitor.families.imu.imu_ts import ImuTwoStageEstimator
from gcs_monitor.fdi.alarms import AlarmStateMachine
from gcs_monitor.fdi.config import channel_params
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState, ChannelStatus, FaultType
from gcs_monitor.fdi.monitor import ChannelBank, ChannelMonitor
from gcs_monitor.fdi.records import Estimate, FamilyStatus
from gcs_monitor.telemetry.frame import Frame
from gcs_monitor.telemetry.period import SamplePeriod

US_PER_S = 1_000_000
# IMU rates the estimators are valid for (their discretisation follows the measured step; below
# 10 Hz the attitude kinematics between samples is not resolved; docs/results.md, rate sweep)
RATE_HZ = (10.0, 400.0)
GPS_FIX_3D = 3  # GPS_RAW_INT fix_type of a 3D fix: the velocity is used from it on
NO_DATA_PERIODS = 3.0  # an IMU instance is silent after this many of its own periods at least


class _Consistency:
    """Running mean of an estimator's normalised innovation squared, per measurement row.

    A filter whose noise model fits the vehicle has ``E[nu_i^2 / S_ii] = 1``; Lu2016's filter
    reports ``test_ratio = nu^2 / (gate^2 S)`` per row, so ``lambda = gate^2 x mean(test_ratio)``
    over the window estimates that expectation. Far above 1, the innovations are not what the
    noise model expects (another airframe's vibration, a GPS noisier than Table 1): its fault
    estimates then carry that mismatch and are not judged.
    """

    __slots__ = ("span_us", "_q", "_sum", "_n_since")

    def __init__(self, span_us: int) -> None:
        self.span_us = span_us
        self._q: deque[tuple[int, float]] = deque()
        self._sum = 0.0
        self._n_since = 0

    def add(self, t_us: int, lam: float) -> None:
        q = self._q
        q.append((t_us, lam))
        self._sum += lam
        while q[0][0] <= t_us - self.span_us:
            self._sum -= q.popleft()[1]
        self._n_since += 1
        if self._n_since >= 1000:  # exact re-summation against rounding drift
            self._n_since = 0
            self._sum = math.fsum(x for _, x in q)

    def mean(self) -> float:
        return self._sum / len(self._q) if self._q else math.nan

    def full(self, t_us: int) -> bool:
        return bool(self._q) and t_us - self._q[0][0] >= self.span_us // 2


@dataclass
class _Judged:
    """One estimator's FDI state: its fault sets, when judging (re)starts, its channels."""

    estimator: FaultEstimator
    sets: ImuFdiSets
    start_us: int | None = None  # fault estimates judged from this vehicle time on
    judging: bool = False  # its channels were being judged
    notice: AlarmEvent | None = None  # active re-initialisation notice
    channels: tuple[ChannelId, ...] = ()
    monitors: list[ChannelMonitor] = field(default_factory=list)
    bank: ChannelBank | None = None


class ImuFamily:
    """IMU fault channels of one vehicle (see the module docstring)."""

    name = "imu"

    def __init__(self, cfg: ImuFamilyConfig, ctx: FamilyContext, *,
                 estimators: Sequence[tuple[FaultEstimator, ImuFdiSets]] | None = None) -> None:
        """``estimators`` replaces the configured ones with given (estimator, its FDI sets)
        pairs (scripted estimators in tests, variants in evaluations)."""
        self.cfg = cfg
        self.ctx = ctx
        self._warmup_us = int(cfg.warmup_s * US_PER_S)
        if estimators is not None:
            self._est = [_Judged(e, sets) for e, sets in estimators]
        else:
            self._est = []
            if cfg.ts.enabled:
                self._est.append(_Judged(ImuTwoStageEstimator(cfg.ts.estimator), cfg.ts.fdi))
            if cfg.hosm.enabled:
                self._est.append(_Judged(ImuHosmEstimator(cfg.hosm.estimator), cfg.hosm.fdi))
        # Frame.gps_interp_err_ned_mps is computed by the assembler only when this is True
        self.reads_interp_error = any(getattr(j.estimator, "reads_interp_error", False)
                                      for j in self._est)
        self._period = SamplePeriod()  # of the primary IMU's new samples (effective rate)
        self._estimates: list[Estimate] = []
        self._held = False  # this Frame's primary IMU sample is a held (repeated) value
        self._last_status: FamilyStatus | None = None  # the account of the last new sample
        # innovation consistency of each estimator that reports test ratios
        self._consistency: dict[str, _Consistency] = {}
        self._gate2 = cfg.ts.estimator.filter.gate_sigma ** 2
        self._inputs = False  # attitude and GPS velocity have been in the telemetry
        self._seen_att = self._seen_gps = False
        # no-data check of every IMU instance: last sample time, alarm
        self._no_data_us = round(cfg.no_data_window_s * US_PER_S)
        self._last_sample: dict[int, int] = {}
        self._last_frame_us: int | None = None
        self._outage_us: dict[int, int] = {}  # vehicle-wide silence inside an IMU's silence
        self._instance_period: dict[int, SamplePeriod] = {}
        self._silent: dict[int, AlarmStateMachine] = {}
        # the GPS reference against itself (gating.py item 3): the accelerometer channels'
        # J_th is raised by the reference error it measures, for reference_hold_s after
        self._ref: ReferenceConsistency | None = None
        if cfg.reference_window_s > 0.0 and self._est:
            self._ref = ReferenceConsistency(cfg.reference_window_s,
                                             cfg.ts.estimator.gate.gate_sigma)
        self._ref_origin: tuple[float, float, float] | None = None
        self._ref_hold_us = round(cfg.reference_hold_s * US_PER_S)
        self._ref_excess: deque[tuple[int, float]] = deque()  # (t_us, m/s^2) above the bound
        self.reference_allowance_mps2 = 0.0  # added to the accelerometer J_th now

    @property
    def estimators(self) -> list[FaultEstimator]:
        return [j.estimator for j in self._est]

    def predict(self, frame: Frame) -> list[Estimate]:
        """Every estimator's step on this Frame: its fault estimates f_hat (Lu2016 eq. 60).

        On a held primary sample (``imu[primary].t_us < t_us``) nothing is stepped: the estimates
        of the last new sample stand (a repeated value fed as new data would be integrated twice
        over an interval it does not describe)."""
        if self._ref is not None:
            self._reference(frame)
        imu = frame.primary_imu
        self._held = imu is not None and imu.t_us != frame.t_us and bool(self._estimates)
        if self._held:
            return self._estimates
        self._period.add(frame.t_us)
        self._estimates = [j.estimator.step(frame) for j in self._est]
        return self._estimates

    def _reference(self, frame: Frame) -> None:
        """Feed the GPS velocity and position to the reference check (gating.py item 3);
        positions north/east/down from the first one on the GS-KM's sphere (Lu2016 eq. 11)."""
        ref = self._ref
        assert ref is not None
        v_arr = frame.gps_vel_ned_mps
        lat, lon, alt = frame.lat_rad, frame.lon_rad, frame.alt_msl_m
        # plain floats (the values themselves): cheaper to test and to integrate
        v = None if v_arr is None else (v_arr.tolist() if isinstance(v_arr, np.ndarray)
                                         else list(v_arr))
        if (v is None or frame.gps_held or not (math.isfinite(lat) and math.isfinite(lon)
                                                and math.isfinite(alt))
                or not all(map(math.isfinite, v))):
            ref.reset()
            return
        q_us = frame.t_us - frame.gps_delay_us
        base = None
        if frame.gps_new:
            if self._ref_origin is None:
                self._ref_origin = (lat, lon, alt)
            lat0, lon0, alt0 = self._ref_origin
            r = EARTH_RADIUS_M + alt
            pos = (r * (lat - lat0), r * math.cos(lat0) * (lon - lon0), alt0 - alt)
            base = (q_us - round(frame.gps_age_s * US_PER_S), pos)
        ref.add(q_us, v, base)
        t_us = frame.t_us
        q = self._ref_excess
        if base is not None and ref.consistent() is False:
            # the velocity reference is off by ~c beyond its noise, changing within the
            # window: an acceleration error of (c - bound) / T the fault estimates absorb
            q.append((t_us, (ref.inconsistency_mps - ref.bound_mps) / self.cfg.reference_window_s))
        while q and q[0][0] < t_us - self._ref_hold_us:
            q.popleft()
        self.reference_allowance_mps2 = max((a for _, a in q), default=0.0)

    def _held_verdict(self, frame: Frame) -> Verdict:
        """The family's account on a held primary sample: unchanged (not a new sample) while the
        hold is no longer than a few of the IMU's periods, else "not judged", with why."""
        t_us = frame.t_us
        imu = frame.primary_imu
        assert imu is not None  # _held needs one
        last = self._last_status
        verdict = Verdict(FamilyStatus(self.name, t_us, False, sample=False,
                                       reason=last.reason if last is not None else "",
                                       inputs=last.inputs if last is not None else False))
        if self._no_data_us:
            verdict.events += self._instances(frame)
        period_s = self._period.seconds()
        limit_s = self.ctx.stale_after_s
        if math.isfinite(period_s):
            limit_s = max(limit_s, NO_DATA_PERIODS * period_s)
        age_s = (t_us - imu.t_us) / US_PER_S
        if age_s > limit_s:
            verdict.status = FamilyStatus(
                self.name, t_us, False, inputs=verdict.status.inputs,
                reason=f"IMU {imu.instance} repeats its last sample for {age_s:.1f} s (held "
                       "values, no new measurement)")
        return verdict

    def judge(self, frame: Frame, prediction: list[Estimate]) -> Verdict:
        if self._held:
            return self._held_verdict(frame)
        verdict = self._judge(frame, prediction)
        self._last_status = verdict.status
        return verdict

    def _judge(self, frame: Frame, prediction: list[Estimate]) -> Verdict:
        t_us = frame.t_us
        if not self._inputs:
            self._seen_att = self._seen_att or frame.euler_rad is not None
            self._seen_gps = self._seen_gps or frame.gps_vel_ned_mps is not None
            self._inputs = self._seen_att and self._seen_gps
        inputs = self._inputs and bool(self._est)  # no estimator enabled: nothing to judge
        verdict = Verdict(FamilyStatus(self.name, t_us, False, reason="no estimator enabled",
                                       inputs=inputs))
        slow = self._too_slow()
        if self._no_data_us:
            verdict.events += self._instances(frame)
        statuses = verdict.channels if self.ctx.statuses else None
        reasons: list[str] = []
        judged_any = False
        for j, e in zip(self._est, prediction, strict=True):
            if slow:  # outside the family's rate range: nothing is judged, whatever else
                j.start_us = None
                reasons = [slow]
                self._judge_channels(t_us, j, e, False, verdict, statuses)
                continue
            if not e.available or not e.numerics_ok:
                j.start_us = None  # (re)starts: converge again
                reasons.append(f"{e.name}: {e.reason or 'numerical failure'}")
                continue
            if e.reinit:
                # the estimator says how long its fault estimates need to re-converge; the
                # operator is told when channels that were being judged stop being judged
                j.start_us = t_us + int(e.reinit_warmup_s * 1e6)
                if j.judging and j.notice is None:
                    verdict.events.append(self._notice(t_us, j, e, AlarmState.RAISED))
                j.judging = False
            misfit = self._inconsistent(t_us, e, j)
            # Filter convergence: fault estimates are not judged during the warm-up after an
            # estimator (re)starts (its start-up transient is up to 10x its converged
            # fault-free level; docs/results.md, "Detection and isolation with imu_ts").
            if j.start_us is None:
                j.start_us = t_us + self._warmup_us
            judged = t_us >= j.start_us and not misfit
            if misfit:
                reasons.append(misfit)
            elif judged:
                j.judging = True
                judged_any = True
                if j.notice is not None:
                    verdict.events.append(self._notice(t_us, j, e, AlarmState.CLEARED))
            else:
                reasons.append(f"{e.name}: warm-up")
            self._judge_channels(t_us, j, e, judged, verdict, statuses)
        if judged_any:
            verdict.status = FamilyStatus(self.name, t_us, True, inputs=inputs)
        elif self._est and not self._inputs:
            # a monitor that cannot judge says why: which input the telemetry never carried
            verdict.status = FamilyStatus(self.name, t_us, False, reason=self._missing(frame),
                                          inputs=False)
        elif reasons:
            verdict.status = FamilyStatus(self.name, t_us, False,
                                          reason="; ".join(dict.fromkeys(reasons)),
                                          inputs=inputs)
        return verdict

    def _missing(self, frame: Frame) -> str:
        """Which of the family's inputs the telemetry has not carried yet (all estimators
        need attitude and GPS velocity; GLOBAL_POSITION_INT's velocity counts only with a 3D
        fix)."""
        out = []
        if not self._seen_gps:
            fix = frame.gps_fix
            out.append(f"no GPS velocity: GPS without a 3D fix (fix type {fix})"
                       if 0 <= fix < GPS_FIX_3D else "no GPS velocity in the telemetry")
        if not self._seen_att:
            out.append("no attitude in the telemetry")
        return "; ".join(out)

    def _instances(self, frame: Frame) -> list[AlarmEvent]:
        """No-data check of every IMU instance that has delivered: silent for
        ``no_data_window_s`` while the primary delivers raises ``no_data`` on
        ``ChannelId("imu", i)`` with the remaining redundancy; it clears when it delivers."""
        t = frame.t_us
        seen = self._last_sample
        periods = self._instance_period
        outage = self._outage_us
        last, self._last_frame_us = self._last_frame_us, t
        if last is not None and t - last > self._no_data_us:
            # the whole vehicle was silent (a link outage, LINK/stale's business): that gap is
            # no evidence against one IMU; the first frame after it may come before the other
            # instances' samples of the same instant
            for i in seen:
                outage[i] = outage.get(i, 0) + t - last
        for i, smp in enumerate(frame.imu):
            if smp is not None and seen.get(i) != smp.t_us:
                seen[i] = smp.t_us
                outage[i] = 0
                per = periods.get(i)
                if per is None:
                    per = periods[i] = SamplePeriod()
                per.add(smp.t_us)
        if len(seen) < 2:
            return []
        # silent for the window, and for several of its own periods (one lost packet of a slow
        # stream is not a silent sensor)
        window = self._no_data_us
        silent = {i for i, ts in seen.items()
                  if (quiet := t - ts - outage.get(i, 0)) > window
                  and quiet > NO_DATA_PERIODS * periods[i].seconds() * 1e6}
        if not silent and not any(sm.active for sm in self._silent.values()):
            return []  # nothing silent, nothing to clear
        events: list[AlarmEvent] = []
        for i in sorted(seen):
            sm = self._silent.get(i)
            if sm is None:
                if i not in silent:
                    continue
                sm = self._silent[i] = AlarmStateMachine(
                    ChannelId("imu", i), AlarmKind.SENSOR_FAULT, "imu", params=self.ctx.alarm,
                    vehicle=self.ctx.vehicle)
            if (i in silent) != sm.active:
                n, left = len(seen), len(seen) - len(silent)
                msg = (f"IMU {i} silent for {(t - seen[i]) / US_PER_S:.1f} s: {left} of {n} "
                       f"IMUs deliver" if i in silent else f"IMU {i} delivers again: {left} of "
                       f"{n} IMUs deliver")
                events += sm.step(t, i in silent, fault_type=FaultType.NO_DATA, message=msg)
        return events

    @staticmethod
    def _any_alarm(j: _Judged) -> bool:
        """Some channel of the estimator is confirmed faulty or in alarm."""
        if j.bank is not None:
            return any(j.bank.in_alarm(c) for c in range(len(j.monitors)))
        return any(m.in_alarm for m in j.monitors)

    def _inconsistent(self, t_us: int, e: Estimate, j: _Judged) -> str:
        """Why an estimator's innovations do not fit its noise model (empty when they do, or
        when it does not report test ratios). While a channel of the estimator is in alarm its
        innovations carry a fault the filter may not have absorbed (the OTSEKF's under several
        faults), not evidence against the noise model: the average holds."""
        lim = self.cfg.max_inconsistency
        tr = e.states.get("test_ratio")
        if lim <= 0.0 or tr is None:
            return ""
        c = self._consistency.get(e.name)
        if c is None:
            c = self._consistency[e.name] = _Consistency(
                round(self.cfg.consistency_window_s * US_PER_S))
        if not self._any_alarm(j):
            c.add(t_us, self._gate2 * sum(tr.tolist()) / len(tr))
        if c.full(t_us) and c.mean() > lim:
            return (f"{e.name}: innovations {c.mean():.0f}x what its noise model expects: "
                    "calibrate this airframe (gcs-monitor calibrate)")
        return ""

    def _too_slow(self) -> str:
        """Why the IMU rate is outside the family's range (empty when it is inside or not
        measured yet)."""
        period = self._period.seconds()
        if not math.isfinite(period):
            return ""
        rate = 1.0 / period
        if rate < RATE_HZ[0]:
            # the rate of new samples: held repeats are not counted (module docstring)
            return f"IMU at {rate:.2g} Hz, below the {RATE_HZ[0]:g} Hz the IMU family needs"
        return ""

    def _judge_channels(self, t_us: int, j: _Judged, e: Estimate, judged: bool,
                        verdict: Verdict, statuses: list[ChannelStatus] | None) -> None:
        faults = e.faults
        chans = tuple(faults)
        if j.channels != chans:  # another IMU is monitored: its channels start afresh
            why = (f"not judged any more: {e.name} now monitors IMU {chans[0].instance}"
                   if chans else "not judged any more")
            for mon in j.monitors:
                verdict.events += mon.retire(t_us, why)
            j.channels, j.monitors, j.bank = chans, [], None
        if not j.monitors:
            if not judged:  # windows are sized when judging starts; until then J = 0
                if statuses is not None:
                    sets = j.sets
                    for ch, v in faults.items():
                        cfg = sets.acc if ch.kind == "acc" else sets.gyro
                        statuses.append(ChannelStatus(ch, t_us, v, 0.0, cfg.threshold, False,
                                                      e.name))
                return
            self._build_channels(j, e.name)
        values = list(faults.values())
        self._schedule(j)
        if j.bank is not None:  # one numba call for all channels
            ev = j.bank.update(t_us, values, judged, statuses)
            if ev:
                verdict.events += ev
        elif statuses is not None:
            for mon, value in zip(j.monitors, values, strict=False):
                st, ev = mon.step(t_us, value, judged)
                statuses.append(st)
                if ev:
                    verdict.events += ev
        else:
            for mon, value in zip(j.monitors, values, strict=False):
                ev = mon.update(t_us, value, judged)
                if ev:
                    verdict.events += ev

    def _schedule(self, j: _Judged) -> None:
        """The accelerometer channels' J_th: configured plus the reference allowance (gating.py
        item 3; 0 while the GPS reference is consistent with itself), frozen while a channel is
        in alarm (the allowance may prevent a raise, never clear one)."""
        th = j.sets.acc.threshold + self.reference_allowance_mps2
        bank = j.bank
        for c, mon in enumerate(j.monitors):
            if mon.channel.kind != "acc" or mon.p.threshold == th:
                continue
            if bank is not None:
                if not bank.in_alarm(c):
                    bank.set_threshold(c, th)
            elif not mon.in_alarm:
                mon.set_threshold(th)

    def _build_channels(self, j: _Judged, estimator: str) -> None:
        """Channel monitors with windows of the measured IMU period."""
        period_s = self._period.seconds()
        if not math.isfinite(period_s):
            raise RuntimeError("IMU judged before its sample period was measured")
        alarm, classifier = self.ctx.alarm, self.ctx.classifier
        params = {"acc": channel_params(j.sets.acc, period_s, alarm=alarm,
                                        classifier=classifier),
                  "gyro": channel_params(j.sets.gyro, period_s, alarm=alarm,
                                         classifier=classifier)}
        j.monitors = [ChannelMonitor(ch, params["acc" if ch.kind == "acc" else "gyro"],
                                     estimator=estimator, vehicle=self.ctx.vehicle)
                      for ch in j.channels]
        j.bank = ChannelBank.create(j.monitors)

    def _notice(self, t_us: int, j: _Judged, e: Estimate, state: AlarmState) -> AlarmEvent:
        """Operator notice of a state re-initialisation (never a sensor-fault alarm): raised
        when it happens, cleared when the fault channels are judged again."""
        cleared = state is AlarmState.CLEARED
        msg = ("fault channels judged again" if cleared else
               e.reinit + f"; fault channels not judged for {e.reinit_warmup_s:g} s")
        ev = AlarmEvent(t_us=t_us, channel=ChannelId("estimator", 0, e.name), state=state,
                        kind=AlarmKind.ESTIMATOR, fault_type=FaultType.UNKNOWN,
                        magnitude=math.nan, residual_rms=math.nan, threshold=math.nan,
                        estimator=e.name, message=msg, vehicle=self.ctx.vehicle)
        j.notice = None if cleared else ev
        return ev

    def update(self, frame: Frame, verdict: Verdict) -> list[Estimate]:
        """Nothing is fused back into the IMU estimators; their estimates of this Frame."""
        return self._estimates
