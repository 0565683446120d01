"""A toy family for the extension test: the baro climb rate against the GPS vertical speed.

It is what a new family is: one module (a package in gcs_monitor/families/ in real life) with
its configuration, its family class and its registry entry, and one line in the registry.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from gcs_monitor.core.params import MPS, param, section
from gcs_monitor.core.types import ChannelId
from gcs_monitor.families.base import FamilyContext, FamilySpec, FamilyViews, PlotSpec, Verdict
from gcs_monitor.fdi.config import ChannelSetConfig, channel_params
from gcs_monitor.fdi.monitor import ChannelMonitor
from gcs_monitor.fdi.records import Estimate, FamilyStatus
from gcs_monitor.telemetry.frame import Frame
from gcs_monitor.telemetry.period import SamplePeriod

CHANNEL = ChannelId("vspeed", 0)


@dataclass(frozen=True, slots=True)
class VSpeedConfig:
    """Toy family: baro climb rate against the GPS vertical speed."""

    enabled: bool = param(True, "monitor the vertical speed")
    fdi: ChannelSetConfig = section(
        lambda: ChannelSetConfig(threshold=1.0, window_s=0.5, detect_ratio=0.5, clear_s=1.0,
                                 latch=False, noise_sigma=0.1, runaway_rate=1.0, history_s=2.0,
                                 reclassify_s=0.5),
        "the climb residual channel", unit=MPS)


class VSpeedFamily:
    name = "vspeed"

    def __init__(self, cfg: VSpeedConfig, ctx: FamilyContext) -> None:
        self.cfg, self.ctx = cfg, ctx
        self.period = SamplePeriod()
        self.monitor: ChannelMonitor | None = None

    def predict(self, frame: Frame) -> float | None:
        self.period.add(frame.t_us)
        v = frame.gps_vel_ned_mps
        return None if v is None else -float(v[2])

    def judge(self, frame: Frame, prediction: float | None) -> Verdict:
        t = frame.t_us
        if prediction is None or not math.isfinite(frame.climb_mps) or not self.period.known:
            return Verdict(FamilyStatus(self.name, t, False, reason="no climb or GPS velocity"))
        if self.monitor is None:
            self.monitor = ChannelMonitor(
                CHANNEL, channel_params(self.cfg.fdi, self.period.seconds()), estimator="toy",
                vehicle=self.ctx.vehicle)
        st, events = self.monitor.step(t, frame.climb_mps - prediction, True)
        return Verdict(FamilyStatus(self.name, t, True), events=events, channels=[st])

    def update(self, frame: Frame, verdict: Verdict) -> list[Estimate]:
        return []


SPEC = FamilySpec(
    name="vspeed", title="toy: baro climb vs GPS vertical speed", config=VSpeedConfig,
    build=VSpeedFamily, inputs=(("baro", "baro"), ("gps_velocity", "GPS velocity")),
    rate_hz=(1.0, 400.0),
    views=lambda cfg: FamilyViews("Vertical speed", (("vspeed", (
        PlotSpec("climb residual", ("channels", "vspeed")),)),)))
