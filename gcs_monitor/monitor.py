"""Monitor: link bytes -> per-vehicle Frames -> VehiclePipelines -> alarms, health.

One process serves many vehicles: decoded messages are demultiplexed by sysid; each vehicle
gets its own FrameAssembler and, once it produces Frames, its own VehiclePipeline with its own
estimators and sinks. Link problems (loss, CRC errors, stale stream, reboot) are LINK alarms
from the link statistics, never sensor-fault alarms. Vehicle time drives everything, so the same
bytes give the same alarms.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

from gcs_monitor.config import MonitorConfig
from gcs_monitor.estimators.base import Estimator
from gcs_monitor.fdi.alarms import LinkAlarmMonitor
from gcs_monitor.fdi.events import AlarmEvent
from gcs_monitor.link.decode import Decoder
from gcs_monitor.pipeline import PipelineStep, VehiclePipeline
from gcs_monitor.sinks import Sink
from gcs_monitor.telemetry.assembler import FrameAssembler

log = logging.getLogger(__name__)

LINK_CHECK_US = 1_000_000  # link statistics -> LINK alarms once per second of vehicle time
GCS_SYSIDS = frozenset({255})  # ground stations: never monitored as vehicles


def wind_envelope(cfg: MonitorConfig) -> Any:
    """The declared weather of ``cfg.airdata`` as the model's WindEnvelope (Wan2018 eq. 21b)."""
    import dataclasses

    from gcs_monitor.models.airdata import WindEnvelope

    a = cfg.airdata  # AirDataConfig carries every WindEnvelope field under the same name
    return WindEnvelope(**{f.name: getattr(a, f.name) for f in dataclasses.fields(WindEnvelope)})


def build_estimators(cfg: MonitorConfig) -> tuple[list[Estimator], Any | None]:
    """The IMU estimators and the air-data estimator the configuration asks for."""
    imu: list[Estimator] = []
    if cfg.estimators.imu_ts:
        from gcs_monitor.estimators.imu_ts import ImuTwoStageEstimator

        imu.append(ImuTwoStageEstimator())
    if cfg.estimators.imu_hosm:
        from gcs_monitor.estimators.imu_hosm import ImuHosmEstimator

        imu.append(ImuHosmEstimator())
    airdata = None
    if cfg.estimators.airdata != "none":
        from gcs_monitor.estimators.airdata import AirDataEstimator, AirDataEstimatorConfig

        est_cfg = AirDataEstimatorConfig(envelope=wind_envelope(cfg),
                                         wind_accel_in_alpha=cfg.airdata.wind_accel_in_alpha,
                                         lateral_terms=cfg.airdata.lateral_terms)
        airdata = AirDataEstimator(est_cfg, variant=cfg.estimators.airdata)
    return imu, airdata


@dataclass
class VehicleState:
    sysid: int
    assembler: FrameAssembler
    pipeline: VehiclePipeline | None = None
    link_alarms: LinkAlarmMonitor | None = None
    next_link_check_us: int = 0
    last_t_us: int = 0
    events: int = 0
    steps: list[PipelineStep] = field(default_factory=list)


