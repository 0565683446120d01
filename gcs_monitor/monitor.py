"""Monitor: link bytes -> per-vehicle Frames -> VehiclePipelines -> alarms, health.

One process serves many vehicles: decoded messages are demultiplexed by sysid; each vehicle
gets its own FrameAssembler and, once it produces Frames, its own VehiclePipeline with its own
estimators and sinks. Link problems (loss, CRC errors, stale stream, reboot) are LINK alarms
from the link statistics, never sensor-fault alarms. Vehicle time drives everything, so the same
bytes give the same alarms.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

from gcs_monitor.config import MonitorConfig
from gcs_monitor.families import registry
from gcs_monitor.families.base import Family, FamilyContext
from gcs_monitor.fdi.alarms import LinkAlarmMonitor
from gcs_monitor.fdi.events import AlarmEvent
from gcs_monitor.fdi.records import StepOutput
from gcs_monitor.link.decode import Decoder
from gcs_monitor.pipeline import VehiclePipeline, build_families
from gcs_monitor.sinks import Sink
from gcs_monitor.telemetry.assembler import FrameAssembler

log = logging.getLogger(__name__)

GCS_SYSIDS = frozenset({255})  # ground stations: never monitored as vehicles


@dataclass
class VehicleState:
    sysid: int
    assembler: FrameAssembler
    pipeline: VehiclePipeline | None = None
    link_alarms: LinkAlarmMonitor | None = None
    next_link_check_us: int = 0
    last_t_us: int = 0
    events: int = 0
    steps: list[StepOutput] = field(default_factory=list)


class Monitor:
    """The ground-station monitor for any number of vehicles on one link.

    Parameters
    ----------
    cfg : monitor configuration
    sinks_for : builds the sinks of a newly seen vehicle (Rerun, Zenoh, journal ...)
    families_for : builds a vehicle's families from its sysid and context; default: the
        enabled families of ``cfg`` (tests give scripted ones)
    on_step : called with (sysid, frame, StepOutput) after each Frame (evaluation harness)
    raw_sink : called with every decoded message (raw input recording)
    """

    def __init__(self, cfg: MonitorConfig | None = None, *,
                 sinks_for: Callable[[int], Sequence[Sink]] = lambda sysid: (),
                 families_for: Callable[[FamilyContext], list[Family]] | None = None,
                 on_step: Callable[[int, Any, StepOutput], None] | None = None,
                 decoder: Decoder | None = None,
                 raw_sink: Callable[[Any], None] | None = None) -> None:
        self.cfg = cfg or MonitorConfig()
        self.decoder = decoder or Decoder()
        self.sinks_for = sinks_for
        self.families_for = families_for or (
            lambda ctx: build_families(dict(self.cfg.families), ctx))
        self.on_step = on_step
        self.raw_sink = raw_sink
        self.vehicles: dict[int, VehicleState] = {}
        self._link_check_us = round(self.cfg.link.check_period_s * 1e6)
        self.events: list[AlarmEvent] = []
        self.source_counters: dict[str, int] = {}

    def _vehicle(self, sysid: int) -> VehicleState:
        v = self.vehicles.get(sysid)
        if v is None:
            stats = self.decoder.vehicle_stats(sysid)
            tel = self.cfg.telemetry
            # aligned: every input of a Frame is at t_us, GPS velocity interpolated exactly
            # between the samples bracketing it; frames leave gps_delay_s behind the newest data
            v = VehicleState(sysid, FrameAssembler.aligned(tel, stats))
            self.vehicles[sysid] = v
        return v

    def _pipeline(self, v: VehicleState) -> VehiclePipeline:
        if v.pipeline is None:
            v.pipeline = self._new_pipeline(v.sysid, list(self.sinks_for(v.sysid)))
            v.link_alarms = LinkAlarmMonitor(params=self.cfg.link, vehicle=v.sysid,
                                             alarm=self.cfg.alarms)
            log.info("vehicle %d: pipeline started", v.sysid)
        return v.pipeline

    def _new_pipeline(self, sysid: int, sinks: list[Sink]) -> VehiclePipeline:
        # per-channel status records are built only when a sink or ``on_step`` reads them
        ctx = FamilyContext(vehicle=sysid, stale_after_s=self.cfg.telemetry.stale_after_s,
                            statuses=bool(sinks) or self.on_step is not None,
                            alarm=self.cfg.alarms, classifier=self.cfg.classifier)
        return VehiclePipeline(sysid, self.families_for(ctx), sinks=sinks,
                               coverage=self.cfg.coverage, alarm=self.cfg.alarms,
                               statuses=ctx.statuses)

    def feed(self, data: bytes, wall_s: float = 0.0) -> list[AlarmEvent]:
        """Decode a chunk and run every Frame it completes; return the alarm events."""
        out: list[AlarmEvent] = []
        raw = self.raw_sink
        last_sysid = -1  # messages of one vehicle come in runs: look its state up once per run
        v: VehicleState | None = None
        push: Callable[[Any], list[Any]] | None = None
        for msg in self.decoder.feed(data, wall_s):
            if raw is not None:
                msg._timestamp = wall_s
                raw(msg)
            sysid = msg._header.srcSystem
            if sysid != last_sysid:
                if sysid in GCS_SYSIDS:
                    continue
                v = self._vehicle(sysid)
                push = v.assembler.push
                last_sysid = sysid
            frames = push(msg)  # type: ignore[misc]
            if frames:
                out += self._run(v, frames)  # type: ignore[arg-type]
        return out

    def _run(self, v: VehicleState, frames: Iterable[Any]) -> list[AlarmEvent]:
        pipe = self._pipeline(v)
        v.assembler.reboot_pending = False  # the first new-clock frame carries reset=True
        out: list[AlarmEvent] = []
        for frame in frames:
            if frame.reset:  # autopilot reboot: estimators and FDI start afresh
                # estimator states, FDI windows, latches and predictions describe the old
                # flight (whose held frames came first): new families with the same sinks
                pipe = v.pipeline = self._new_pipeline(v.sysid, pipe.sinks)
                # vehicle time restarted: without this no link check (and no LINK/reboot alarm)
                # would run until the new clock passed the old one
                v.next_link_check_us = 0
            extra: list[AlarmEvent] = []
            if frame.t_us >= v.next_link_check_us and v.link_alarms is not None:
                v.next_link_check_us = frame.t_us + self._link_check_us
                extra = v.link_alarms.step(frame.t_us, self._link_stats(v))
            step = pipe.step(frame, extra)
            v.last_t_us = frame.t_us
            if step.events:
                out += step.events
                v.events += len(step.events)
            if self.on_step is not None:
                self.on_step(v.sysid, frame, step)
        self.events += out
        return out

    def _link_stats(self, v: VehicleState) -> dict[str, float]:
        st = v.assembler.stats
        return {"lost": float(st.lost), "messages": float(st.messages),
                "crc_errors": float(self.decoder.counters.parse_errors),
                "boot_count": float(st.reboots), "duplicate_sysid": float(st.duplicate_sysid)}

    def finish(self) -> list[AlarmEvent]:
        """End of input: decode bytes still held, then flush held frames through the pipelines."""
        out: list[AlarmEvent] = []
        for msg in self.decoder.flush():
            sysid = msg._header.srcSystem
            if sysid not in GCS_SYSIDS:
                frames = self._vehicle(sysid).assembler.push(msg)
                if frames:
                    out += self._run(self._vehicle(sysid), frames)
        for v in self.vehicles.values():
            frames = v.assembler.flush()
            if frames:
                out += self._run(v, frames)
        return out

    def health(self) -> dict[str, Any]:
        vehicles = {}
        for sysid, v in self.vehicles.items():
            avail = v.assembler.availability()
            vehicles[str(sysid)] = {
                "link": v.assembler.stats.as_dict(),
                "inputs": avail,
                "families": family_availability(avail, self.cfg.families, v.pipeline),
                "alarms": v.pipeline.health()["active_alarms"] if v.pipeline else [],
                "vehicle_time_s": v.last_t_us * 1e-6,
                "sinks": [sink_health(s) for s in v.pipeline.sinks] if v.pipeline else [],
            }
        return {"link": self.decoder.counters.as_dict() | self.source_counters,
                "vehicles": vehicles}

    def publish_health(self) -> None:
        h = self.health()
        for v in self.vehicles.values():
            if v.pipeline is not None:
                for sink in v.pipeline.sinks:
                    sink.update_health(h)

    def close(self) -> None:
        self.publish_health()
        for v in self.vehicles.values():
            if v.pipeline is not None:
                v.pipeline.close()


def sink_health(sink: Any) -> dict[str, Any]:
    """A sink's own counters (a Zenoh session that failed, payloads dropped) for health."""
    out: dict[str, Any] = {"sink": type(sink).__name__}
    for k in ("active", "n_published", "n_dropped", "n_errors"):
        v = getattr(sink, k, None)
        if isinstance(v, bool | int | float):
            out[k] = v
    return out


