"""IMU fault reconstruction with the ATSEKF / IOTSEKF on the GS-KM or AS-KM (Lu2016).

Consumes Frames (primary IMU ``imu[cfg.imu_instance]``, ATTITUDE Euler angles, GPS velocity
interpolated to the IMU time, latitude/altitude) and returns an Estimate with the velocity and
attitude, the six IMU fault estimates f_hat, the corrected IMU ``u_m - f_hat`` (Lu2016 eq. 60)
and the innovations as residuals.

Between GPS samples the interpolated velocity is corrected by the interpolation error the
assembler measures from the IMU (``Frame.gps_interp_err_ned_mps``, ``gps_imu_shape``; ours):
Lu2016 sec. 5 interpolates 1 Hz GPS linearly, whose error in a manoeuvre the filter would read
as an accelerometer fault (docs/papers-notes.md, "Sec. 5: the GPS velocity between 1 Hz
samples").
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace

import numpy as np

from gcs_monitor.core.atmosphere import gravity_mps2, tas_from_cas
from gcs_monitor.core.frames import euler_rates
from gcs_monitor.core.kernels import load_kernels
from gcs_monitor.core.params import param, section
from gcs_monitor.core.types import ChannelId, Mat, Vec
from gcs_monitor.families.imu.gating import (
    SQRT2,
    SQRT6,
    GateConfig,
    GateDecision,
    MeasurementStepGate,
    intra_sample_excess_var,
    step_bound,
)
from gcs_monitor.fdi.records import Estimate
from gcs_monitor.filters.ekf import Innovation
from gcs_monitor.filters.two_stage import (
    PackedTwoStage,
    TwoStageConfig,
    TwoStageNoise,
    TwoStageState,
    two_stage_init,
    two_stage_predict,
    two_stage_step,
)
from gcs_monitor.models.kinematics import AsKm, GsKm
from gcs_monitor.telemetry.frame import Frame, ImuSample
from gcs_monitor.telemetry.period import SamplePeriod

log = logging.getLogger(__name__)

_DEG = math.pi / 180.0
US_PER_S = 1_000_000
GPS_FIX_3D = 3  # GPS_RAW_INT fix_type of a 3D fix
FAULT_CHANNELS = (
    ChannelId("acc", 0, "x"), ChannelId("acc", 0, "y"), ChannelId("acc", 0, "z"),
    ChannelId("gyro", 0, "p"), ChannelId("gyro", 0, "q"), ChannelId("gyro", 0, "r"),
)  # fmt: skip



def fault_channels(instance: int) -> tuple[ChannelId, ...]:
    """The six fault channels of IMU ``instance`` (accelerometer x, y, z; gyro p, q, r)."""
    return tuple(ChannelId(c.kind, instance, c.axis) for c in FAULT_CHANNELS)


_EULER_CHANNELS = (
    ChannelId("euler", 0, "phi"), ChannelId("euler", 0, "theta"), ChannelId("euler", 0, "psi"),
)  # fmt: skip
_ZEROS6 = (0.0,) * 6  # no extra input variance (gates)
_ANGLE_ROWS = (3, 5)  # phi and psi wrap at +-pi; theta stays within +-pi/2
RESIDUAL_CHANNELS_GS = (
    ChannelId("gps_vel", 0, "n"), ChannelId("gps_vel", 0, "e"), ChannelId("gps_vel", 0, "d"),
) + _EULER_CHANNELS  # fmt: skip
RESIDUAL_CHANNELS_AS = (ChannelId("tas", 0), ChannelId("aoa", 0), ChannelId("ssa", 0)) + (
    _EULER_CHANNELS
)


@dataclass(frozen=True, slots=True)
class Lu2016Table1:
    """Sensor noise standard deviations (Lu2016 Table 1)."""

    tas_sigma_mps: float = param(0.1, "true airspeed noise sigma_V (AS-KM only)", positive=True)
    vel_sigma_mps: float = param(0.01, "GPS velocity noise sigma_UN, sigma_UE, sigma_UD",
                                 positive=True)
    aoa_sigma_rad: float = param(0.1 * _DEG, "AoA and sideslip noise sigma_alpha, sigma_beta "
                                 "(AS-KM only)", positive=True)
    euler_sigma_rad: float = param(0.01 * _DEG, "attitude noise sigma_phi, sigma_theta, "
                                   "sigma_psi", positive=True)
    acc_sigma_mps2: float = param(0.01, "accelerometer noise sigma_Ax, sigma_Ay, sigma_Az",
                                  positive=True)
    gyro_sigma_radps: float = param(0.01 * _DEG, "gyro noise sigma_p, sigma_q, sigma_r",
                                    positive=True)


@dataclass(frozen=True, slots=True)
class FaultPrior:
    """Initial fault covariance and initial (IOTSEKF: fixed) fault random walk ``Q^f``.

    Lu2016 gives no values. Choice: the random walk per sample should let the estimate follow
    the fastest fault of Lu2016 Table 2, so its per-second rate is the largest |df/dt| there:
    f_Az = 4 sin(0.5 pi t) -> 2 pi m/s^3; f_q = (pi/180) sin(0.5 pi (t-10)) -> 0.5 pi (pi/180)
    rad/s^2. ``Q^f = diag((rate * dt)^2)``. With the ATSEKF this only matters for the first N
    steps, after which eqs. 53-58 replace it. The initial fault covariance is wide (faults
    may already be present at start-up): 5 m/s^2 and 5 deg/s, 1 sigma.
    """

    acc_rate_sigma_mps3: float = param(2.0 * math.pi, "accelerometer fault random-walk rate "
                                       "(largest |df/dt| of Lu2016 Table 2)", positive=True)
    gyro_rate_sigma_radps2: float = param(0.5 * math.pi * _DEG, "gyro fault random-walk rate "
                                          "(largest |df/dt| of Lu2016 Table 2)", positive=True)
    acc_init_sigma_mps2: float = param(5.0, "initial accelerometer fault sigma", positive=True)
    gyro_init_sigma_radps: float = param(5.0 * _DEG, "initial gyro fault sigma", positive=True)


@dataclass(frozen=True, slots=True)
class ImuTsConfig:
    """Configuration of the Lu2016 ATSEKF / IOTSEKF IMU fault estimator."""

    model: str = param("gs", "kinematic model: gs = GS-KM (Lu2016 eqs. 11-14, GPS velocity), "
                       "as = AS-KM (eqs. 15-20, air data)", choices=("gs", "as"))
    adaptive: bool = param(True, "true = ATSEKF (covariance matching, eqs. 53-58); false = "
                           "IOTSEKF with a fixed Q^f")
    follow_primary: bool = param(True, "monitor the primary IMU, restarting on the new one when "
                                 "the primary switches (false: always imu_instance)")
    imu_instance: int = param(0, "the IMU instance (HIGHRES_IMU id) monitored when "
                              "follow_primary is false")
    noise: Lu2016Table1 = section(Lu2016Table1, "sensor noise (Lu2016 Table 1)")
    prior: FaultPrior = section(FaultPrior, "fault prior and initial fault random walk")
    filter: TwoStageConfig = section(TwoStageConfig, "two-stage filter algorithm settings "
                                     "(Lu2016 sec. 3.1)")
    max_gps_age_s: float = param(0.5, "older GPS velocity makes the estimate unavailable",
                                 positive=True)
    max_held_gps_age_s: float = param(0.1, "a GPS velocity held past its sample (no later "
                                      "sample to interpolate towards) is not used beyond this "
                                      "age (its error is |dv/dt| x age)", positive=True)
    gps_imu_shape: bool = param(True, "between GPS samples the interpolated velocity follows "
                                "the IMU-integrated velocity's deviation from its chord "
                                "(telemetry/samples.py imu_chord): a GPS slower than the IMU "
                                "does not turn the manoeuvre inside its interval into an "
                                "accelerometer fault (ours; Lu2016 sec. 5 interpolates "
                                "linearly)")
    max_gps_gap_s: float = param(1.0, "a GPS velocity missing for up to this long after the "
                                 "last one used (a lost, late or repeated GPS sample) is "
                                 "bridged: the states are propagated with the IMU alone (the "
                                 "time update without a measurement), the fault estimates "
                                 "kept; beyond it the estimate is unavailable (0: never "
                                 "bridged)")
    max_att_age_s: float = param(0.5, "older attitude makes the estimate unavailable",
                                 positive=True)
    max_air_age_s: float = param(0.5, "older air data makes the AS-KM estimate unavailable",
                                 positive=True)
    max_dt_s: float = param(0.1, "after a larger gap between usable samples the states are "
                            "re-anchored on the measurement (fault estimates kept when the "
                            "filter had converged), else the filter restarts", positive=True)
    max_gap_periods: float = param(2.5, "the gap limit is at least this many measured sample "
                                   "periods (a slow IMU is not a gap)", positive=True)
    gate: GateConfig = section(GateConfig, "input-validity term and GPS-velocity / attitude "
                               "step gates (ours, families/imu/gating.py; GS-KM only)")
    start_warmup_s: float = param(5.0, "convergence time of the fault estimates after a "
                                  "(re)start: the FDI does not judge them before")
    reanchor_warmup_s: float = param(2.0, "the same after a re-anchoring of the states with "
                                     "the fault estimates kept (input gap, rejected step)")


def _all_finite(a: Vec) -> bool:
    """``np.all(np.isfinite(a))`` for a short vector, on Python floats (cheaper at n = 3-6)."""
    return all(map(math.isfinite, a.ravel().tolist() if isinstance(a, np.ndarray) else a))


def _wrap_pi(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


class ImuTwoStageEstimator:
    """ATSEKF (or IOTSEKF) IMU fault estimator of Lu2016 behind the Estimator protocol."""

    def __init__(self, config: ImuTsConfig | None = None) -> None:
        self.cfg = config or ImuTsConfig()
        if self.cfg.model not in ("gs", "as"):
            raise ValueError(f"ImuTsConfig.model must be 'gs' or 'as', got {self.cfg.model!r}")
        self.name = "imu_ts" if self.cfg.model == "gs" else "imu_ts_as"
        # the GS-KM reads Frame.gps_interp_err_ned_mps (gps_imu_shape); the assembler computes
        # it only when some estimator does
        self.reads_interp_error = self.cfg.model == "gs" and self.cfg.gps_imu_shape
        nz = self.cfg.noise
        sig_u = [nz.acc_sigma_mps2] * 3 + [nz.gyro_sigma_radps] * 3
        if self.cfg.model == "gs":
            sig_y = [nz.vel_sigma_mps] * 3 + [nz.euler_sigma_rad] * 3  # Lu2016 eq. 55
        else:
            sig_y = [nz.tas_sigma_mps, nz.aoa_sigma_rad, nz.aoa_sigma_rad] + [
                nz.euler_sigma_rad
            ] * 3
        self._noise = TwoStageNoise(
            Q=np.diag(np.square(sig_u)), R=np.diag(np.square(sig_y))
        )  # eq. 56
        self._fcfg = TwoStageConfig(
            eps0=self.cfg.filter.eps0,
            n_iterated_steps=self.cfg.filter.n_iterated_steps,
            max_iterations=self.cfg.filter.max_iterations,
            adapt=self.cfg.adaptive,
            window_n=self.cfg.filter.window_n,
            gate_sigma=self.cfg.filter.gate_sigma,
        )
        self._d2_floor = [self.cfg.gate.gate_sigma * SQRT6 * x for x in sig_u]  # gating item 1
        # its sample-timing term (first difference), unless turned off
        self._d1_floor = ([self.cfg.gate.gate_sigma * SQRT2 * x for x in sig_u]
                          if self.cfg.gate.sample_timing else [])
        # velocity rows 0-2 and Euler rows 3-5 are gated separately (gating.py item 2)
        self._gates = (MeasurementStepGate(self.cfg.gate), MeasurementStepGate(self.cfg.gate))
        self._state: TwoStageState | None = None
        self._u_prev: Vec | None = None
        self._u_prev2: list[float] | None = None  # input at k-2 and k-1, plain floats
        self._u_prev_l: list[float] = []
        self._r_prev = [0.0] * 6  # previous measured minus estimated output (gates)
        self._t_prev_us = 0
        self._t_meas_us = 0  # vehicle time of the last measurement update
        self._rejected = False  # the step gate rejected rows of this sample
        # extra attitude variance of the last measurement when it was a held sample
        self._att_held_var: tuple[float, ...] = ()
        self._period = SamplePeriod()  # of its usable samples: gap limit, re-anchoring
        self._instance: int | None = None  # the IMU instance monitored
        self._restart_why = ""
        self._channels: tuple[ChannelId, ...] = FAULT_CHANNELS
        self._t_start_us = 0  # time of the last full (re)start
        # Compiled hot path (GS-KM, numba): one kernel call (_imu_ts_jit.gs_km_step) writes F, G
        # and the propagated x_bar into these work arrays and runs the PackedTwoStage filter
        # step; the same equations and operations as two_stage_step (tests/.../test_imu_ts.py).
        gs_km = self.cfg.model == "gs"
        self._kern = load_kernels("gcs_monitor.families.imu._imu_ts_jit") if gs_km else None
        self._packed: PackedTwoStage | None = None
        if self._kern is not None:
            load_kernels("gcs_monitor.models._kinematics_jit")  # its dependency check
            self._packed = PackedTwoStage(6, 6, 6, self._fcfg.window_n)
            self._F = np.zeros((6, 6))
            self._G = np.zeros((6, 6))
            self._xb = np.zeros(6)
            self._g_key = (math.nan, math.nan)
            self._g = math.nan

    # -- protocol ------------------------------------------------------------------------------
    def reset(self) -> None:
        self._state = None
        self._u_prev = None
        self._u_prev2 = None
        self._u_prev_l = []
        self._period.reset()
        for g in self._gates:
            g.reset()

    def step(self, frame: Frame) -> Estimate:
        cfg = self.cfg
        inst = frame.primary if cfg.follow_primary else cfg.imu_instance
        imu = frame.imu[inst] if inst < len(frame.imu) else None
        if imu is None or frame.t_us - imu.t_us > cfg.max_dt_s * US_PER_S:
            return Estimate.unavailable(self.name, frame.t_us, f"imu{inst} missing or stale")
        switched = inst != self._instance
        if switched:
            if self._instance is not None:  # the monitored IMU changed: a clean restart
                log.info("imu_ts: IMU %d -> %d at t_us=%d, restart", self._instance, inst,
                         frame.t_us)
                self.reset()
                self._restart_why = f"primary IMU switched from {self._instance} to {inst}"
            self._instance = inst
            self._channels = fault_channels(inst)
        if frame.euler_rad is None or frame.att_age_s > cfg.max_att_age_s:
            return Estimate.unavailable(self.name, frame.t_us, "attitude missing or stale")
        geo = math.isfinite(frame.lat_rad) and math.isfinite(frame.alt_msl_m)
        if not geo and cfg.model == "as":  # the AS-KM measurement needs the altitude (TAS)
            return Estimate.unavailable(self.name, frame.t_us, "latitude/altitude missing")
        y = self._measurement(frame)
        if y is None and geo:
            bridged = self._bridge(frame, imu)
            if bridged is not None:
                return bridged
        if y is None:
            if cfg.model == "as":
                why = "air data (cas, aoa, ssa) missing or stale"
            elif 0 <= frame.gps_fix < GPS_FIX_3D:
                why = f"gps velocity missing: no 3D fix (GPS fix type {frame.gps_fix})"
            else:
                why = "gps velocity missing or stale"
            return Estimate.unavailable(self.name, frame.t_us, why)
        if not geo:  # GS-KM: position comes with the GPS velocity; a bad field alone
            return Estimate.unavailable(self.name, frame.t_us, "latitude/altitude missing")
        u_m = np.concatenate([imu.acc_frd_mps2, imu.omega_frd_radps])
        u_l = u_m.tolist()  # the input as plain floats (gates, f_hat, corrected IMU)
        if not all(map(math.isfinite, u_l)):
            return Estimate.unavailable(self.name, frame.t_us, "imu sample not finite")
        dt_s = (frame.t_us - self._t_prev_us) * 1e-6
        self._period.add(frame.t_us)
        max_dt_s = max(cfg.max_dt_s, cfg.max_gap_periods * self._period.seconds()) \
            if self._period.known else cfg.max_dt_s
        dt_meas_s = (frame.t_us - self._t_meas_us) * 1e-6  # since the last measurement used
        self._t_meas_us = frame.t_us
        if self._state is None or self._u_prev is None or not 0.0 < dt_s <= max_dt_s:
            converged = frame.t_us - self._t_start_us >= cfg.start_warmup_s * 1e6
            if self._state is not None and dt_s > 0.0 and cfg.gate.enabled and converged:
                self._state = self._reanchor(self._state, y, dt_s)
                why = f"input gap {dt_s:.2f} s: states re-anchored, fault estimates kept"
                warm = cfg.reanchor_warmup_s
            else:
                self._state = self._init_state(y)
                why, warm = self._restart_why or "start", cfg.start_warmup_s
                self._restart_why = ""
                self._t_start_us = frame.t_us
            self._u_prev, self._u_prev2, self._t_prev_us = u_m, None, frame.t_us
            self._u_prev_l = u_l
            self._r_prev = [0.0] * 6
            for g in self._gates:
                g.reset()
            return replace(self._estimate(frame.t_us, self._state, u_m, np.zeros(y.size), True),
                           reinit=why, reinit_warmup_s=warm)
        s = self._state
        if s.k == 0:  # the first step after a start: Q^f for the measured sample interval
            s = replace(s, Qf=self.qf0(dt_s))
        # y is this step's own array (_measurement); plain floats, same operations
        x_l = s.x.tolist()
        y[5] = x_l[5] + _wrap_pi(float(y[5]) - x_l[5])  # heading innovation across +-pi
        if abs(float(y[3]) - x_l[3]) > math.pi:  # roll across +-pi (a vehicle on its back)
            y[3] = x_l[3] + _wrap_pi(float(y[3]) - x_l[3])
        noise, extra = self._noise, None
        gate_on = cfg.gate.enabled
        if gate_on and self._u_prev2 is not None:
            # gating.py item 1: unresolved intra-sample input profile is process noise (eq. 56)
            extra = intra_sample_excess_var(self._u_prev2, self._u_prev_l, u_l, self._d2_floor,
                                            self._d1_floor)
            if extra is not None:
                Q = self._noise.Q.copy()  # Q + diag(extra): its off-diagonal zeros stay zeros
                Q.flat[::7] += extra
                noise = TwoStageNoise(Q=Q, R=self._noise.R)
        held_prev = self._att_held_var
        gs = cfg.model == "gs"
        if gs and frame.att_age_s > 0.0:
            noise, self._att_held_var = self._held_attitude_noise(noise, s, u_m,
                                                                  frame.att_age_s)
        else:
            self._att_held_var = ()
        if self._packed is not None and s.k >= self._fcfg.n_iterated_steps:
            new, innov = self._step_packed(s, frame, u_m, y, dt_s, noise)
        else:
            new, innov = two_stage_step(s, self._model(frame), self._u_prev, u_m, y, dt_s,
                                        noise, self._fcfg)
        why = ""
        self._rejected = False
        if gate_on and gs and innov.numerics_ok:
            why, new, innov = self._gated(s, frame, u_m, y, dt_s, noise, extra, new, innov,
                                          dt_meas_s, held_prev)
        self._u_prev2, self._u_prev_l = self._u_prev_l, u_l
        self._u_prev, self._t_prev_us = u_m, frame.t_us
        if not innov.numerics_ok:
            log.warning("imu_ts: numerical failure at t_us=%d, filter reset", frame.t_us)
            self.reset()
            est = self._estimate(frame.t_us, s, u_m, innov.nu, False)
            return est
        xn = new.x.tolist()
        if abs(xn[5]) > math.pi or abs(xn[3]) > math.pi:
            # keep phi and psi in (-pi, pi]; a 2 pi shift leaves P unchanged
            shift = np.zeros(6)
            for i in _ANGLE_ROWS:
                shift[i] = _wrap_pi(xn[i]) - xn[i]
            new = replace(new, x_bar=new.x_bar + shift, x=new.x + shift)
            xn = new.x.tolist()
        self._state = new
        r = [a - b for a, b in zip(y.tolist(), xn, strict=True)]
        r[5] = _wrap_pi(r[5])  # y[5] was unwrapped against the previous state, new.x may wrap
        if abs(r[3]) > math.pi:
            r[3] = _wrap_pi(r[3])
        self._r_prev = r
        # a sample the step gate rejected is a reference step, not noise: its test ratios do
        # not enter the noise-model consistency check (family.py)
        est = self._estimate(frame.t_us, new, u_m, innov.nu, True,
                             None if self._rejected else innov.test_ratio, u_l)
        if why:
            return replace(est, reinit=why, reinit_warmup_s=cfg.reanchor_warmup_s)
        return est

    # -- helpers -------------------------------------------------------------------------------
    def _held_attitude_noise(self, noise: TwoStageNoise, s: TwoStageState, u_m: Vec,
                             age_s: float) -> tuple[TwoStageNoise, tuple[float, ...]]:
        """Attitude noise of a held ATTITUDE sample (``age_s`` older than the IMU sample): it
        is the attitude of an earlier instant, off by the rotation since, so its variance
        grows by ``(euler_rate x age)^2`` per angle (Euler rates from the corrected gyro,
        Lu2016 eq. 11). A slower attitude stream (ArduCopter logs ATT at 10 Hz while the IMU
        runs at 50 Hz) is then used for what it is, and the attitude step gate (gating.py) does
        not take the jump at its next sample for an unexplained step."""
        w = u_m[3:] - s.f[3:]
        rates = euler_rates(float(s.x[3]), float(s.x[4]), w)
        add = tuple((float(r) * age_s) ** 2 for r in rates)
        R = noise.R.copy()
        for i in range(3):
            R[3 + i, 3 + i] += add[i]
        return TwoStageNoise(Q=noise.Q, R=R), add

    def _bridge(self, frame: Frame, imu: ImuSample) -> Estimate | None:
        """The time update alone across a short GPS gap (``max_gps_gap_s``): the states follow
        the IMU, the fault estimates and their covariance carry on (two_stage_predict); None
        when the gap is too long or there is nothing to propagate (the caller reports the
        estimate unavailable)."""
        cfg = self.cfg
        s = self._state
        if (cfg.model != "gs" or s is None or self._u_prev is None or s.k == 0
                or frame.t_us - self._t_meas_us > cfg.max_gps_gap_s * US_PER_S):
            return None
        dt_s = (frame.t_us - self._t_prev_us) * 1e-6
        max_dt_s = max(cfg.max_dt_s, cfg.max_gap_periods * self._period.seconds()) \
            if self._period.known else cfg.max_dt_s
        u_m = np.concatenate([imu.acc_frd_mps2, imu.omega_frd_radps])
        if not (0.0 < dt_s <= max_dt_s and _all_finite(u_m)):
            return None
        u_l = u_m.tolist()
        noise = self._noise
        if cfg.gate.enabled and self._u_prev2 is not None:
            extra = intra_sample_excess_var(self._u_prev2, self._u_prev_l, u_l, self._d2_floor,
                                            self._d1_floor)
            if extra is not None:
                noise = TwoStageNoise(Q=self._noise.Q + np.diag(extra), R=self._noise.R)
        new = two_stage_predict(s, self._model(frame), self._u_prev, u_m, dt_s, noise)
        if new is None:
            return None
        if abs(new.x[5]) > math.pi or abs(new.x[3]) > math.pi:
            shift = np.zeros(6)
            for i in _ANGLE_ROWS:
                shift[i] = _wrap_pi(new.x[i]) - new.x[i]
            new = replace(new, x_bar=new.x_bar + shift, x=new.x + shift)
        self._period.add(frame.t_us)
        self._state = new
        self._u_prev2, self._u_prev_l = self._u_prev_l, u_l
        self._u_prev, self._t_prev_us = u_m, frame.t_us
        return self._estimate(frame.t_us, new, u_m, np.zeros(6), True)

    def _step_packed(self, s: TwoStageState, frame: Frame, u_m: Vec, y: Vec, dt_s: float,
                     noise: TwoStageNoise) -> tuple[TwoStageState, Innovation]:
        """``two_stage_step(s, GsKm(lat, alt), ...)`` through the compiled GS-KM and filter, in
        one kernel call (``_imu_ts_jit.gs_km_step``)."""
        assert self._kern is not None and self._packed is not None and self._u_prev is not None
        lat, alt = frame.lat_rad, frame.alt_msl_m
        if (lat, alt) != self._g_key:  # GsKm.propagate's gravity, once per GPS position
            self._g_key = (lat, alt)
            self._g = gravity_mps2(lat, alt)
        # Lu2016 note 1 (F, G at x_hat with u_m - f_hat) and eq. 31, then the filter step
        return self._packed.step_with(
            self._kern.gs_km_step, (self._u_prev, u_m, lat, alt, self._g, self._F, self._G,
                                    self._xb), s, y, dt_s, noise, self._fcfg)

    def _model(self, frame: Frame) -> GsKm | AsKm:
        if self.cfg.model == "gs":
            return GsKm(frame.lat_rad, frame.alt_msl_m)
        return AsKm(frame.lat_rad, frame.alt_msl_m)

    def _measurement(self, frame: Frame) -> Vec | None:
        cfg = self.cfg
        eul = np.asarray(frame.euler_rad, dtype=np.float64)
        if self.cfg.model == "gs":
            v = frame.gps_vel_ned_mps
            if v is None or not frame.gps_fresh(cfg.max_gps_age_s) or not _all_finite(v):
                return None
            if frame.gps_held and frame.gps_age_s > cfg.max_held_gps_age_s:
                return None
            err = frame.gps_interp_err_ned_mps
            if err is not None and cfg.gps_imu_shape:
                v = v - err
            return np.concatenate([v, eul])
        cas, aoa, ssa = float(frame.cas_mps[0]), float(frame.aoa_rad[0]), frame.ssa_rad
        fresh = frame.air_age_s <= cfg.max_air_age_s or (
            frame.cas_age_s[0] <= cfg.max_air_age_s and frame.aoa_age_s[0] <= cfg.max_air_age_s
        )
        if (
            not (fresh and math.isfinite(cas) and math.isfinite(aoa) and math.isfinite(ssa))
            or cas <= 0.0
        ):
            return None
        tas = tas_from_cas(cas, frame.alt_msl_m)
        return np.concatenate([[tas, aoa, ssa], eul])

    def _init_state(self, y: Vec) -> TwoStageState:
        p = self.cfg.prior
        if self.cfg.model == "gs":
            x0 = y.copy()
        else:
            tas, aoa, ssa = y[0], y[1], y[2]
            x0 = np.array(
                [
                    tas * math.cos(aoa) * math.cos(ssa),
                    tas * math.sin(ssa),
                    tas * math.sin(aoa) * math.cos(ssa),
                    y[3],
                    y[4],
                    y[5],
                ]
            )
        P0 = self._init_cov(x0)
        Pf0 = np.diag(np.square([p.acc_init_sigma_mps2] * 3 + [p.gyro_init_sigma_radps] * 3))
        return two_stage_init(
            x0,
            P0,
            np.zeros(6),
            Pf0,
            self.qf0(0.0),  # set at the first step, from its measured interval
            m=6,
            window_n=self._fcfg.window_n,
        )

    def _reanchor(self, s: TwoStageState, y: Vec, gap_s: float) -> TwoStageState:
        """States from the measurement after an input gap; fault estimate kept, its covariance
        grown by the random walk of the fault model (Lu2016 sec. 3.1) over the gap."""
        fresh = self._init_state(y)
        n_steps = gap_s / self._period.seconds()  # steps of the measured sample period
        return replace(fresh, f=s.f.copy(), Pf=s.Pf + n_steps * s.Qf, Qf=s.Qf.copy(), k=s.k)

    def _gated(self, s: TwoStageState, frame: Frame, u_m: Vec, y: Vec, dt_s: float,
               noise: TwoStageNoise, extra: list[float] | None, new: TwoStageState,
               innov: Innovation, dt_meas_s: float, held_prev: tuple[float, ...] = (),
               ) -> tuple[str, TwoStageState, Innovation]:
        """Velocity and attitude step gates (gating.py item 2) on a finished step; re-runs the
        step without the rejected rows only when a gate does not accept. The increment it
        tests spans ``dt_meas_s``, the time since the previous measurement used (one sample
        interval, or a bridged GPS gap), and so does the fault step it admits; from a held
        previous attitude it also allows that sample's ``(rate x age)^2`` (``held_prev``)."""
        g = self.cfg.gate
        ex = _ZEROS6 if extra is None else extra
        nu, sd, r = innov.nu.tolist(), innov.S_diag.tolist(), self._r_prev
        dt_gate_s = max(dt_s, dt_meas_s)
        gate_vel, gate_att = self._gates  # velocity rows 0-2, attitude rows 3-5
        decisions = (
            gate_vel.decide(nu[:3], r[:3], step_bound(
                sd[:3], ex[:3], dt_gate_s, g.gate_sigma, g.acc_fault_step_max_mps2)),
            gate_att.decide(nu[3:], r[3:], step_bound(
                sd[3:], ex[3:], dt_gate_s, g.gate_sigma, g.gyro_fault_step_max_radps,
                held_var=held_prev)),
        )
        if decisions[0] is GateDecision.ACCEPT and decisions[1] is GateDecision.ACCEPT:
            return "", new, innov
        self._rejected = True
        # no information from the rejected rows this sample: the measurement is replaced by the
        # prediction (zero innovation); the real innovation is still reported
        y_pred = y.copy()
        for j, d in enumerate(decisions):
            if d is not GateDecision.ACCEPT:
                y_pred[3 * j:3 * j + 3] -= innov.nu[3 * j:3 * j + 3]
        assert self._u_prev is not None  # step only gates after a step from _u_prev
        new, innov2 = two_stage_step(s, self._model(frame), self._u_prev, u_m, y_pred, dt_s,
                                     noise, self._fcfg)
        if not innov2.numerics_ok:
            return "", new, innov2
        why = []
        for j, (d, what, unit) in enumerate(zip(
                decisions, ("gps velocity", "attitude"), ("m/s", "rad"), strict=True)):
            if d is GateDecision.REANCHOR:
                new = self._reanchor_rows(new, slice(3 * j, 3 * j + 3), y[3 * j:3 * j + 3])
                why.append(f"{what} step {self._gates[j].last_step:.3g} {unit}")
        if not why:
            return "", new, innov
        return (" and ".join(why) + " not explained by the IMU: states re-anchored, fault "
                "estimates kept"), new, innov

    def _reanchor_rows(self, s: TwoStageState, rows: slice, value: Vec) -> TwoStageState:
        """States ``rows`` set to the measurement (gating.py item 2); fault estimate, the other
        states and the fault/state coupling V kept: ``x = x_bar + V f`` (Lu2016 eq. 51)."""
        x = s.x.copy()
        x_bar = s.x_bar.copy()
        x[rows] = value
        x_bar[rows] = value - s.V[rows] @ s.f
        P_bar = s.P_bar.copy()
        P_bar[rows, :] = 0.0
        P_bar[:, rows] = 0.0
        P_bar[rows, rows] = self._noise.R[rows, rows]
        Px = P_bar + s.V @ s.Pf @ s.V.T  # eq. 52
        return replace(s, x=x, x_bar=x_bar, P_bar=P_bar, Px=Px)

    def _init_cov(self, x0: Vec) -> Mat:
        # first measurement as the estimate: its covariance is R mapped through h^{-1}
        if self.cfg.model == "gs":
            return self._noise.R.copy()
        Hinv = np.linalg.solve(AsKm(0.0, 0.0).h_jac(x0), np.eye(6))
        return Hinv @ self._noise.R @ Hinv.T

    def qf0(self, dt_s: float) -> Mat:
        """Initial (IOTSEKF: fixed) ``Q^f`` for a sample interval, see :class:`FaultPrior`."""
        p = self.cfg.prior
        return np.diag(
            np.square([p.acc_rate_sigma_mps3 * dt_s] * 3 + [p.gyro_rate_sigma_radps2 * dt_s] * 3)
        )

    def _estimate(self, t_us: int, s: TwoStageState, u_m: Vec, nu: Vec, ok: bool,
                  test_ratio: Vec | None = None, u_l: list[float] | None = None) -> Estimate:
        """The Estimate of state ``s``; ``u_l``: ``u_m.tolist()`` when the caller has it."""
        x = s.x
        f = s.f.tolist()
        if u_l is None:
            u_l = u_m.tolist()
        u_hat = [a - b for a, b in zip(u_l, f, strict=True)]  # Lu2016 eq. 60: u_m - f_hat
        if self.cfg.model == "gs":
            states = {"vel_ned_mps": x[:3].copy(), "euler_rad": x[3:].copy()}
            if test_ratio is not None:  # nu_i^2 / (gate^2 S_ii) per row: consistency check
                states["test_ratio"] = test_ratio
            res_names = RESIDUAL_CHANNELS_GS
        else:
            states = {"vel_air_frd_mps": x[:3].copy(), "euler_rad": x[3:].copy()}
            res_names = RESIDUAL_CHANNELS_AS
        chans = self._channels
        return Estimate(
            name=self.name,
            t_us=t_us,
            states=states,
            faults=dict(zip(chans, f, strict=True)),
            residuals=dict(zip(res_names, nu.tolist(), strict=True)),
            virtual=dict(zip(chans, u_hat, strict=True)),
            numerics_ok=ok,
        )
