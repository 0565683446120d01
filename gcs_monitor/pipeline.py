"""VehiclePipeline: one vehicle's Frames through its monitored families to the sinks.

Per Frame every family predicts, its FDI judges the sample against the prediction (Wan2018
eq. 17 needs the prediction before the update), and it updates with what the vote kept
(:mod:`gcs_monitor.families.base`); the alarm events, statuses and estimates of all families go
to the sinks together.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from gcs_monitor.core.types import ChannelId
from gcs_monitor.families import registry
from gcs_monitor.families.base import Family, FamilyContext
from gcs_monitor.fdi.alarms import AlarmParams
from gcs_monitor.fdi.coverage import CoverageConfig, FamilyCoverage
from gcs_monitor.fdi.events import AlarmEvent, AlarmState
from gcs_monitor.fdi.records import FamilyStatus, StepOutput
from gcs_monitor.sinks import Sink
from gcs_monitor.telemetry.frame import Frame


def build_families(configs: dict[str, Any], ctx: FamilyContext) -> list[Family]:
    """The enabled families of ``configs`` (name -> family configuration), in registry order."""
    return [spec.build(configs[spec.name], ctx) for spec in registry.FAMILIES
            if spec.name in configs and configs[spec.name].enabled]


class VehiclePipeline:
    """The whole chain for one vehicle.

    Parameters
    ----------
    vehicle : MAVLink sysid
    families : the monitored families, in the order they run
    sinks : publishers (Rerun, Zenoh, journal)
    coverage : when a family counts as judging (monitor_degraded alarms)
    alarm : alarm update policy
    statuses : put each family's coverage in every StepOutput (off when nobody reads it)
    """

    def __init__(self, vehicle: int, families: Sequence[Family], *,
                 sinks: Sequence[Sink] = (), coverage: CoverageConfig | None = None,
                 alarm: AlarmParams | None = None, statuses: bool = True) -> None:
        self.vehicle = vehicle
        self.statuses = statuses  # coverage records per Frame (for sinks and callbacks)
        self.families = list(families)
        self.sinks = list(sinks)
        cov = coverage if coverage is not None else CoverageConfig()
        self.coverage = {f.name: FamilyCoverage(f.name, cov, vehicle=vehicle, alarm=alarm)
                         for f in self.families}
        self.frames = 0
        # active alarms by (channel, estimator): two families may judge one channel (the IMU
        # family's imu_ts and the yaw-rate family both reconstruct the yaw-rate gyro's fault)
        self.active: dict[tuple[ChannelId, str], AlarmEvent] = {}
        # each family's account of its latest sample (Frames without one do not replace it)
        self.status: dict[str, FamilyStatus] = {}
        # whether a family reads Frame.gps_interp_err_ned_mps (the assembler computes it only
        # then: it is the cost of the IMU samples of every GPS interval)
        self.reads_interp_error = any(getattr(f, "reads_interp_error", False)
                                      for f in self.families)

    def step(self, frame: Frame, extra_events: Sequence[AlarmEvent] = ()) -> StepOutput:
        """Run one Frame through the families and the sinks; ``extra_events`` (link alarms) are
        published with this Frame's output."""
        out = StepOutput(events=list(extra_events))
        self.frames += 1
        for family in self.families:
            prediction = family.predict(frame)
            verdict = family.judge(frame, prediction)
            out.estimates += family.update(frame, verdict)
            out.events += verdict.events
            out.sets += verdict.sets
            out.channels += verdict.channels
            out.families.append(verdict.status)
            if verdict.status.sample or family.name not in self.status:
                self.status[family.name] = verdict.status
            cov = self.coverage[family.name]
            degraded = cov.step(verdict.status)
            if degraded:
                out.events += degraded
            if self.statuses:
                out.coverage.append(cov.coverage)
        for event in out.events:
            if event.state is AlarmState.CLEARED:
                self.active.pop((event.channel, event.estimator), None)
            else:
                self.active[(event.channel, event.estimator)] = event
        for sink in self.sinks:
            sink.publish(frame, out)
        return out

    def health(self) -> dict[str, Any]:
        return {
            "vehicle": self.vehicle,
            "frames": self.frames,
            "active_alarms": [
                {"channel": str(ch), "estimator": est, "kind": ev.kind.value,
                 "fault_type": ev.fault_type.value, "confidence": ev.confidence,
                 "magnitude": ev.magnitude, "since_t_us": ev.t_us}
                for (ch, est), ev in sorted(self.active.items(), key=lambda kv: kv[0])
            ],
        }

    def close(self) -> None:
        for sink in self.sinks:
            sink.close()