def family_availability(avail: dict[str, Any], configs: Any,
                        pipeline: VehiclePipeline | None) -> dict[str, dict[str, Any]]:
    """Per registered family: ``state`` (judging, degraded, starting, unavailable, disabled),
    its coverage (the share of the last window and of the flight it judged) and the reason it
    did not judge; "available" means judging."""
    out: dict[str, dict[str, Any]] = {}
    for spec in registry.FAMILIES:
        cfg = configs.get(spec.name)
        row: dict[str, Any] = {"title": spec.title, "coverage_recent": math.nan,
                               "coverage_overall": math.nan}
        if cfg is None or not cfg.enabled:
            out[spec.name] = row | {"state": "disabled", "reason": ""}
            continue
        cov = pipeline.coverage.get(spec.name) if pipeline is not None else None
        missing = spec.missing_inputs(avail)
        if cov is None or cov.state == "unavailable":
            why = ("missing " + ", ".join(missing)) if missing else (
                cov.coverage.reason if cov is not None else "no frame yet")
            out[spec.name] = row | {"state": "unavailable", "reason": why}
            continue
        c = cov.coverage
        out[spec.name] = row | {"state": c.state, "reason": c.reason,
                                "coverage_recent": c.recent, "coverage_overall": c.overall}
    return out
