"""The Chen2020 LPV sliding-mode observer on the Frames of one vehicle.

Per observer step (``[yaw_rate.observer] step_s``, Chen2020's 50 Hz), from the Frame:
``y_p = [phi, beta, p, r]`` (ATTITUDE roll, AOA_SSA sideslip, the primary IMU's roll and yaw
rates), ``u_p = [delta_a, delta_r]`` (surface positions, else commands, of DEBUG_FLOAT_ARRAY
``SURF``), and ``rho = [V_eas, V_eas^2]`` with ``V_eas`` from the air-data family's airspeed
(the fusion of the CAS instances its vote keeps; not its virtual CAS when it keeps none: the
observer does not judge then; the blackboard of :mod:`gcs_monitor.families.base`), else the
median valid CAS instance, at the barometric altitude (Chen2020 eq. 59). The observer
(:mod:`gcs_monitor.filters.lpv_smo`) gives the fault estimate of the monitored gyro axis,
low-passed to the equivalent output injection, and the corrected (virtual) gyro ``y - f_hat``
(Chen2020 eq. 24).

A design of several altitude bands (:mod:`gcs_monitor.families.yaw_rate.design`) runs the band
of the barometric altitude: on a change of band the observer re-anchors at the measurement with
its fault estimate kept, as over a short gap; a band is kept up to ``BAND_HYSTERESIS_M`` beyond
its edge (baro noise at an edge does not switch back and forth).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from gcs_monitor.core.atmosphere import tas_from_cas
from gcs_monitor.core.types import ChannelId
from gcs_monitor.families.base import AIRSPEED_CAS, FUSED, Blackboard, SharedValue
from gcs_monitor.families.yaw_rate.config import YawRateFamilyConfig
from gcs_monitor.families.yaw_rate.design import ObserverDesign, load_bands
from gcs_monitor.fdi.records import Estimate
from gcs_monitor.filters.lpv_smo import (
    SmoDesign,
    SmoMatrices,
    SmoState,
    smo_init,
    smo_matrices,
    smo_step,
)
from gcs_monitor.models.lateral import STATES, eas_from_tas
from gcs_monitor.telemetry.frame import Frame

US_PER_S = 1_000_000
AILERON, RUDDER = 0, 2  # surface indices of the telemetry contract
# residuals of the Estimate: ||e_y|| (sliding maintained) and the fault estimate before the
# equivalent-injection low-pass
EY_CHANNEL = ChannelId("smo_ey", 0)
RAW_CHANNEL = ChannelId("smo_f_raw", 0)
BAND_HYSTERESIS_M = 50.0  # a band is left this far beyond its edge


@dataclass(frozen=True, slots=True)
class LateralInputs:
    """One sample of the observer's inputs (SI) or why there is none."""

    y_p: np.ndarray | None
    u: np.ndarray | None
    eas_mps: float
    reason: str = ""
    alt_m: float = math.nan


def lateral_inputs(frame: Frame, stale_s: float,
                   airspeed: SharedValue | None = None) -> LateralInputs:
    """The observer's measurements of a Frame, or the first missing input. ``airspeed`` is the
    air-data family's CAS when it has judged recently; only a fused one is used (its virtual
    CAS, while every CAS instance is faulty, drifts with the wind estimate, and a wrong V_eas
    reads as a gyro fault); without it the median of the fresh CAS instances."""
    nan = math.nan
    imu = frame.primary_imu
    if imu is None:
        return LateralInputs(None, None, nan, "no IMU sample")
    if frame.euler_rad is None:
        return LateralInputs(None, None, nan, "no attitude (ATTITUDE)")
    beta = frame.ssa_rad
    if not math.isfinite(beta):
        return LateralInputs(None, None, nan, "no sideslip (AOA_SSA)")
    surf = frame.surf_pos_rad if frame.surf_pos_rad is not None else frame.surf_cmd_rad
    if surf is None:
        return LateralInputs(None, None, nan, "no surface deflections (SURF)")
    if airspeed is not None:
        v_cas = airspeed.value
        if airspeed.source != FUSED or v_cas != v_cas:
            return LateralInputs(None, None, nan, "no trusted airspeed (the air-data family "
                                                  "keeps no CAS instance)")
    else:
        cas = [c for c, a in zip(frame.cas_mps.tolist(), frame.cas_age_s.tolist(),
                                 strict=False) if c == c and a <= stale_s]
        if not cas:
            return LateralInputs(None, None, nan, "no airspeed (AIRSPEED)")
        cas.sort()
        mid = len(cas) // 2
        v_cas = cas[mid] if len(cas) % 2 else 0.5 * (cas[mid - 1] + cas[mid])
    alt = frame.baro_alt_m if math.isfinite(frame.baro_alt_m) else frame.alt_msl_m
    eas = eas_from_tas(tas_from_cas(v_cas, alt), alt) if math.isfinite(alt) else v_cas
    w = imu.omega_frd_radps
    return LateralInputs(np.array((frame.euler_rad[0], beta, w[0], w[2]), dtype=np.float64),
                         np.array((surf[AILERON], surf[RUDDER]), dtype=np.float64), eas,
                         alt_m=alt)


