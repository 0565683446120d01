"""VehiclePipeline: wires telemetry Frames -> estimators -> FDI -> sinks for one sysid.

Ordering per air-data sample (Wan2018 sec. III-A): residuals of each redundant AoA/CAS
instance are taken against the model's one-step-ahead prediction from the previous sample
(eq. 17); the FDI layer windows them (eq. 18), confirms, isolates and fuses the healthy
instances (eq. 19); the fused values are the MHE's measurements for this sample. Without a
model-based air-data estimator the residuals are taken against the set's own consensus.
IMU fault estimates (Lu2016 f_hat) are monitored per channel.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gcs_monitor.config import MonitorConfig, SetConfig
from gcs_monitor.core.types import ChannelId
from gcs_monitor.core.units import DEG2RAD, KT2MPS
from gcs_monitor.estimators.base import Estimate, Estimator
from gcs_monitor.fdi.confirmation import ConfirmationParams
from gcs_monitor.fdi.events import AlarmEvent, ChannelStatus, SetStatus
from gcs_monitor.fdi.monitor import (
    ChannelMonitor,
    ChannelMonitorParams,
    RedundantSetMonitor,
    SetMonitorParams,
)
from gcs_monitor.fdi.residuals import RmsWindowParams
from gcs_monitor.sinks import Sink
from gcs_monitor.telemetry.frame import Frame

# Noise levels and runaway boundaries the classifier uses per set (SI). The AoA/CAS noise is the
# simulated vanes' / pitots' (Lu2016 Table 1: sigma_alpha = 0.1 deg; CAS 0.1 m/s ~ sigma_V); the
# runaway boundaries separate Wan2018 Table II drifts from runaways.
SET_NOISE = {"aoa": 0.1 * DEG2RAD, "cas": 0.1, "acc": 0.05, "gyro": 0.05 * DEG2RAD}
SET_RUNAWAY_RATE = {"aoa": 1.0 * DEG2RAD, "cas": 2.0 * KT2MPS, "acc": 1.0, "gyro": 1.0 * DEG2RAD}
AIR_DT_S = 0.05  # air-data sample interval (20 Hz, docs/telemetry.md)
IMU_DT_S = 0.01


def set_params(name: str, cfg: SetConfig, dt_s: float) -> SetMonitorParams:
    return SetMonitorParams(
        threshold=cfg.threshold, noise_sigma=SET_NOISE[name],
        runaway_rate_per_s=SET_RUNAWAY_RATE[name], dt_s=dt_s,
        rms=RmsWindowParams(rms_window_n=cfg.n_eval),
        confirmation=ConfirmationParams(detect_n=cfg.n_detect, eval_n=cfg.n_eval,
                                        clear_ratio=cfg.clear_ratio, clear_n=cfg.n_clear,
                                        latch=cfg.latch),
    )


def channel_params(name: str, cfg: SetConfig, dt_s: float) -> ChannelMonitorParams:
    return ChannelMonitorParams(
        threshold=cfg.threshold, noise_sigma=SET_NOISE[name],
        runaway_rate_per_s=SET_RUNAWAY_RATE[name], dt_s=dt_s,
        rms=RmsWindowParams(rms_window_n=cfg.n_eval),
        confirmation=ConfirmationParams(detect_n=cfg.n_detect, eval_n=cfg.n_eval,
                                        clear_ratio=cfg.clear_ratio, clear_n=cfg.n_clear,
                                        latch=cfg.latch),
    )


@dataclass
class PipelineStep:
    """What one Frame produced (for tests, the evaluation harness and the sinks)."""

    events: list[AlarmEvent] = field(default_factory=list)
    estimates: list[Estimate] = field(default_factory=list)
    sets: list[SetStatus] = field(default_factory=list)
    channels: list[ChannelStatus] = field(default_factory=list)


class VehiclePipeline:
    """The whole chain for one vehicle.

    Parameters
    ----------
    vehicle : MAVLink sysid
    cfg : monitor configuration
    imu_estimators : estimators whose ``faults`` are monitored per channel (Lu2016/Atmaca2025)
    airdata : Wan2018 air-data estimator (``set_fused_measurements`` + ``step``), or None for
        set-internal consensus residuals
    sinks : publishers (Rerun, Zenoh, journal)
    """

    def __init__(self, vehicle: int, cfg: MonitorConfig, *,
                 imu_estimators: Sequence[Estimator] = (), airdata: Any | None = None,
                 sinks: Sequence[Sink] = (), n_aoa: int = 3, n_cas: int = 3) -> None:
        self.vehicle = vehicle
        self.cfg = cfg
        self.imu_estimators = list(imu_estimators)
        self.airdata = airdata
        self.sinks = list(sinks)
        ref_name = airdata.name if airdata is not None else "voting"
        self.aoa_set = RedundantSetMonitor("aoa", n_aoa, set_params("aoa", cfg.fdi.aoa, AIR_DT_S),
                                           estimator=ref_name, vehicle=vehicle)
        self.cas_set = RedundantSetMonitor("cas", n_cas, set_params("cas", cfg.fdi.cas, AIR_DT_S),
                                           estimator=ref_name, vehicle=vehicle)
        self._channels: dict[tuple[str, ChannelId], ChannelMonitor] = {}
        self._aoa_pred = math.nan
        self._cas_pred = math.nan
        self._last_sets: list[SetStatus] = []
        self._airdata_estimate: Estimate | None = None
        self.frames = 0
        self.active: dict[ChannelId, AlarmEvent] = {}

    def _channel(self, estimator: str, ch: ChannelId) -> ChannelMonitor:
        key = (estimator, ch)
        mon = self._channels.get(key)
        if mon is None:
            kind = "acc" if ch.kind == "acc" else "gyro"
            cfg = self.cfg.fdi.acc if kind == "acc" else self.cfg.fdi.gyro
            mon = ChannelMonitor(ch, channel_params(kind, cfg, IMU_DT_S), estimator=estimator,
                                 vehicle=self.vehicle)
            self._channels[key] = mon
        return mon

    def step(self, frame: Frame, extra_events: Sequence[AlarmEvent] = ()) -> PipelineStep:
        """Run one Frame through estimators, FDI and sinks; ``extra_events`` (link alarms) are
        published with this Frame's output."""
        out = PipelineStep(events=list(extra_events))
        self.frames += 1
        for est in self.imu_estimators:
            e = est.step(frame)
            out.estimates.append(e)
            if not e.available:
                continue
            for ch, value in e.faults.items():
                st, ev = self._channel(e.name, ch).step(frame.t_us, value, e.numerics_ok)
                out.channels.append(st)
                out.events += ev
        if frame.air_new:
            out.sets = self._air_step(frame, out)
            self._last_sets = out.sets
        elif self._airdata_estimate is not None:
            out.estimates.append(self._airdata_estimate)
        for ev in out.events:
            if ev.state.value == "cleared":
                self.active.pop(ev.channel, None)
            else:
                self.active[ev.channel] = ev
        for sink in self.sinks:
            sink.publish(frame, out.estimates, out.events, out.sets, out.channels)
        return out

    def _air_step(self, frame: Frame, out: PipelineStep) -> list[SetStatus]:
        aoa_valid = np.isfinite(frame.aoa_rad) & (frame.aoa_age_s < self.cfg.telemetry.stale_after_s)
        cas_valid = np.isfinite(frame.cas_mps) & (frame.cas_age_s < self.cfg.telemetry.stale_after_s)
        aoa_ref = self._aoa_pred if math.isfinite(self._aoa_pred) else None
        cas_ref = self._cas_pred if math.isfinite(self._cas_pred) else None
        s_aoa, ev_a = self.aoa_set.step(frame.t_us, frame.aoa_rad[: self.aoa_set.n],
                                        aoa_valid[: self.aoa_set.n], aoa_ref)
        s_cas, ev_c = self.cas_set.step(frame.t_us, frame.cas_mps[: self.cas_set.n],
                                        cas_valid[: self.cas_set.n], cas_ref)
        out.events += ev_a + ev_c
        if self.airdata is not None:
            # Table I / sec. V-C: a lost set (no healthy instance) removes its row of C.
            aoa_f = s_aoa.fused if any(not f for f in s_aoa.faulty) else None
            cas_f = s_cas.fused if any(not f for f in s_cas.faulty) else None
            self.airdata.set_fused_measurements(
                aoa_f if aoa_f is not None and math.isfinite(aoa_f) else None,
                cas_f if cas_f is not None and math.isfinite(cas_f) else None)
            e = self.airdata.step(frame)
            out.estimates.append(e)
            self._airdata_estimate = e
            if e.available and e.numerics_ok:
                self._aoa_pred = float(e.states.get("aoa_pred_rad", [math.nan])[0])
                self._cas_pred = float(e.states.get("cas_pred_mps", [math.nan])[0])
            else:
                self._aoa_pred = self._cas_pred = math.nan
        return [s_aoa, s_cas]

    def health(self) -> dict[str, Any]:
        return {
            "vehicle": self.vehicle,
            "frames": self.frames,
            "active_alarms": [
                {"channel": str(ch), "kind": ev.kind.value, "fault_type": ev.fault_type.value,
                 "magnitude": ev.magnitude, "since_t_us": ev.t_us}
                for ch, ev in sorted(self.active.items())
            ],
        }

    def close(self) -> None:
        for sink in self.sinks:
            sink.close()
