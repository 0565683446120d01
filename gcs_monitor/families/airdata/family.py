"""The air-data family: redundant AoA and CAS sets judged against the Wan2018 model.

Per air-data sample, Wan2018 sec. III-A:

1. ``predict``: the estimator's one-step-ahead ``alpha_hat_{k|k-1}``, ``V_c_hat_{k|k-1}``
   (eq. 29 through eq. 16), before y_k is seen; on every Frame, so that each IMU sample enters
   Theta's averages (None on Frames without air data);
2. ``judge``: each instance's residual against it (eq. 17), RMS windows (eq. 18), n_D-of-N_eval
   confirmation, isolation and Table I in the set monitors, then the eq. 19 fusion the MHE is
   given (:class:`gcs_monitor.fdi.fusion.MheMeasurementFusion`);
3. ``update``: the MHE step on that fusion (a lost set removes its row of C).

Without a model reference (``estimator = "none"``) each instance is judged against its set's
consensus. The FDI runs at the air-data rate (N_eval = 10 is 0.5 s of Wan2018's 20 Hz air
data): windows in seconds are turned into samples with the stream's measured period, which the
telemetry assembler reports on the Frame (``Frame.air_period_s``).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from gcs_monitor.core.atmosphere import tas_from_cas
from gcs_monitor.families.airdata.config import AirDataFamilyConfig
from gcs_monitor.families.airdata.estimator import VIRTUAL_CAS, AirDataEstimator, floats
from gcs_monitor.families.airdata.weather import WeatherEstimator, wind_ned_tas
from gcs_monitor.families.base import AIRSPEED_CAS, FUSED, VIRTUAL, FamilyContext, Verdict
from gcs_monitor.fdi.config import scheduled_threshold, set_params
from gcs_monitor.fdi.events import AlarmState, SetStatus
from gcs_monitor.fdi.fusion import MheMeasurementFusion
from gcs_monitor.fdi.monitor import RedundantSetMonitor
from gcs_monitor.fdi.records import Estimate, FamilyStatus
from gcs_monitor.telemetry.frame import Frame

SETS = ("aoa", "cas")
RATE_HZ = (5.0, 100.0)  # air-data rates the Wan2018 model and windows are valid for


class AirDataFamily:
    """Triplex air-data FDI of one vehicle (see the module docstring)."""

    name = "airdata"

    def __init__(self, cfg: AirDataFamilyConfig, ctx: FamilyContext, *,
                 estimator: AirDataEstimator | None = None) -> None:
        """``estimator`` replaces the configured one (variants in evaluations and tests)."""
        self.cfg = cfg
        self.ctx = ctx
        self.estimator: AirDataEstimator | None = estimator
        fixed = cfg.wind_bounds == "fixed"
        if estimator is None and cfg.estimator != "none":
            est_cfg = dataclasses.replace(cfg.filter, envelope=None if fixed else cfg.weather)
            self.estimator = AirDataEstimator(est_cfg, variant=cfg.estimator)
        self.reference = self.estimator.name if self.estimator is not None else "voting"
        # the weather: declared (Wan2018), or estimated from the flight with the declared as prior
        self.weather = (WeatherEstimator(cfg.weather_estimate, cfg.weather)
                        if cfg.weather_estimate.enabled else None)
        envelope = self.weather.estimate.envelope if self.weather is not None else cfg.weather
        self._fixed_bounds = fixed
        if self.estimator is not None and self.weather is not None and not fixed:
            self.estimator.set_envelope(envelope)
        sigma = envelope.turbulence_sigma_mps  # J_th of the sets follow the weather
        self.thresholds = {s: scheduled_threshold(getattr(cfg.fdi, s), sigma) for s in SETS}
        # built at the first air-data sample with the stream's measured period
        self.sets: dict[str, RedundantSetMonitor] = {}
        self._fusion: dict[str, MheMeasurementFusion] = {}
        self._last: Estimate | None = None
        self._estimates: list[Estimate] = []
        self._inputs = False  # air data has been in the telemetry
        self._hold = False  # an instance was suspected or isolated on this sample
        self._min_healthy = cfg.weather_estimate.min_healthy
        self._thin = {s: False for s in SETS}  # the set has too few healthy instances

    def predict(self, frame: Frame) -> tuple[float, float] | None:
        """eq. 17's reference alpha_hat_{k|k-1}, V_c_hat_{k|k-1} (None without one)."""
        return self.estimator.predict(frame) if self.estimator is not None else None

    def _build_sets(self, frame: Frame) -> bool:
        period_s = frame.air_period_s
        if not math.isfinite(period_s):
            return False
        n = {"aoa": len(frame.aoa_rad), "cas": len(frame.cas_mps)}
        for s in SETS:
            scfg = getattr(self.cfg.fdi, s)
            th = self.thresholds[s]
            self.sets[s] = RedundantSetMonitor(
                s, n[s], set_params(scfg, period_s, threshold=th, alarm=self.ctx.alarm,
                                    classifier=self.ctx.classifier),
                estimator=self.reference, vehicle=self.ctx.vehicle)
            self._fusion[s] = MheMeasurementFusion(
                n[s], th, self.sets[s].p.rms.rms_window_n, self.cfg.fusion.weight_floor_ratio,
                scfg.equal_pair_weights)
        return True

    def judge(self, frame: Frame, prediction: tuple[float, float] | None) -> Verdict:
        t_us = frame.t_us
        if not frame.air_new:
            return Verdict(FamilyStatus(self.name, t_us, False, sample=False,
                                        reason="no new air data", inputs=self._inputs))
        self._inputs = True
        if not self.sets and not self._build_sets(frame):
            return Verdict(FamilyStatus(self.name, t_us, False,
                                        reason="air-data sample period not measured yet"))
        rate = 1.0 / frame.air_period_s
        if rate < RATE_HZ[0]:
            return Verdict(FamilyStatus(
                self.name, t_us, False,
                reason=f"air data at {rate:.0f} Hz, below the {RATE_HZ[0]:g} Hz the air-data "
                       "family needs"))
        verdict = Verdict(FamilyStatus(self.name, t_us, True))
        # Python floats and lists: numpy per-call overhead dominates for three instances
        stale = self.ctx.stale_after_s
        values = ((frame.aoa_rad, frame.aoa_age_s), (frame.cas_mps, frame.cas_age_s))
        for k, s in enumerate(SETS):
            mon = self.sets[s]
            raw, age = values[k]
            m = floats(raw)[:mon.n]
            valid = [math.isfinite(x) and a < stale
                     for x, a in zip(m, floats(age), strict=False)]
            # eq. 17 against the prediction for this sample; update() steps on the eq. 19 fusion
            ref = prediction[k] if prediction is not None and math.isfinite(prediction[k]) \
                else None
            status, events = mon.step(t_us, m, valid, ref)
            if events:
                verdict.events += events
            if self.estimator is not None:
                # eq. 19 on independent weights; Table I / sec. V-C: a lost set (no healthy
                # instance) removes its row of C
                fused, w = self._fusion[s].step(m, valid, status)  # m: status.measured
                status = SetStatus(
                    name=status.name, t_us=status.t_us, measured=status.measured,
                    reference=status.reference, fused=math.nan if fused is None else fused,
                    weights=w, rms=status.rms, threshold=status.threshold,
                    faulty=status.faulty, configuration=status.configuration)
                verdict.fused[s] = fused
            else:
                verdict.fused[s] = status.fused if math.isfinite(status.fused) else None
            verdict.sets.append(status)
            # the weather estimate holds when the set's membership changes (an isolation, a
            # readmission) or an instance is suspected; a relabel of an instance already
            # isolated (UPDATED, every few seconds while its alarm stands) changes nothing the
            # fusion uses: holding on it froze the estimate for as long as any alarm stood
            # (triplex run 41: an AoA instance isolated at 30.9 s, a 10 m/s shear from 33.5 s
            # never learnt, all three CAS flagged at 41.8 s)
            if mon.suspected or any(e.state is not AlarmState.UPDATED
                                             for e in events):
                self._hold = True
            # a set down to its last healthy instance: nothing cross-checks it, so the weather
            # estimate does not learn from it (weather.py, "thin sets")
            self._thin[s] = mon.healthy < min(self._min_healthy, mon.n)
        return verdict

    def _estimate_weather(self, frame: Frame, verdict: Verdict) -> Estimate | None:
        """One wind sample from the fused air data into the weather estimate; the new envelope
        (and the J_th scheduled on it) when the estimate is recomputed."""
        w = self.weather
        assert w is not None
        t = frame.t_us
        if self._hold:
            w.hold(t)
            self._hold = False
        aoa, cas = verdict.fused.get("aoa"), verdict.fused.get("cas")
        thin_aoa, thin_cas = self._thin["aoa"], self._thin["cas"]
        wind = None
        if (aoa is not None and cas is not None and cas > 0.0 and frame.euler_rad is not None
                and frame.gps_vel_ned_mps is not None and math.isfinite(frame.baro_alt_m)
                and not (thin_aoa and thin_cas)):
            ssa = frame.ssa_rad if math.isfinite(frame.ssa_rad) else 0.0
            tas: float | None = tas_from_cas(cas, frame.baro_alt_m)
            if thin_aoa or thin_cas:  # the set that cannot be checked is replaced by kinematics
                kin = w.kinematic_air(frame.gps_vel_ned_mps, frame.euler_rad)
                if kin is None:
                    tas = None  # no mean wind learnt yet: no sample
                else:
                    aoa = kin[0] if thin_aoa else aoa
                    tas = kin[1] if thin_cas else tas
            if tas is not None:
                wind = wind_ned_tas(frame.gps_vel_ned_mps, frame.euler_rad, tas, aoa, ssa)
        env = w.add(t, wind, gusts=not (thin_aoa or thin_cas))
        if env is None:
            return None
        if self.estimator is not None and not self._fixed_bounds:
            self.estimator.set_envelope(env)
        for s in SETS:
            th = scheduled_threshold(getattr(self.cfg.fdi, s), env.turbulence_sigma_mps)
            if th != self.thresholds[s]:
                self.thresholds[s] = th
                self.sets[s].set_threshold(th)
                if s in self._fusion:
                    self._fusion[s].set_threshold(th)
        e = w.estimate
        return Estimate("weather", t, states={
            "mean_wind_ned_mps": np.array(e.mean_wind_ned_mps),
            "turbulence_sigma_mps": np.array([e.turbulence_sigma_mps]),
            "envelope_wind_mps": np.array([env.wind_mps, env.wind_z_mps]),
            "envelope_turbulence_sigma_mps": np.array([env.turbulence_sigma_mps]),
            "envelope_shear_rate_mps2": np.array([env.shear_rate_mps2]),
            "converged": np.array([float(e.converged)])})

    def update(self, frame: Frame, verdict: Verdict) -> list[Estimate]:
        """The estimator's step on the fused measurements of this air-data sample; on other
        Frames its latest estimate. Every judged sample goes into the weather estimate first
        (its bounds hold from the next sample on)."""
        weather = None
        if self.weather is not None and verdict.sets:
            weather = self._estimate_weather(frame, verdict)
        out = self._step(frame, verdict)
        if verdict.sets:
            self._share(frame.t_us, verdict)
        return out + [weather] if weather is not None else out

    def _share(self, t_us: int, verdict: Verdict) -> None:
        """The airspeed the families after this one use (the yaw-rate observer's ``V_eas``, the
        aircraft tier's dynamic pressure): the eq. 19 fusion of the CAS instances the vote
        keeps; with none healthy, the MHE's virtual CAS marked :data:`VIRTUAL` (Wan2018 Table
        I), else no airspeed at all, which a reader must not replace with the raw instances it
        was just told are faulty.

        The virtual CAS is a scale, not a reference: with the CAS set lost the wind states lose
        the measurement that makes them observable, and in the campaign's run 120 (three CAS
        faults, shear and 3.5 m/s turbulence) it ran 6-21 m/s above the true airspeed. The
        yaw-rate observer scheduled on it raised a false gyro alarm and now declines it; the
        aircraft tier, which otherwise falls back to the ground speed, raised false alarms in 14
        of the 63 runs with two or more CAS faults on the ground speed, 7 on the virtual CAS."""
        shared = self.ctx.shared
        cas = verdict.fused.get("cas")
        if cas is not None and math.isfinite(cas):
            # one instance left of several: the value is that pitot alone, unchecked (run 153
            # of the Wan2018 campaign: the last pitot's runaway read as a lost engine by the
            # aircraft tier 0.1 s before this family isolated it)
            st = next((x for x in verdict.sets if x.name == "cas"), None)
            survivor = st is not None and len(st.weights) > 1 and \
                sum(w > 0.0 for w in st.weights) == 1
            shared.put(AIRSPEED_CAS, cas, t_us, FUSED, survivor=survivor)
            return
        last = self._last
        v = (last.virtual.get(VIRTUAL_CAS) if last is not None and last.available
             and last.numerics_ok and last.t_us == t_us else None)
        if v is not None and math.isfinite(v):
            shared.put(AIRSPEED_CAS, v, t_us, VIRTUAL)
        else:
            shared.withdraw(AIRSPEED_CAS, t_us, "no healthy CAS instance")

    def _step(self, frame: Frame, verdict: Verdict) -> list[Estimate]:
        if self.estimator is None:
            return []
        if verdict.sets:
            self.estimator.set_fused_measurements(verdict.fused.get("aoa"),
                                                  verdict.fused.get("cas"))
            self._last = self.estimator.step(frame)
            return [self._last]
        if frame.air_new:  # not judged (period unknown): the estimator still sees the sample
            self._last = self.estimator.step(frame)
            return [self._last]
        return [self._last] if self._last is not None else []
