"""VehiclePipeline: wires telemetry Frames -> estimators -> FDI -> sinks for one sysid.

Ordering per air-data sample (Wan2018 sec. III-A): residuals of each redundant AoA/CAS
instance are taken against the model's one-step-ahead prediction from the previous sample
(eq. 17); the FDI layer windows them (eq. 18), confirms, isolates and fuses the healthy
instances (eq. 19); the fused values are the MHE's measurements for this sample. Without a
model-based air-data estimator the residuals are taken against the set's own consensus.
IMU fault estimates (Lu2016 f_hat) are monitored per channel.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gcs_monitor.config import MonitorConfig, SetConfig, scheduled_threshold
from gcs_monitor.core.types import ChannelId
from gcs_monitor.core.units import DEG2RAD, KT2MPS
from gcs_monitor.estimators.base import Estimate, Estimator
from gcs_monitor.fdi.confirmation import ConfirmationParams
from gcs_monitor.fdi.events import (
    AlarmEvent,
    AlarmKind,
    AlarmState,
    ChannelStatus,
    FaultType,
    SetStatus,
)
from gcs_monitor.fdi.isolation import consensus_residuals
from gcs_monitor.fdi.monitor import (
    ChannelBank,
    ChannelMonitor,
    ChannelMonitorParams,
    RedundantSetMonitor,
    SetMonitorParams,
)
from gcs_monitor.fdi.residuals import ResidualRms, RmsWindowParams
from gcs_monitor.fdi.voting import adaptive_weights
from gcs_monitor.sinks import Sink
from gcs_monitor.telemetry.frame import Frame

# Noise levels and runaway boundaries the classifier uses per set (SI). The AoA/CAS noise is the
# simulated vanes' / pitots' (Lu2016 Table 1: sigma_alpha = 0.1 deg; CAS 0.1 m/s ~ sigma_V); the
# runaway boundaries separate Wan2018 Table II drifts from runaways.
SET_NOISE = {"aoa": 0.1 * DEG2RAD, "cas": 0.1, "acc": 0.05, "gyro": 0.05 * DEG2RAD}
SET_RUNAWAY_RATE = {"aoa": 1.0 * DEG2RAD, "cas": 2.0 * KT2MPS, "acc": 1.0, "gyro": 1.0 * DEG2RAD}
AIR_DT_S = 0.05  # air-data sample interval (20 Hz, docs/telemetry.md)
IMU_DT_S = 0.01
# FDI sets (config.fdi.<name>) of the acc and gyro fault channels per IMU estimator: each
# estimator's fault estimates have their own fault-free statistics, so their own thresholds
IMU_FDI_SETS = {"imu_hosm": ("acc_hosm", "gyro_hosm")}
IMU_FDI_SETS_DEFAULT = ("acc", "gyro")
IMU_WARMUP_US = 5_000_000  # IMU fault estimates are judged 5 s after an estimator (re)start
# Floor on J in the eq. 19 weights of the MHE's measurement, as a fraction of J_th: residual RMS
# below the fault-free level (model error + noise) carries no fault information (see
# MheMeasurementFusion and docs/papers-notes.md "Slow drift and the MHE's measurement fusion").
AIR_WEIGHT_FLOOR_RATIO = 0.25


class MheMeasurementFusion:
    """The fused measurement of one redundant set that the air-data MHE receives (Wan2018 eq. 19).

    Wan2018 weights each healthy instance by ``1/J^2`` of its model residual.  The model is
    driven by this fused value, so for a fault slower than the wind-rate bound u_w (which the
    wind states absorb) the loop has positive feedback: the instance the model happens to follow
    gets the smallest J, the highest weight, and pulls the model further (a slow CAS drift then
    captures the model and the healthy instances are isolated instead).  Two changes close
    the loop on independent information:

    - J in the weights is ``max(J_model, J_consensus)``: with >= 3 healthy instances the
      residual against the set's median (:func:`consensus_residuals`) is independent of the
      model, so an instance departing from the others loses weight even if the model follows it;
      with fewer healthy instances only J_model is used (two instances cannot isolate each
      other; a fault fast enough to exceed u_w makes J_model of the faulty one rise first);
    - J is floored at ``floor_ratio * J_th`` (not at the sensor noise): healthy instances share
      the weight equally instead of by the noise of their fault-free residuals.

    With ``equal_pair`` (``[fdi.<set>] equal_pair_weights``; ours, off by default) the last two
    healthy instances get equal weights while both are below J_th (J floored at J_th; one
    above J_th still leaves the fusion, as eq. 19's set S says). Two instances cannot isolate
    each other through the consensus, and the model is driven by their fusion: for a fault the
    wind states absorb (a Table II non-return to zero of 0.1 x on one of the last two vanes),
    1/J^2 weights make the model follow whichever instance had the smaller J at the fault's
    onset, so either the faulty one or the healthy one is isolated, by chance. Equal weights
    keep the model at the pair's mean: such a fault is missed (the output carries half of it)
    instead of being isolated on the wrong instance; a fault faster than the wind bounds still
    raises the faulty instance's J first. docs/papers-notes.md ("The last two instances")
    gives the measured trade.

    Detection stays on the model residuals (eq. 17) in the set monitor; the fused value is what
    the instances judged healthy (not latched out, J_model <= J_th) agree on.
    """

    def __init__(self, n: int, threshold: float, n_eval: int, floor_ratio: float,
                 equal_pair: bool = False) -> None:
        self.threshold = threshold
        self.floor = floor_ratio * threshold
        self.equal_pair = equal_pair
        self._rms = [ResidualRms(RmsWindowParams(rms_window_n=n_eval)) for _ in range(n)]
        self._j = [0.0] * n

    def step(self, measured: list[float], usable: list[bool], status: SetStatus
             ) -> tuple[float | None, tuple[float, ...]]:
        """Fused value (None when no instance is healthy) and the weights used."""
        healthy = [u and not f for u, f in zip(usable, status.faulty, strict=True)]
        n_healthy = sum(healthy)
        if n_healthy >= 3:
            _, r = consensus_residuals(measured, usable, healthy)
            for i, ri in enumerate(r):
                if ri == ri:
                    self._j[i] = self._rms[i].update(ri)
        else:
            self._j = [0.0] * len(measured)
        j_eff = [max(a, b) for a, b in zip(status.rms, self._j, strict=True)]
        floor = self.threshold if self.equal_pair and n_healthy == 2 else self.floor
        w = adaptive_weights(j_eff, healthy, self.threshold, floor)
        if not any(w):
            return None, tuple(w)
        return sum(wi * x for wi, x in zip(w, measured, strict=True) if wi), tuple(w)


def _floats(x: Any) -> list[float]:
    """A Frame's per-instance array as a list of Python floats."""
    return x.tolist() if isinstance(x, np.ndarray) else [float(v) for v in x]


def set_params(name: str, cfg: SetConfig, dt_s: float) -> SetMonitorParams:
    return SetMonitorParams(
        threshold=cfg.threshold, noise_sigma=SET_NOISE[name],
        runaway_rate_per_s=SET_RUNAWAY_RATE[name], dt_s=dt_s,
        rms=RmsWindowParams(rms_window_n=cfg.n_eval),
        confirmation=ConfirmationParams(detect_n=cfg.n_detect, eval_n=cfg.n_eval,
                                        clear_ratio=cfg.clear_ratio, clear_n=cfg.n_clear,
                                        latch=cfg.latch),
        stuck_n=round(cfg.stuck_window_s / dt_s) if cfg.stuck_window_s > 0.0 else 0,
        no_data_n=max(1, round(cfg.no_data_window_s / dt_s)) if cfg.no_data_window_s > 0.0
        else 0,
        restart_peers=cfg.restart_peers,
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
        sigma = cfg.airdata.turbulence_sigma_mps  # declared weather: J_th of the air-data sets
        aoa_cfg = dataclasses.replace(cfg.fdi.aoa,
                                      threshold=scheduled_threshold(cfg.fdi.aoa, sigma))
        cas_cfg = dataclasses.replace(cfg.fdi.cas,
                                      threshold=scheduled_threshold(cfg.fdi.cas, sigma))
        self.aoa_set = RedundantSetMonitor("aoa", n_aoa, set_params("aoa", aoa_cfg, AIR_DT_S),
                                           estimator=ref_name, vehicle=vehicle)
        self.cas_set = RedundantSetMonitor("cas", n_cas, set_params("cas", cas_cfg, AIR_DT_S),
                                           estimator=ref_name, vehicle=vehicle)
        self._channels: dict[tuple[str, ChannelId], ChannelMonitor] = {}
        self._est_start_us: dict[str, int] = {}  # judged from this time on, per estimator
        self._est_judging: set[str] = set()  # estimators whose channels were being judged
        self._est_event: dict[str, AlarmEvent] = {}  # active re-initialisation notice
        self._last_sets: list[SetStatus] = []
        self._airdata_estimate: Estimate | None = None
        self._aoa_fusion = MheMeasurementFusion(n_aoa, aoa_cfg.threshold, aoa_cfg.n_eval,
                                                AIR_WEIGHT_FLOOR_RATIO,
                                                aoa_cfg.equal_pair_weights)
        self._cas_fusion = MheMeasurementFusion(n_cas, cas_cfg.threshold, cas_cfg.n_eval,
                                                AIR_WEIGHT_FLOOR_RATIO,
                                                cas_cfg.equal_pair_weights)
        self.frames = 0
        self.active: dict[ChannelId, AlarmEvent] = {}
        # Per-channel ChannelStatus records in PipelineStep.channels; the Monitor turns them off
        # when neither a sink nor an on_step callback reads them (alarms are the same either way)
        self.channel_status = True
        # estimator name -> (fault channel ids, their monitors, their ChannelBank) in the order
        # of Estimate.faults
        self._banks: dict[str, tuple[tuple[ChannelId, ...], list[ChannelMonitor],
                                     ChannelBank | None]] = {}

    def _channel(self, estimator: str, ch: ChannelId) -> ChannelMonitor:
        key = (estimator, ch)
        mon = self._channels.get(key)
        if mon is None:
            kind = "acc" if ch.kind == "acc" else "gyro"
            acc_set, gyro_set = IMU_FDI_SETS.get(estimator, IMU_FDI_SETS_DEFAULT)
            cfg = getattr(self.cfg.fdi, acc_set if kind == "acc" else gyro_set)
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
            if not e.available or not e.numerics_ok:
                self._est_start_us.pop(e.name, None)  # (re)starts: converge again
                continue
            if e.reinit:
                # the estimator says how long its fault estimates need to re-converge; the
                # operator is told when channels that were being judged stop being judged
                self._est_start_us[e.name] = frame.t_us + int(e.reinit_warmup_s * 1e6)
                if e.name in self._est_judging and e.name not in self._est_event:
                    out.events.append(self._reinit_event(frame.t_us, e, AlarmState.RAISED))
                self._est_judging.discard(e.name)
            # Filter convergence: fault estimates are not judged during the first
            # IMU_WARMUP_US after an estimator (re)starts (its start-up transient is up to
            # 10x its converged fault-free level; see docs/results.md, "Detection and isolation
            # with imu_ts").
            t0 = self._est_start_us.setdefault(e.name, frame.t_us + IMU_WARMUP_US)
            judged = frame.t_us >= t0
            if judged:
                self._est_judging.add(e.name)
                if e.name in self._est_event:
                    out.events.append(self._reinit_event(frame.t_us, e, AlarmState.CLEARED))
            faults = e.faults
            bank = self._banks.get(e.name)
            chans = tuple(faults)
            if bank is None or bank[0] != chans:  # same ids: identity compare, no hashing
                mons = [self._channel(e.name, ch) for ch in chans]
                # one numba call for all channels (None without numba: monitor by monitor)
                bank = self._banks[e.name] = (chans, mons, ChannelBank.create(mons))
            t_us = frame.t_us
            if bank[2] is not None:
                ev = bank[2].update(t_us, list(faults.values()), judged,
                                    out.channels if self.channel_status else None)
                if ev:
                    out.events += ev
            elif self.channel_status:
                for mon, value in zip(bank[1], faults.values(), strict=False):
                    st, ev = mon.step(t_us, value, judged)
                    out.channels.append(st)
                    if ev:
                        out.events += ev
            else:
                for mon, value in zip(bank[1], faults.values(), strict=False):
                    ev = mon.update(t_us, value, judged)
                    if ev:
                        out.events += ev
        # eq. 17's reference alpha_hat_{k|k-1}, V_c_hat_{k|k-1}, predicted before y_k is seen;
        # on every frame, so that each IMU sample enters Theta's averages (None without air data)
        pred = self.airdata.predict(frame) if self.airdata is not None else None
        if frame.air_new:
            out.sets = self._air_step(frame, out, pred)
            self._last_sets = out.sets
        elif self._airdata_estimate is not None:
            out.estimates.append(self._airdata_estimate)
        for event in out.events:
            if event.state.value == "cleared":
                self.active.pop(event.channel, None)
            else:
                self.active[event.channel] = event
        for sink in self.sinks:
            sink.publish(frame, out.estimates, out.events, out.sets, out.channels)
        return out

    def _reinit_event(self, t_us: int, e: Estimate, state: AlarmState) -> AlarmEvent:
        """Operator notice of a state re-initialisation (never a sensor-fault alarm): raised
        when it happens, cleared when the fault channels are judged again."""
        msg = (e.reinit + f"; fault channels not judged for {e.reinit_warmup_s:g} s"
               if state is not AlarmState.CLEARED else "fault channels judged again")
        ev = AlarmEvent(t_us=t_us, channel=ChannelId("estimator", 0, e.name), state=state,
                        kind=AlarmKind.ESTIMATOR, fault_type=FaultType.UNKNOWN,
                        magnitude=math.nan, residual_rms=math.nan, threshold=math.nan,
                        estimator=e.name, message=msg, vehicle=self.vehicle)
        if state is AlarmState.CLEARED:
            self._est_event.pop(e.name, None)
        else:
            self._est_event[e.name] = ev
        return ev

    def _air_step(self, frame: Frame, out: PipelineStep,
                  pred: tuple[float, float] | None) -> list[SetStatus]:
        # Python floats and lists: numpy per-call overhead dominates for three instances
        stale = self.cfg.telemetry.stale_after_s
        n_a, n_c = self.aoa_set.n, self.cas_set.n
        aoa = _floats(frame.aoa_rad)[:n_a]
        cas = _floats(frame.cas_mps)[:n_c]
        aoa_valid = [math.isfinite(x) and a < stale
                     for x, a in zip(aoa, _floats(frame.aoa_age_s), strict=False)]
        cas_valid = [math.isfinite(x) and a < stale
                     for x, a in zip(cas, _floats(frame.cas_age_s), strict=False)]
        # eq. 17 against the prediction for this sample; the MHE step below uses the eq. 19 fusion
        aoa_ref = pred[0] if pred is not None and math.isfinite(pred[0]) else None
        cas_ref = pred[1] if pred is not None and math.isfinite(pred[1]) else None
        s_aoa, ev_a = self.aoa_set.step(frame.t_us, aoa, aoa_valid, aoa_ref)
        s_cas, ev_c = self.cas_set.step(frame.t_us, cas, cas_valid, cas_ref)
        if ev_a or ev_c:
            out.events += ev_a + ev_c
        if self.airdata is not None:
            # eq. 19 on independent weights (MheMeasurementFusion); Table I / sec. V-C: a lost
            # set (no healthy instance) removes its row of C.
            aoa_f, w_a = self._aoa_fusion.step(list(s_aoa.measured), aoa_valid, s_aoa)
            cas_f, w_c = self._cas_fusion.step(list(s_cas.measured), cas_valid, s_cas)
            s_aoa = dataclasses.replace(s_aoa, fused=math.nan if aoa_f is None else aoa_f,
                                        weights=w_a)
            s_cas = dataclasses.replace(s_cas, fused=math.nan if cas_f is None else cas_f,
                                        weights=w_c)
            self.airdata.set_fused_measurements(aoa_f, cas_f)
            e = self.airdata.step(frame)
            out.estimates.append(e)
            self._airdata_estimate = e
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
