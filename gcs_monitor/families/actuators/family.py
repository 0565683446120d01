"""The actuator family: tiers that judge the control surfaces and the engine, composed.

A tier is one object with the family protocol (``predict`` / ``judge`` -> Verdict /
``update``, :class:`gcs_monitor.families.base.Family`) built from its configuration section
and the family context:

* ``aircraft`` (:mod:`.aircraft`): surfaces and engine from servo outputs or setpoints and the
  aircraft's response, for any autopilot;
* ``servo`` (:mod:`.servo`): Lu2017's IOTSEKF / RTS-EKF per surface where the telemetry reports
  surface and rod positions (SURF); without them it reports itself unavailable.

Per Frame every enabled tier runs its three phases; the family's verdict gathers the tiers'
events, channel statuses and estimates, and judges the Frame when any tier did.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from gcs_monitor.families.actuators.aircraft import AircraftTier
from gcs_monitor.families.actuators.config import ActuatorFamilyConfig
from gcs_monitor.families.actuators.servo import ServoTier
from gcs_monitor.families.base import Family, FamilyContext, Verdict
from gcs_monitor.fdi.records import Estimate, FamilyStatus
from gcs_monitor.telemetry.frame import Frame

# (configuration field of ActuatorFamilyConfig, builder) of every tier, in the order they run
TIERS: tuple[tuple[str, Callable[[Any, FamilyContext], Family]], ...] = (
    ("servo", ServoTier),
    ("aircraft", AircraftTier),
)
# the rates of the driving streams the tiers accept (control samples: servo outputs, setpoints)
RATE_HZ = (2.0, 400.0)


class ActuatorFamily:
    """Actuator and engine faults of one vehicle (see the module docstring)."""

    name = "actuators"

    def __init__(self, cfg: ActuatorFamilyConfig, ctx: FamilyContext) -> None:
        self.cfg = cfg
        self.ctx = ctx
        self.tiers: list[Family] = [build(getattr(cfg, field), ctx) for field, build in TIERS
                                    if getattr(cfg, field).enabled]

    def predict(self, frame: Frame) -> list[Any]:
        return [tier.predict(frame) for tier in self.tiers]

    def judge(self, frame: Frame, prediction: list[Any]) -> Verdict:
        t = frame.t_us
        if not self.tiers:
            return Verdict(FamilyStatus(self.name, t, False, reason="no tier enabled",
                                        inputs=False))
        verdicts = [tier.judge(frame, p) for tier, p in zip(self.tiers, prediction, strict=True)]
        self._verdicts = verdicts
        judged = sample = inputs = False
        for v in verdicts:
            st = v.status
            judged = judged or st.judged
            sample = sample or st.sample
            inputs = inputs or st.inputs
        reason = "" if judged else "; ".join(
            [f"{tier.name}: {v.status.reason}" for tier, v in zip(self.tiers, verdicts,
                                                                  strict=True)
             if v.status.reason])
        out = Verdict(FamilyStatus(self.name, t, judged, sample=sample, reason=reason,
                                   inputs=inputs))
        for v in verdicts:  # most Frames: nothing to gather
            if v.events:
                out.events += v.events
            if v.channels:
                out.channels += v.channels
            if v.sets:
                out.sets += v.sets
            if v.fused:
                out.fused.update(v.fused)
        return out

    def update(self, frame: Frame, verdict: Verdict) -> list[Estimate]:
        out: list[Estimate] = []
        for tier, v in zip(self.tiers, self._verdicts, strict=True):
            out += tier.update(frame, v)
        return out