class Monitor:
    """The ground-station monitor for any number of vehicles on one link.

    Parameters
    ----------
    cfg : monitor configuration
    sinks_for : builds the sinks of a newly seen vehicle (Rerun, Zenoh, journal ...)
    estimators_for : builds a vehicle's (imu_estimators, airdata); default from ``cfg``
    on_step : called with (sysid, frame, PipelineStep) after each Frame (evaluation harness)
    raw_sink : called with every decoded message (raw input recording)
    """

    def __init__(self, cfg: MonitorConfig | None = None, *,
                 sinks_for: Callable[[int], Sequence[Sink]] = lambda sysid: (),
                 estimators_for: Callable[[int], tuple[list[Estimator], Any | None]] | None = None,
                 on_step: Callable[[int, Any, PipelineStep], None] | None = None,
                 decoder: Decoder | None = None,
                 raw_sink: Callable[[Any], None] | None = None) -> None:
        self.cfg = cfg or MonitorConfig()
        self.decoder = decoder or Decoder()
        self.sinks_for = sinks_for
        self.estimators_for = estimators_for or (lambda sysid: build_estimators(self.cfg))
        self.on_step = on_step
        self.raw_sink = raw_sink
        self.vehicles: dict[int, VehicleState] = {}
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
            imu, airdata = self.estimators_for(v.sysid)
            v.pipeline = VehiclePipeline(v.sysid, self.cfg, imu_estimators=imu, airdata=airdata,
                                         sinks=list(self.sinks_for(v.sysid)))
            v.pipeline.channel_status = self._channel_status(v.pipeline)
            v.link_alarms = LinkAlarmMonitor(vehicle=v.sysid)
            log.info("vehicle %d: pipeline started", v.sysid)
        return v.pipeline

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
        if v.assembler.reboot_pending:  # autopilot reboot: estimators and FDI start afresh
            v.assembler.reboot_pending = False
            for est in pipe.imu_estimators:
                est.reset()
            if pipe.airdata is not None:
                pipe.airdata.reset()
            # FDI windows, latches and the air-data predictions describe the old flight: a new
            # pipeline with the same (reset) estimators and the same sinks starts them afresh.
            pipe = v.pipeline = VehiclePipeline(v.sysid, self.cfg,
                                                imu_estimators=pipe.imu_estimators,
                                                airdata=pipe.airdata, sinks=pipe.sinks)
            pipe.channel_status = self._channel_status(pipe)
            # vehicle time restarted: without this no link check (and no LINK/reboot alarm)
            # would run until the new clock passed the old one
            v.next_link_check_us = 0
        out: list[AlarmEvent] = []
        for frame in frames:
            extra: list[AlarmEvent] = []
            if frame.t_us >= v.next_link_check_us and v.link_alarms is not None:
                v.next_link_check_us = frame.t_us + LINK_CHECK_US
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

    def _channel_status(self, pipe: VehiclePipeline) -> bool:
        """Per-channel status records are built only when a sink or ``on_step`` reads them."""
        return bool(pipe.sinks) or self.on_step is not None

    def _link_stats(self, v: VehicleState) -> dict[str, float]:
        st = v.assembler.stats
        return {"loss_pct": st.loss_pct, "crc_errors": float(self.decoder.counters.parse_errors),
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
                "estimators": estimator_availability(avail),
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


def estimator_availability(avail: dict[str, Any]) -> dict[str, str]:
    """Which estimators and redundant sets have their inputs on this vehicle's telemetry."""
    imu = avail["imu_instances"] > 0
    att = avail["attitude"]
    gps = avail["gps_velocity"]
    out = {}
    gs = imu and att and gps
    missing = [n for n, ok in (("IMU", imu), ("attitude", att), ("GPS velocity", gps)) if not ok]
    why = "missing " + ", ".join(missing)
    out["imu_ts (Lu2016 ATSEKF)"] = "available" if gs else why
    out["imu_hosm (Atmaca2025)"] = "available" if gs else why
    air = avail["aoa_instances"] > 0 and avail["cas_instances"] > 0 and avail["baro"]
    out["airdata (Wan2018 MHE)"] = ("available" if air and gs else
                                    "missing " + ", ".join(n for n, ok in (
                                        ("AoA", avail["aoa_instances"] > 0),
                                        ("CAS", avail["cas_instances"] > 0),
                                        ("baro", avail["baro"]), ("IMU/attitude/GPS", gs))
                                        if not ok))
    out["set aoa"] = f"{avail['aoa_instances']} instance(s)"
    out["set cas"] = f"{avail['cas_instances']} instance(s)"
    out["actuator (Lu2017)"] = "available" if avail["surfaces"] else "missing surface feedback"
    return out