class YawRateEstimator:
    """Chen2020 observer for the configured gyro axis (see the module docstring)."""

    name = "yaw_rate_smo"

    def __init__(self, cfg: YawRateFamilyConfig, *,
                 design: ObserverDesign | list[ObserverDesign] | None = None,
                 stale_s: float = 0.5, shared: Blackboard | None = None) -> None:
        self.cfg = cfg
        bands = (load_bands(cfg.design) if design is None
                 else [design] if isinstance(design, ObserverDesign) else list(design))
        self.bands = bands
        self.design = bands[0]
        mg = cfg.observer.eas_margin
        self._mats: list[SmoMatrices] = []
        self._eas: list[tuple[float, float]] = []
        for b in bands:
            if cfg.sensor not in b.sensors:
                raise ValueError(f"design {cfg.design!r} has no observer for sensor "
                                 f"{cfg.sensor!r}; it has {sorted(b.sensors)}")
            d: SmoDesign = b.sensors[cfg.sensor]
            if cfg.observer.modulation > 0.0:
                d = replace(d, k=cfg.observer.modulation)
            m = b.model
            self._mats.append(smo_matrices(m.A, m.B, m.c, d))
            lo, hi = m.eas_range_mps
            self._eas.append((lo * (1.0 - mg), hi * (1.0 + mg)))
        self.mats = self._mats[0]
        self.eas_range = self._eas[0]
        self.index = STATES.index(cfg.sensor)
        # names the design in the coverage reason: another aircraft's speeds say which airframe
        # the model belongs to
        self.label = Path(cfg.design).name if cfg.design.endswith(".json") else cfg.design
        self.stale_s = stale_s
        self.shared = shared  # the air-data family's airspeed, when it runs
        self._step_us = round(cfg.observer.step_s * US_PER_S)
        self._gap_us = round(cfg.max_gap_s * US_PER_S)
        self._reanchor_us = round(cfg.reanchor_s * US_PER_S)
        self._tau = cfg.observer.nu_filter_s
        self._channels: dict[int, ChannelId] = {}
        self._band = 0
        # one band without altitude limits (a design identified from flights) holds anywhere,
        # even without an altitude
        self._everywhere = len(bands) == 1 and bands[0].alt_range_m == (-math.inf, math.inf)
        self.reset()

    def _band_at(self, alt_m: float) -> int:
        """The band of this altitude (the current one while within its hysteresis), -1 if
        none holds there; a design of one unbounded band holds everywhere."""
        if self._everywhere:
            return 0
        bands = self.bands
        if not math.isfinite(alt_m):
            return -1
        lo, hi = bands[self._band].alt_range_m
        if lo - BAND_HYSTERESIS_M <= alt_m < hi + BAND_HYSTERESIS_M:
            return self._band
        for i, b in enumerate(bands):
            if b.holds_at(alt_m):
                return i
        return -1

    def reset(self) -> None:
        self._s: SmoState | None = None
        self._last_us: int | None = None
        self._inst = -1
        self._f_lp = 0.0

    def _fault_vec(self, f: float) -> np.ndarray:
        return np.array([f])

    def due(self, frame: Frame) -> bool:
        """Whether the observer steps on this Frame (every ``step_s``, on the measured time)."""
        last = self._last_us
        # an eighth of a step of slack: 100 Hz Frames with 20 ms steps step on every second
        # Frame despite jitter
        return last is None or 8 * (frame.t_us - last) >= 7 * self._step_us

    def step(self, frame: Frame) -> Estimate:
        """One observer step on this Frame (the caller checks :meth:`due`)."""
        t = frame.t_us
        inp = lateral_inputs(frame, self.stale_s, None if self.shared is None else
                             self.shared.get(AIRSPEED_CAS, frame.t_us, self.stale_s))
        if inp.y_p is None or inp.u is None:  # the next sample re-anchors over the gap
            return Estimate.unavailable(self.name, t, inp.reason)
        band = self._band_at(inp.alt_m)
        if band < 0:
            self.reset()
            lo_m, hi_m = self.bands[0].alt_range_m[0], self.bands[-1].alt_range_m[1]
            if not math.isfinite(inp.alt_m):
                return Estimate.unavailable(
                    self.name, t, f"no altitude (baro or GPS): the {self.label!r} design's "
                    "models hold per altitude band")
            side = "below" if inp.alt_m < lo_m else "above"
            return Estimate.unavailable(
                self.name, t, f"altitude {side} the {self.label!r} design's bands, "
                f"{lo_m:.0f}-{hi_m:.0f} m (its models hold only there)")
        if band != self._band:
            self._band = band
            self.mats = self._mats[band]
            self.eas_range = self._eas[band]
            if self._s is not None and self._last_us is not None:
                # another band's model: re-anchor at the measurement, keeping the fault
                # estimate (as over a short gap of the same gyro)
                self._s = smo_init(self.mats, inp.y_p, self._fault_vec(self._f_lp))
        lo, hi = self.eas_range
        if not lo <= inp.eas_mps <= hi:
            self.reset()
            # no value in the reason: coverage names the reason with the most uncovered time
            # in its window, and one reason per m/s would split it
            side = "below" if inp.eas_mps < lo else "above"
            return Estimate.unavailable(
                self.name, t, f"EAS {side} the {self.label!r} design's {lo:.0f}-{hi:.0f} m/s "
                "(its model holds only there)")
        reinit = ""
        imu = frame.primary_imu
        inst = imu.instance if imu is not None else 0
        if self._s is None or self._last_us is None:
            reinit = "start"  # the only restart the family waits for (warm-up)
            self._s = smo_init(self.mats, inp.y_p)
            self._last_us = t
            self._f_lp = 0.0
        elif t - self._last_us > self._gap_us or inst != self._inst:
            # explicit Euler cannot step across a gap: re-anchor at the measurement, keeping
            # the fault estimate over a short gap of the same gyro (e~_1 starts near 0)
            keep = inst == self._inst and t - self._last_us <= self._reanchor_us
            if not keep:
                self._f_lp = 0.0
            self._s = smo_init(self.mats, inp.y_p, self._fault_vec(self._f_lp))
            self._last_us = t
        self._inst = inst
        dt = (t - self._last_us) / US_PER_S
        self._last_us = t
        s, out = smo_step(self._s, self.mats, inp.y_p, inp.u, (inp.eas_mps, inp.eas_mps ** 2),
                          dt if dt > 0.0 else self.cfg.observer.step_s)
        self._s = s
        f = float(out.f_hat[0])
        if not (math.isfinite(f) and math.isfinite(float(s.z.sum()))):
            self.reset()
            return Estimate(self.name, t, numerics_ok=False)
        a = 1.0 if self._tau <= 0.0 else min(1.0, dt / self._tau)
        self._f_lp += a * (f - self._f_lp)
        ch = self._channels.get(inst)
        if ch is None:
            ch = self._channels[inst] = ChannelId("gyro", inst, self.cfg.sensor)
        e_y = out.e_y
        return Estimate(
            self.name, t, faults={ch: self._f_lp}, virtual={ch: float(inp.y_p[self.index])
                                                             - self._f_lp},
            residuals={EY_CHANNEL: math.sqrt(float(e_y @ e_y)), RAW_CHANNEL: f},
            states={"x_hat": out.x_hat}, reinit=reinit,
            reinit_warmup_s=self.cfg.warmup_s if reinit else 0.0)
