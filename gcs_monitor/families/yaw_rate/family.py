"""The yaw-rate family: a lateral gyro's fault reconstructed by the Chen2020 observer, judged
as one channel of the shared FDI layer.

``predict`` steps the observer when a step is due (every ``[yaw_rate.observer] step_s`` of
vehicle time; None on the Frames in between); ``judge`` windows the reconstructed fault
(Wan2018 eq. 18 with r = f_hat), confirms, classifies and raises ``sensor_fault`` on
``ChannelId("gyro", i, "r")`` (or ``"p"``) of the primary IMU ``i``; ``update`` returns the
estimate, whose ``virtual`` entry is the corrected gyro (Chen2020 eq. 24).

The family judges only where its model holds: all inputs present (attitude, sideslip, body
rates, surfaces, airspeed) and the equivalent airspeed inside the design's range (Chen2020's
set Omega). Until the telemetry has carried all of them at once inside that range the family is
unavailable (a copter, a log without sideslip or surfaces, another aircraft's speeds), with the
missing input as the reason; afterwards a missing input is a loss of coverage.
"""

from __future__ import annotations

import math

from gcs_monitor.families.base import FamilyContext, Verdict
from gcs_monitor.families.yaw_rate.config import YawRateFamilyConfig
from gcs_monitor.families.yaw_rate.estimator import YawRateEstimator
from gcs_monitor.fdi.config import channel_params
from gcs_monitor.fdi.monitor import ChannelMonitor
from gcs_monitor.fdi.records import Estimate, FamilyStatus
from gcs_monitor.telemetry.frame import Frame
from gcs_monitor.telemetry.period import SamplePeriod

US_PER_S = 1_000_000
# Frame rates the observer is valid for: its explicit Euler step k dt / delta must stay below 2
# (k = 0.8, delta = 0.01: dt < 25 ms) and it steps at most every Frame
RATE_HZ = (45.0, 1000.0)


class YawRateFamily:
    """Lateral gyro fault channel of one vehicle (see the module docstring)."""

    name = "yaw_rate"

    def __init__(self, cfg: YawRateFamilyConfig, ctx: FamilyContext, *,
                 estimator: YawRateEstimator | None = None) -> None:
        self.cfg = cfg
        self.ctx = ctx
        self.estimator = estimator if estimator is not None else YawRateEstimator(
            cfg, stale_s=ctx.stale_after_s, shared=ctx.shared)
        self._frames = SamplePeriod()  # Frame period (rate range)
        self._steps = SamplePeriod()  # observer step period (FDI windows)
        self._warmup_us = round(cfg.warmup_s * US_PER_S)
        self._start_us: int | None = None
        self._monitor: ChannelMonitor | None = None
        self._estimate: Estimate | None = None
        self._inputs = False

    def predict(self, frame: Frame) -> Estimate | None:
        """The observer's step on this Frame when one is due, else None."""
        self._frames.add(frame.t_us)
        if not self.estimator.due(frame):
            return None
        e = self.estimator.step(frame)
        if e.available:
            self._steps.add(frame.t_us)
            self._estimate = e
        else:
            self._steps.gap()
        return e

    def _slow(self) -> str:
        period = self._frames.seconds()
        if math.isfinite(period) and 1.0 / period < RATE_HZ[0]:
            return (f"Frames at {1.0 / period:.0f} Hz, below the {RATE_HZ[0]:g} Hz the yaw-rate "
                    "observer needs")
        return ""

    def judge(self, frame: Frame, prediction: Estimate | None) -> Verdict:
        t = frame.t_us
        name = self.name
        if prediction is None:
            return Verdict(FamilyStatus(name, t, False, sample=False,
                                        reason="between observer steps", inputs=self._inputs))
        e = prediction
        if not e.available or not e.numerics_ok:
            return Verdict(FamilyStatus(name, t, False, reason=e.reason or "numerical failure",
                                        inputs=self._inputs))
        self._inputs = True
        slow = self._slow()
        if slow:
            self.estimator.reset()  # starts afresh (and warms up) once the rate is back
            return Verdict(FamilyStatus(name, t, False, reason=slow))
        if e.reinit:  # a fresh start; re-anchoring over a gap does not pause judging
            self._start_us = t + self._warmup_us
        judged = self._start_us is not None and t >= self._start_us
        verdict = Verdict(FamilyStatus(name, t, judged, reason="" if judged else "warm-up"))
        ((ch, value),) = e.faults.items()
        mon = self._monitor
        if mon is not None and mon.channel != ch:  # another IMU is primary: start afresh
            verdict.events += mon.retire(t, f"not judged any more: IMU {ch.instance} is primary")
            mon = self._monitor = None
        if mon is None and judged:
            period = self._steps.seconds()
            if not math.isfinite(period):
                return verdict
            mon = self._monitor = ChannelMonitor(
                ch, channel_params(self.cfg.fdi, period, alarm=self.ctx.alarm,
                                   classifier=self.ctx.classifier),
                estimator=e.name, vehicle=self.ctx.vehicle)
        if mon is not None:
            if self.ctx.statuses:
                st, ev = mon.step(t, value, judged)
                verdict.channels.append(st)
            else:
                ev = mon.update(t, value, judged)
            verdict.events += ev
        return verdict

    def update(self, frame: Frame, verdict: Verdict) -> list[Estimate]:
        """Nothing is fed back; the latest estimate (fault, corrected gyro, state)."""
        return [self._estimate] if self._estimate is not None else []
