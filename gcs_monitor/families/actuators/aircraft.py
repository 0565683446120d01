"""Aircraft tier of the actuator family: surfaces and engine judged from what every autopilot
sends (no surface feedback, as on small UAVs).

One axis per actuator, each a linear model identified online by recursive least squares with
forgetting (Keipour, Mousaei and Scherer, ICRA 2019: RLS on correlated input-output pairs),
in one of two forms depending on what the telemetry carries:

* **servo** -- the command is the actuator's own output (SERVO_OUTPUT_RAW): the body rate of
  its axis against the commanded deflection scaled by dynamic pressure, the previous rate and
  a coupling term (a control-effectiveness model)::

      aileron   p_k = b u_a s + a p + c r + d
      elevator  q_k = b u_e s + a q + c f_z + d
      rudder    r_k = b u_r s + a r + c f_y + c' p + d
      engine    f_x,k = b lag_tau(thr) + a s + c f_z + d

  every right-hand term taken at the previous control sample k-1 (causal: see
  :meth:`AircraftTier._regression`), with ``s = (V / V_ref)^2``, ``f`` the specific force
  (FRD), ``thr`` the throttle 0..1 and ``lag_tau`` a first-order lag of it (its time constant
  the data's choice, :meth:`AircraftTier._throttle_lag`);
* **setpoint** -- no servo outputs: the command is the attitude error the autopilot is
  correcting (NAV_CONTROLLER_OUTPUT minus ATTITUDE), a closed-loop model: roll rate against
  the bank error, pitch rate against the pitch error, yaw rate against the coordinated-turn
  yaw rate ``g sin(phi) cos(theta) / V``, and the body-x specific force against the energy
  error ``aspd_error + g alt_error / V``.

Two RLS per axis: a *reference* model with a long memory, frozen while any axis is suspected
(so a fault is never learned as healthy), and a short-memory *tracking* regression of the
reference's prediction error on the command alone, ``e = b (kappa - 1) x + c``: with the
other terms held at their reference values it stays well conditioned where a full refit would
trade the command's effect against correlated states. The
reference's a priori prediction error is divided by its own running RMS over healthy flight
(the normalised residual) and judged through the shared FDI layer: residual RMS window
(Wan2018 eq. 18), n_D-of-N confirmation, alarm state machine with ``actuator_fault``. Only a
thrust deficit counts for the engine. Isolation: among the confirmed axes, the one whose
J/J_th dominates is the actuator whose command no longer acts.

Two checks per axis: the *residual* check on the reference model's normalised prediction
error (an abrupt change), and the *effectiveness* check on the loss of effectiveness the
tracking regression finds, in standard errors (a parameter jump: the command no longer acts as
it did). Either confirms the axis.

Classification, by the command that no longer acts: ``kappa`` is the share of the command
that still acts. A stuck
surface has ``kappa ~ 0`` and sits where the response says it is: with servo outputs the
position that explains the response, ``u + e / b`` (``b`` the reference effectiveness, ``e``
its prediction error), averaged over the history ("stuck at zero" near neutral); without them
the position is unobservable. ``0 < kappa < 1`` is a loss of effectiveness of ``1 - kappa``.
The engine's loss is the thrust deficit over the reference's thrust at that throttle. The
engine's model regresses on the throttle through the lag the data show among a few (its thrust
spools up: see :meth:`AircraftTier._throttle_lag`); a deficit counts only up to the thrust the
model gives (an engine cannot lose more).

An axis steps when its command has a new sample and the response (body rates, specific force)
has changed since its last step: a logger that repeats its last IMU sample (ALFA's 20 Hz grid
over a 2.5 Hz IMU) gives no new information, and the measured step rate is reported; below
``min_rate_hz`` nothing is judged.
"""

from __future__ import annotations

import math
import statistics
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from gcs_monitor.core.constants import GRAVITY_STD_MPS2
from gcs_monitor.core.types import ChannelId
from gcs_monitor.families.actuators.config import (
    ACTUATORS,
    AircraftTierConfig,
    ResidualCheckConfig,
)
from gcs_monitor.families.base import AIRSPEED_CAS, VIRTUAL, FamilyContext, Verdict
from gcs_monitor.fdi.alarms import AlarmStateMachine
from gcs_monitor.fdi.config import samples_in
from gcs_monitor.fdi.confirmation import Confirmation, ConfirmationParams
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, ChannelStatus, FaultType
from gcs_monitor.fdi.records import Estimate, FamilyStatus
from gcs_monitor.fdi.residuals import ResidualRms, RmsWindowParams
from gcs_monitor.filters.rls import RlsFilter, huber_weight
from gcs_monitor.telemetry.frame import Frame
from gcs_monitor.telemetry.period import SamplePeriod

US_PER_S = 1_000_000
ENGINE = 3
# the engine models' throttle lags: these shares of ``engine_lag_max_s`` (0: no lag)
ENGINE_LAG_SHARES = (0.0, 1.0 / 9.0, 1.0 / 3.0, 1.0)
# another lag's model replaces the engine's when its healthy residual variance is below this
# share of the current one's, with at least LAG_MIN_SAMPLES samples in it
LAG_SWITCH_RATIO = 0.8
LAG_MIN_SAMPLES = 100
# after a telemetry gap the engine is judged again after this many of its lag's time constants
# (the throttle in the gap is unknown; 3 time constants leave 5 % of its effect)
LAG_SETTLE = 3.0
ESTIMATOR = "actuators_aircraft"
STOP_SHARE = 0.98  # a surface command at or beyond this share of its full deflection is at the stop
PERIOD_REFRESH = 50  # axis steps between two re-measurements of the step period
ESTIMATE_PERIOD_US = 100_000  # estimates (dashboard, evaluation) at most at 10 Hz
SERVO, SETPOINT = "servo", "setpoint"
CHANNELS = tuple(ChannelId("actuator", i, name) for i, name in enumerate(ACTUATORS))
# the effectiveness checks' statuses (their alarms are the actuator's own channel's)
EFF_CHANNELS = tuple(ChannelId("actuator_effectiveness", i, name)
                     for i, name in enumerate(ACTUATORS))
RAD2DEG = 180.0 / math.pi
# MAV_TYPE of the vehicles whose control surfaces and engine the tier models: fixed wing and the
# VTOL types that fly as aeroplanes (common.xml: 1; 19-25); -1 (no HEARTBEAT yet) is judged
FIXED_WING_TYPES = frozenset({-1, 1, 19, 20, 21, 22, 23, 24, 25})


@dataclass(frozen=True, slots=True)
class Signals:
    """What one frame offers the axes, SI (NaN / None where absent)."""

    t_us: int
    omega: tuple[float, float, float]  # body rates FRD
    f: tuple[float, float, float]  # specific force FRD
    euler: tuple[float, float, float] | None
    airspeed_mps: float
    u_rad: tuple[float, float, float]  # commanded deflections from the servo outputs
    throttle: float  # 0..1
    err_roll_rad: float  # nav_roll - roll
    err_pitch_rad: float  # nav_pitch - pitch
    energy_err_mps: float  # aspd_error + g alt_error / V
    servo_t_us: int
    nav_t_us: int
    hud_t_us: int
    airspeed_src: str = ""  # where airspeed_mps comes from (AircraftTier._signals)
    # why airspeed_mps is no measured, cross-checked airspeed (empty when it is): the engine's
    # thrust is told from drag by it (AircraftTier._not_judged)
    airspeed_doubt: str = ""


def _share(kappa: float) -> str:
    """The share of the command that still acts, as an operator reads it (0..100 %)."""
    return f"{100.0 * min(1.0, max(0.0, kappa)):.0f} %"


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


class _Check:
    """One residual check through the shared FDI layer: optional exponential smoothing of the
    value (a persistent fault is a bias; smoothing over ``smoothing_s`` divides the noise by
    about sqrt(2 smoothing_s / period)), then the RMS window (Wan2018 eq. 18) and n_D-of-N
    confirmation with hysteresis, sized with the axis's measured step period. A one-sided check
    keeps only negative values (a thrust deficit)."""

    __slots__ = ("cfg", "rms", "conf", "J", "faulty", "value", "one_sided", "_a", "_smooth")

    def __init__(self, cfg: ResidualCheckConfig, period_s: float, *,
                 one_sided: bool = False) -> None:
        n = samples_in(cfg.window_s, period_s)
        self.cfg = cfg
        self.one_sided = one_sided
        self.rms = ResidualRms(RmsWindowParams(rms_window_n=n))
        self.conf = Confirmation(ConfirmationParams(
            detect_n=max(1, round(cfg.detect_ratio * n)), eval_n=n, clear_ratio=cfg.clear_ratio,
            clear_n=samples_in(cfg.clear_s, period_s), latch=cfg.latch))
        self._a = math.exp(-period_s / cfg.smoothing_s) if cfg.smoothing_s > 0.0 else 0.0
        self._smooth = 0.0
        self.J = self.value = 0.0
        self.faulty = False

    def update(self, value: float) -> None:
        a = self._a
        self._smooth = v = a * self._smooth + (1.0 - a) * value
        if self.one_sided and v > 0.0:
            v = 0.0
        self.value = v
        self.J = self.rms.update(v)
        self.faulty = self.conf.update(self.J, self.cfg.threshold)

    @property
    def ratio(self) -> float:
        return self.J / self.cfg.threshold

    def suspected(self, ratio: float) -> bool:
        return self.faulty or self.J > ratio * self.cfg.threshold


@dataclass
class _LagModel:
    """One candidate engine lag's reference model and its healthy residual variance."""

    tau_s: float
    rls: RlsFilter
    sigma2: float = math.nan
    sigma_n: int = 0


def _sigma_step(sigma2: float, sigma_n: int, err: float, dt: float, memory_s: float,
                huber_c: float) -> tuple[float, int]:
    """One step of a healthy residual variance: an exact mean of the squared a priori errors
    until ``memory_s`` is reached, exponential after; an outlier counts at ``huber_c`` sigma."""
    sigma_n += 1
    a = max(1.0 / sigma_n, 1.0 - math.exp(-dt / memory_s))
    e2 = err * err
    if sigma_n > 1:
        e2 = min(e2, huber_c * huber_c * sigma2)
    return (e2 if sigma_n == 1 else (1.0 - a) * sigma2 + a * e2), sigma_n


@dataclass
class _Axis:
    """One actuator's models and FDI: the residual check on the reference model's normalised
    prediction error, the effectiveness check on the tracking model's loss of effectiveness."""

    index: int
    channel: ChannelId
    res_cfg: ResidualCheckConfig
    eff_cfg: ResidualCheckConfig
    one_sided: bool
    mode: str = ""
    ref: RlsFilter | None = None
    trk: RlsFilter | None = None
    sigma2: float = math.nan
    sigma_n: int = 0  # samples in sigma2 (an exact mean until its memory is reached)
    e_ref: float = 0.0  # the reference model's a priori prediction error of this step
    trk_sigma2: float = math.nan  # the tracking regression's own residual variance
    prev: Signals | None = None
    response: tuple[float, ...] = ()
    cmd_t_us: int = -1
    t_start_us: int = 0
    period: SamplePeriod = field(default_factory=SamplePeriod)
    period_s: float = math.nan  # the measured step period, refreshed every PERIOD_REFRESH steps
    steps: int = 0
    res: _Check | None = None
    eff: _Check | None = None
    alarm: AlarmStateMachine | None = None
    nu: float = 0.0
    z: float = 0.0  # loss of effectiveness, in standard errors
    judged: bool = False
    identified: bool = False  # the command's effect b has been identified (latched per model)
    hist: deque[tuple[int, float, float, float]] = field(default_factory=deque)
    next_class_us: int = 0
    effectiveness: float = math.nan
    position_rad: float = math.nan
    command_rad: float = math.nan
    # the engine: the throttle through each candidate lag, the model of each (the selected
    # one's is ``ref``) and which lag is selected
    thr_lag: list[float] = field(default_factory=list)
    lag_models: list[_LagModel] = field(default_factory=list)
    lag_k: int = 0
    settle_us: int = -1  # after a gap the engine is not judged before this time

    @property
    def faulty(self) -> bool:
        res, eff = self.res, self.eff
        return (res is not None and res.faulty) or (eff is not None and eff.faulty)

    def suspected(self, ratio: float) -> bool:
        """A check is confirmed, or its J is above ``ratio`` x J_th."""
        res, eff = self.res, self.eff
        return ((res is not None and res.suspected(ratio))
                or (eff is not None and eff.suspected(ratio)))

    @property
    def ratio(self) -> float:
        """The larger J / J_th of the two checks."""
        return max((c.ratio for c in (self.res, self.eff) if c is not None), default=0.0)

    @property
    def J(self) -> float:
        """J of the check with the larger J / J_th (what an alarm reports)."""
        checks = [c for c in (self.res, self.eff) if c is not None]
        return max(checks, key=lambda c: c.ratio).J if checks else 0.0

    @property
    def threshold(self) -> float:
        checks = [c for c in (self.res, self.eff) if c is not None]
        return max(checks, key=lambda c: c.ratio).cfg.threshold if checks else math.nan

    def reset(self, mode: str, t_us: int) -> None:
        self.mode = mode
        self.ref = self.trk = None
        self.sigma2 = math.nan
        self.sigma_n = 0
        self.trk_sigma2 = math.nan
        self.prev = None
        self.t_start_us = t_us
        self.period.reset()
        self.period_s = math.nan
        self.steps = 0
        self.hist.clear()
        self.res = self.eff = None  # rebuilt with the new step period
        self.nu = self.z = 0.0
        self.identified = False
        self.effectiveness = self.position_rad = math.nan
        self.thr_lag = []
        self.lag_models = []
        self.lag_k = 0
        self.settle_us = -1


class AircraftTier:
    """The aircraft tier of one vehicle (see the module docstring)."""

    name = "aircraft"

    def __init__(self, cfg: AircraftTierConfig, ctx: FamilyContext) -> None:
        self.cfg = cfg
        self.ctx = ctx
        fdi = cfg.fdi
        self.axes = [_Axis(i, CHANNELS[i], fdi.engine if i == ENGINE else fdi.surface,
                           fdi.effectiveness, one_sided=i == ENGINE)
                     for i in range(len(CHANNELS))]
        self._v_ref = cfg.model.airspeed_ref_mps
        self._history_us = round(cfg.fdi.classify.history_s * US_PER_S)  # classifier history
        # the engine models' candidate lags (ENGINE_LAG_SHARES of engine_lag_max_s; 0: none)
        lag_max = cfg.model.engine_lag_max_s
        self._lags = tuple(f * lag_max for f in ENGINE_LAG_SHARES) if lag_max > 0.0 else (0.0,)
        self._seen_inputs = False
        self._estimate: Estimate | None = None
        self._max_defl = cfg.outputs.max_deflection_rad
        self._cmd_key: tuple[int, int, int] = (-2, -2, -2)  # command samples seen last Frame
        # some axis has not stepped on the latest command yet (it waits for a new response:
        # ALFA's setpoints come at ~12 Hz, its IMU at 2.5 Hz)
        self._pending = True
        self._v_src = ""  # the airspeed's source the models were learnt on
        self._restart_why = ""  # why the models restarted last (the warm-up's reason) ...
        self._restart_us = -1  # ... and when

    # -- signals ---------------------------------------------------------------------------
    def _signals(self, frame: Frame) -> Signals | None:
        imu = frame.primary_imu
        if imu is None:
            return None
        # the autopilot's body rates (ATTITUDE), else the gyro; rates that are exactly zero
        # on every axis are a producer's placeholder, not a measurement
        w = frame.att_rate_frd_radps
        omega = tuple(w.tolist()) if w is not None else (0.0, 0.0, 0.0)
        if omega == (0.0, 0.0, 0.0):
            omega = tuple(imu.omega_frd_radps.tolist())
        f = tuple(imu.acc_frd_mps2.tolist())
        e = tuple(frame.euler_rad.tolist()) if frame.euler_rad is not None else None
        nan = math.nan
        hud = frame.hud
        # the airspeed: the air-data family's (the fusion of the pitots its vote keeps, or its
        # virtual CAS while it keeps none: a better scale than the ground speed in wind), else
        # the median of the pitots (one faulty pitot of three cannot move it; the autopilot's
        # VFR_HUD airspeed is one sensor, or its own fusion of them), else VFR_HUD's, else the
        # ground speed. When the air-data family has no airspeed at all, VFR_HUD's (made from
        # the same pitots) is skipped too: the ground speed.
        shared = self.ctx.shared.get(AIRSPEED_CAS, frame.t_us, self.ctx.stale_after_s)
        doubt = ""
        if shared is not None:
            v, src = shared.value, f"the air-data family's {shared.source} CAS"
            if shared.source == VIRTUAL:
                doubt = "the airspeed is the air-data family's model estimate (no pitot healthy)"
            elif shared.survivor:
                doubt = "the airspeed is the last healthy pitot of its set, unchecked"
        else:
            pitots = [c for c in frame.cas_mps.tolist() if c > 0.0]  # False for NaN
            v, src = (statistics.median(pitots), "the pitots' median") if pitots else (nan, "")
            if v != v and hud is not None and hud.airspeed_mps > 0.0:
                v, src = hud.airspeed_mps, "VFR_HUD"
        if v != v and frame.gps_vel_ned_mps is not None:
            v, src = float(np.linalg.norm(frame.gps_vel_ned_mps)), "the ground speed"
        out = self.cfg.outputs
        u = [nan, nan, nan]
        thr = nan
        servo = frame.servo
        if servo is not None:
            for k, ch in enumerate(out.channels()):
                if ch:
                    pwm = servo.pwm_us[ch - 1]
                    u[k] = (pwm - out.pwm_center_us) / out.pwm_half_range_us * self._max_defl[k]
            if out.throttle_channel:
                pwm = servo.pwm_us[out.throttle_channel - 1]
                thr = min(1.0, max(0.0, (pwm - out.throttle_min_us)
                                   / (out.throttle_max_us - out.throttle_min_us)))
        if thr != thr and hud is not None:
            thr = hud.throttle
        nav = frame.nav
        er = ep = ee = nan
        if nav is not None and e is not None:
            er = _wrap(nav.nav_roll_rad - e[0])
            ep = _wrap(nav.nav_pitch_rad - e[1])
        if nav is not None and math.isfinite(v) and v > 1.0:
            ee = nav.aspd_error_mps + GRAVITY_STD_MPS2 * nav.alt_error_m / v
        return Signals(frame.t_us, omega, f, e, v, (u[0], u[1], u[2]), thr, er, ep, ee,
                       servo.t_us if servo is not None else -1,
                       nav.t_us if nav is not None else -1,
                       hud.t_us if hud is not None else -1, src if v == v else "", doubt)

    def _mode(self, ax: _Axis, s: Signals) -> str:
        src = self.cfg.command_source
        if ax.index == ENGINE:
            if src != SETPOINT and math.isfinite(s.throttle):
                return SERVO
            return SETPOINT if src != SERVO and math.isfinite(s.energy_err_mps) else ""
        if src != SETPOINT and math.isfinite(s.u_rad[ax.index]):
            return SERVO
        if src == SERVO:
            return ""
        if ax.index == 0:
            ok = math.isfinite(s.err_roll_rad)
        elif ax.index == 1:
            ok = math.isfinite(s.err_pitch_rad)
        else:  # the coordinated-turn yaw rate needs attitude and airspeed
            ok = s.euler is not None and math.isfinite(s.airspeed_mps)
        return SETPOINT if ok else ""

    def _command_t(self, ax: _Axis, s: Signals) -> int:
        """Time stamp of the sample the axis's command comes from."""
        if ax.mode == SERVO:
            if ax.index == ENGINE and not self.cfg.outputs.throttle_channel:
                return s.hud_t_us
            return s.servo_t_us
        if ax.index == 2 and s.nav_t_us < 0:  # setpoint yaw needs attitude and airspeed only
            return s.t_us
        return s.nav_t_us

    def _scale(self, s: Signals) -> float:
        v = s.airspeed_mps
        if not math.isfinite(v):
            return 1.0
        if self._v_ref <= 0.0:
            if v < self.cfg.model.min_airspeed_mps:  # on the ground: no reference yet (a real
                return 1.0  # flight's first airspeed may be 0, which cannot scale anything)
            self._v_ref = v  # the first airspeed at which the surfaces can be judged
        r = v / self._v_ref
        return r * r

    def _regression(self, ax: _Axis, s: Signals, prev: Signals) -> tuple[float, list[float]]:
        """(y, phi) of the axis; phi[0] is the command (module docstring).

        The command and the other terms are the previous sample's: the response at k follows
        the command issued before it, while the command at k already reacts to the response
        at k through the autopilot's feedback (which would bias its effect to zero), and the
        current states are partly the command's own effect (f_z follows the elevator, f_y the
        rudder) and would absorb it.
        """
        sq = self._scale(prev)
        i = ax.index
        w, wp, fp = s.omega, prev.omega, prev.f
        if i == ENGINE:
            if ax.mode == SERVO:
                cmd = prev.throttle
            else:  # the throttle saturates as the energy error grows
                e_max = self.cfg.model.max_energy_error_mps
                cmd = max(-e_max, min(e_max, prev.energy_err_mps))
            if ax.mode == SERVO:
                cmd = self._throttle_lag(ax, cmd, s.t_us - prev.t_us)
            return s.f[0], [cmd, sq, fp[2], 1.0]
        lim = self.cfg.model.max_setpoint_error_rad
        if ax.mode == SERVO:
            cmd = prev.u_rad[i] * sq
        elif i == 0:  # the autopilot's rate demand saturates: so does the error's effect
            cmd = max(-lim, min(lim, prev.err_roll_rad))
        elif i == 1:
            cmd = max(-lim, min(lim, prev.err_pitch_rad))
        else:
            e = prev.euler
            assert e is not None
            cmd = GRAVITY_STD_MPS2 * math.sin(e[0]) * math.cos(e[1]) / max(prev.airspeed_mps,
                                                                          1.0)
        if i == 0:  # no f_y: the aileron's own side force is in it (Cy_da)
            return w[0], [cmd, wp[0], wp[2], 1.0]
        if i == 1:
            return w[1], [cmd, wp[1], fp[2], 1.0]
        return w[2], [cmd, wp[2], fp[1], wp[0], 1.0]

    def _throttle_lag(self, ax: _Axis, thr: float, dt_us: int) -> float:
        """Advance the throttle through every candidate lag; the selected one's value.

        An engine's thrust follows its throttle with a lag (a turbofan spools up in seconds, a
        propeller in a tenth): a model on the throttle alone reads a fast throttle increase as
        a thrust deficit until the engine catches up (a shear, where the autopilot throttles
        up hard). Each candidate lag (``ENGINE_LAG_SHARES`` of ``engine_lag_max_s``) has its
        own reference model; the one whose healthy residual is smallest judges (:meth:`_learn`):
        the data pick the lag. One lagged throttle per model, not several in one model: in
        cruise they are all equal, and a model fed with them all splits their weights
        arbitrarily and mispredicts the first throttle transient."""
        taus = self._lags
        if len(ax.thr_lag) != len(taus):
            ax.thr_lag = [thr] * len(taus)  # start in steady state
        else:
            dt = dt_us / US_PER_S
            for j, tau in enumerate(taus):
                a = math.exp(-dt / tau) if tau > 0.0 else 0.0
                ax.thr_lag[j] = a * ax.thr_lag[j] + (1.0 - a) * thr
        return ax.thr_lag[ax.lag_k]

    def _learn_lags(self, ax: _Axis, y: float, phi: list[float], dt: float, lam: float,
                    w: float) -> None:
        """The other lags' engine models learn the same sample (healthy flight only); the
        best replaces the selected one when it is clearly better (``LAG_SWITCH_RATIO``)."""
        m = self.cfg.model
        sel = ax.lag_models[ax.lag_k]
        sel.sigma2, sel.sigma_n = ax.sigma2, ax.sigma_n
        best = sel
        for k, lm in enumerate(ax.lag_models):
            if k == ax.lag_k:
                continue
            phi_k = np.array((ax.thr_lag[k], *phi[1:]))
            up = lm.rls.update(phi_k, y, lam, trace_max=m.covariance_trace_max, weight=w)
            if ax.sigma_n:  # the same samples as the selected model's variance
                lm.sigma2, lm.sigma_n = _sigma_step(lm.sigma2, lm.sigma_n, up.error, dt,
                                                    m.sigma_memory_s, m.huber_c)
            if (lm.sigma_n >= LAG_MIN_SAMPLES and lm.sigma2 < LAG_SWITCH_RATIO * sel.sigma2
                    and (best is sel or lm.sigma2 < best.sigma2)):
                best = lm
        if best is not sel:
            ax.lag_k = ax.lag_models.index(best)
            ax.ref = best.rls
            ax.sigma2, ax.sigma_n = best.sigma2, best.sigma_n

    # -- the three phases -----------------------------------------------------------------------
    def predict(self, frame: Frame) -> Signals | None:
        """The Frame's signals, or None when no command stream has a new sample (most Frames:
        commands come at 10-50 Hz, Frames at the IMU rate)."""
        servo, nav, hud = frame.servo, frame.nav, frame.hud
        key = (servo.t_us if servo is not None else -1, nav.t_us if nav is not None else -1,
               hud.t_us if hud is not None else -1)
        if key != self._cmd_key:
            self._cmd_key = key
            self._pending = True
        elif not self._pending and (servo is not None or nav is not None):
            return None  # every axis has stepped on the latest commands
        return self._signals(frame)

    def judge(self, frame: Frame, s: Signals | None) -> Verdict:
        t = frame.t_us
        if frame.mav_type not in FIXED_WING_TYPES:  # a copter's outputs drive motors
            return Verdict(FamilyStatus(
                self.name, t, False, sample=False, inputs=False,
                reason=f"not an aeroplane (MAV_TYPE {frame.mav_type}): the aircraft tier models "
                       "control surfaces and a propulsion engine"))
        if s is None:
            return Verdict(FamilyStatus(self.name, t, False, sample=False,
                                        reason="no new control sample",
                                        inputs=self._seen_inputs))
        stepped: list[tuple[_Axis, float, list[float], np.ndarray, float]] = []
        reasons: list[str] = []
        if s.airspeed_src and s.airspeed_src != self._v_src:
            self._airspeed_source(s)
        for ax in self.axes:
            step = self._step_axis(ax, s, reasons)
            if step is not None:
                stepped.append(step)
        if not self._seen_inputs and any(ax.mode for ax in self.axes):
            self._seen_inputs = True
        statuses: list[ChannelStatus] | None = [] if self.ctx.statuses else None
        events = self._decide(t, stepped, statuses)
        freeze = any(ax.suspected(self.cfg.model.freeze_ratio) for ax in self.axes)
        for ax, y, phi, phi_v, sq in stepped:
            self._learn(ax, y, phi, phi_v, sq, freeze)
        self._pending = any(ax.mode and self._command_t(ax, s) > ax.cmd_t_us
                            for ax in self.axes)
        judged = any(ax.judged for ax, *_ in stepped)
        reason = "" if judged else ("; ".join(dict.fromkeys(reasons)) if reasons
                                    else "no new control sample")
        status = FamilyStatus(self.name, t, judged, sample=bool(stepped), reason=reason,
                              inputs=self._seen_inputs)
        if stepped and (self._estimate is None or t - self._estimate.t_us >= ESTIMATE_PERIOD_US
                        or events):
            self._estimate = self._estimates(t, frame)
        return Verdict(status, events=events, channels=statuses or [])

    def update(self, frame: Frame, verdict: Verdict) -> list[Estimate]:
        return [self._estimate] if self._estimate is not None else []

    def _airspeed_source(self, s: Signals) -> None:
        """The airspeed now comes from another source (the air-data family lost its CAS set
        and shares its virtual CAS, or nothing and the ground speed stands in): the models'
        dynamic-pressure scale ``(V / V_ref)^2`` was learnt on the old one and jumps with the
        difference (a wind of 10 m/s is 25 % of the scale at 80 m/s). A change of the scale is
        no fault of an actuator: the models restart on the new source, with their warm-up
        (coverage says why), and ``V_ref`` is taken afresh. The first source is no change."""
        old, self._v_src = self._v_src, s.airspeed_src
        if not old:
            return
        self._restart_why = f"airspeed from {s.airspeed_src}, was {old}: the models restart"
        self._restart_us = s.t_us
        self._v_ref = self.cfg.model.airspeed_ref_mps
        for ax in self.axes:
            if ax.mode:
                ax.reset(ax.mode, s.t_us)

    # -- per axis ----------------------------------------------------------------------------
    def _step_axis(self, ax: _Axis, s: Signals, reasons: list[str]
                   ) -> tuple[_Axis, float, list[float], np.ndarray, float] | None:
        """Advance one axis by a new control sample; (axis, y, phi, phi as an array, scale)
        when it stepped."""
        ax.judged = False
        mode = self._mode(ax, s)
        if not mode:  # a command stream gone quiet (or stale) keeps the models it had
            reasons.append(f"{ax.channel.axis}: no command (servo output or setpoint)")
            return None
        if mode != ax.mode:  # another kind of command: other regressors, a new model
            ax.reset(mode, s.t_us)
        cmd_t = self._command_t(ax, s)
        response = s.omega + s.f
        if cmd_t <= ax.cmd_t_us or response == ax.response:
            return None  # no new command, or the response repeats (a logger's forward fill)
        ax.cmd_t_us, ax.response = cmd_t, response
        prev = ax.prev
        ax.prev = s
        if prev is None or s.t_us - prev.t_us > self.cfg.model.max_step_s * US_PER_S:
            ax.period.gap()
            ax.period.add(s.t_us)
            if ax.thr_lag and ax.lag_models:
                # the engine lags restart too, at the throttle after the gap; what the
                # throttle did in the gap is unknown, and the engine still follows it for a
                # few of its time constants: not judged, not learnt, until that has passed
                tau = ax.lag_models[ax.lag_k].tau_s
                ax.settle_us = s.t_us + round(LAG_SETTLE * tau * US_PER_S)
            ax.thr_lag = []
            return None
        ax.period.add(s.t_us)
        ax.steps += 1
        if ax.steps <= PERIOD_REFRESH or ax.steps % PERIOD_REFRESH == 0:
            # a median of 16 intervals: every step while it settles, then now and then
            ax.period_s = ax.period.seconds()
        y, phi = self._regression(ax, s, prev)
        if not (math.isfinite(y) and all(map(math.isfinite, phi))):
            reasons.append(f"{ax.channel.axis}: inputs not finite")
            return None
        if s.t_us < ax.settle_us:
            reasons.append(f"{ax.channel.axis}: the engine settles after a telemetry gap")
            return None
        m = self.cfg.model
        if ax.ref is None:
            ax.ref = RlsFilter(len(phi), m.initial_covariance)
            ax.trk = RlsFilter(2, m.initial_covariance)
            if ax.index == ENGINE and ax.mode == SERVO:
                ax.lag_models = [_LagModel(tau, ax.ref if k == ax.lag_k else
                                           RlsFilter(len(phi), m.initial_covariance))
                                 for k, tau in enumerate(self._lags)]
        phi_v = np.array(phi)
        e = y - ax.ref.predict(phi_v)
        ax.e_ref = e
        if ax.index == ENGINE and ax.mode == SERVO:
            # an engine can lose at most the thrust it was making: with the throttle known, the
            # part of a deficit an engine fault can explain is bounded by the model's thrust at
            # that throttle, b thr (none at idle, none while b is not identified as positive).
            # A larger deficit (drag and lift in wind shear with the throttle at idle) is no
            # evidence against the engine. The models learn the unbounded error (_learn).
            e = max(e, -max(float(ax.ref.theta[0]) * phi[0], 0.0))
        floor = m.min_accel_sigma_mps2 if ax.index == ENGINE else m.min_rate_sigma_radps
        sigma = math.sqrt(max(ax.sigma2, floor * floor)) if ax.sigma2 == ax.sigma2 else math.inf
        # the a priori prediction error's spread includes the model's own parameter
        # uncertainty along this regressor: var(e) = sigma^2 (1 + phi^T P phi) (Ljung and
        # Soderstrom 1983, sec. 2.6; P is the parameter covariance over sigma^2). A command
        # the model has not seen (a rudder first used in an S-turn after 40 s at zero) is
        # not a fault of the surface: the model cannot predict it yet.
        nu = e / (sigma * math.sqrt(1.0 + float(phi_v @ ax.ref.P @ phi_v)))
        ax.nu = nu
        sq = self._scale(prev)
        ax.hist.append((s.t_us, phi[0], e, sq))
        horizon = s.t_us - self._history_us
        while ax.hist and ax.hist[0][0] < horizon:
            ax.hist.popleft()
        why = self._not_judged(ax, s)
        if not why:
            if ax.res is None:  # sized with the step period measured at the warm-up's end
                self._build_fdi(ax)
            why = self._unidentified(ax)
        if why:
            reasons.append(f"{ax.channel.axis}: {why}")
        else:
            ax.judged = True
            assert ax.res is not None and ax.eff is not None
            scale = self._convergence(ax, s.t_us)
            ax.res.update(nu / scale)
            # the effectiveness check needs a command of the actuator's own: not the engine
            # (a thrust deficit is the residual's), not the yaw axis on setpoints
            own = ax.index != ENGINE and (ax.mode == SERVO or ax.index != 2)
            ax.z = self._loss_z(ax) if own else 0.0
            # a command held at its end stop (the autopilot has run out of this surface) does
            # not vary and tells nothing of the effectiveness (the tracking slope has no
            # excitation): the check holds its state until the command leaves the stop
            if not (own and self._at_stop(ax, prev)):
                ax.eff.update(max(ax.z, 0.0) / scale)
        ax.command_rad = prev.u_rad[ax.index] if ax.index != ENGINE and ax.mode == SERVO \
            else math.nan
        return ax, y, phi, phi_v, sq

    def _at_stop(self, ax: _Axis, prev: Signals) -> bool:
        """The surface's servo-output command (the one acting) is at its end stop (NaN: no)."""
        return ax.mode == SERVO and abs(prev.u_rad[ax.index]) >= \
            STOP_SHARE * self._max_defl[ax.index]

    def _not_judged(self, ax: _Axis, s: Signals) -> str:
        m = self.cfg.model
        if s.t_us - ax.t_start_us < m.warmup_s * US_PER_S or ax.sigma2 != ax.sigma2:
            return (f"warm-up ({self._restart_why})" if ax.t_start_us == self._restart_us
                    else "warm-up")
        period = ax.period_s
        if math.isfinite(period) and 1.0 / period < self.cfg.min_rate_hz:
            return (f"control samples at {1.0 / period:.1f} Hz, below the "
                    f"{self.cfg.min_rate_hz:g} Hz the aircraft tier needs")
        v = s.airspeed_mps
        if math.isfinite(v) and v < m.min_airspeed_mps:
            return f"airspeed {v:.1f} m/s below {m.min_airspeed_mps:g} m/s"
        if ax.index == ENGINE and s.airspeed_doubt and not ax.suspected(m.freeze_ratio):
            # the engine's model tells thrust from drag by the airspeed (its a s term): an
            # airspeed that drifts moves the drag it predicts, and reads as thrust lost
            # (Wan2018 campaign: run 153, the last pitot running away before the air-data
            # family isolated it; run 241, the virtual CAS after the set was lost in a
            # shear: the wind states lose the measurement that makes them observable). The
            # ground speed, where no airspeed is sent at all (ALFA), does not drift: a steady
            # wind is in the model's terms from its start. The surfaces take the airspeed as a
            # scale only and are judged. A check that already suspects the engine keeps
            # judging (the loss came first).
            return f"{s.airspeed_doubt}: thrust is not told from drag on it"
        return ""

    def _unidentified(self, ax: _Axis) -> str:
        """Why a surface's command effect is not identified yet (empty once it is)."""
        m = self.cfg.model
        if not ax.identified and ax.index != ENGINE and m.identified_se > 0.0:
            # a surface whose command has not moved enough since its model started (a rudder
            # held at neutral by a coordinated autopilot) has an unidentified effect b: the
            # model cannot predict its first use, which is not a fault (the triplex
            # campaign's run 90: "rudder stuck" 1 s into an S-turn). Latched: once identified,
            # a later loss of effectiveness is what the checks are for. Not the engine: its
            # throttle may hold for a whole cruise, and a thrust deficit needs no slope.
            assert ax.ref is not None
            se = math.sqrt(max(ax.sigma2, m.min_rate_sigma_radps ** 2) * float(ax.ref.P[0, 0]))
            if abs(float(ax.ref.theta[0])) <= m.identified_se * se:
                return "the command's effect not identified yet (the surface has not moved enough)"
            ax.identified = True
        return ""

    def _convergence(self, ax: _Axis, t_us: int) -> float:
        """How much the checks' values are divided by while the reference model converges:
        ``convergence_factor`` at the end of the warm-up, 1 after ``convergence_s`` more
        (a model that has not yet seen every manoeuvre is judged with a wider margin)."""
        m = self.cfg.model
        since = (t_us - ax.t_start_us) / US_PER_S - m.warmup_s
        if since >= m.convergence_s:
            return 1.0
        return 1.0 + (m.convergence_factor - 1.0) * (1.0 - max(since, 0.0) / m.convergence_s)

    def _build_fdi(self, ax: _Axis) -> None:
        """The two checks, sized with the axis's measured step period, and its alarm."""
        period = ax.period_s
        if not math.isfinite(period):
            period = 0.1
        ax.res = _Check(ax.res_cfg, period, one_sided=ax.one_sided)
        ax.eff = _Check(ax.eff_cfg, period)
        if ax.alarm is None:
            ax.alarm = AlarmStateMachine(ax.channel, AlarmKind.ACTUATOR_FAULT, ESTIMATOR,
                                         params=self.ctx.alarm, vehicle=self.ctx.vehicle)

    @staticmethod
    def _loss_z(ax: _Axis) -> float:
        """The effectiveness lost, in standard errors: the tracking regression's slope of the
        reference residual on the command is ``b (kappa - 1)``; ``-slope sign(b_ref) /
        (sigma sqrt(P_00))`` with ``sigma`` the healthy residual RMS (0 before it exists; large
        ``P_00``, i.e. a command without excitation, gives no evidence)."""
        ref, trk = ax.ref, ax.trk
        if ref is None or trk is None or not ax.sigma2 > 0.0:
            return 0.0
        # the slope's residual variance: the tracking regression's own (what the command does
        # not explain now: large in a manoeuvre the reference never saw, small when a stuck or
        # weakened surface explains the residual), not below a quarter of the healthy level
        var = max(ax.trk_sigma2, 0.25 * ax.sigma2) if ax.trk_sigma2 == ax.trk_sigma2 \
            else ax.sigma2
        se = math.sqrt(var * float(trk.P[0, 0]))
        if not se > 0.0:
            return 0.0
        return -float(trk.theta[0]) * (1.0 if ref.theta[0] >= 0.0 else -1.0) / se

    def _learn(self, ax: _Axis, y: float, phi: list[float], phi_v: np.ndarray, sq: float,
               freeze: bool) -> None:
        """Tracking model always; reference model and residual RMS only in healthy flight
        (``phi_v``: ``phi`` as an array)."""
        assert ax.ref is not None and ax.trk is not None and ax.prev is not None
        m = self.cfg.model
        period = ax.period_s
        dt = period if math.isfinite(period) else 0.1
        tr = m.covariance_trace_max
        # tracking regression of the reference residual on the command: e = b (kappa - 1) x + c
        # (unweighted: it is there to follow a change, large residuals included)
        a_trk = math.exp(-dt / m.tracking_memory_s)
        up_trk = ax.trk.update(np.array((phi[0], 1.0)), ax.e_ref, a_trk, trace_max=tr)
        e2 = up_trk.error * up_trk.error
        if math.isfinite(e2):
            ax.trk_sigma2 = e2 if ax.trk_sigma2 != ax.trk_sigma2 else \
                a_trk * ax.trk_sigma2 + (1.0 - a_trk) * e2
        # Huber weights in the reference model: one glitch (a setpoint that jumps for a
        # sample) must not move what healthy flight looks like
        nu = abs(ax.e_ref) / math.sqrt(ax.sigma2) if ax.sigma2 > 0.0 else 0.0
        w = huber_weight(nu, m.huber_c)
        if not freeze:
            lam = math.exp(-dt / m.reference_memory_s)
            up = ax.ref.update(phi_v, y, lam, trace_max=tr, weight=w)
            # the residual RMS over healthy flight, from half-way through the warm-up (the
            # reference model's start-up errors are not its healthy level)
            assert ax.prev is not None
            if ax.prev.t_us - ax.t_start_us >= 0.5 * m.warmup_s * US_PER_S:
                ax.sigma2, ax.sigma_n = _sigma_step(ax.sigma2, ax.sigma_n, up.error, dt,
                                                    m.sigma_memory_s, m.huber_c)
            if len(ax.lag_models) > 1:
                self._learn_lags(ax, y, phi, dt, lam, w)

        b_ref = float(ax.ref.theta[0])
        ax.effectiveness = 1.0 + float(ax.trk.theta[0]) / b_ref if abs(b_ref) > 1e-9 \
            else math.nan
        if ax.index != ENGINE:
            if ax.mode == SERVO and abs(b_ref) > 1e-9 and sq > 0.0:
                e = y - ax.ref.predict(phi_v)
                ax.position_rad = (phi[0] + e / b_ref) / sq
            else:
                ax.position_rad = math.nan

    # -- decisions ---------------------------------------------------------------------------
    def _decide(self, t_us: int,
                stepped: list[tuple[_Axis, float, list[float], np.ndarray, float]],
                statuses: list[ChannelStatus] | None) -> list[AlarmEvent]:
        """Isolation among the confirmed axes, alarm transitions, channel statuses."""
        fdi = self.cfg.fdi
        iso = fdi.isolation_ratio
        ratios = {ax.index: ax.ratio for ax in self.axes if ax.judged and ax.faulty}
        top = max(ratios.values(), default=0.0)
        # a second actuator alarm must dominate the active one: a fault disturbs the other
        # axes' models too (cross-coupling), later than its own
        active = max((ax.ratio for ax in self.axes if ax.alarm is not None and ax.alarm.active),
                     default=0.0)
        events: list[AlarmEvent] = []
        for ax in self.axes:
            if statuses is not None and ax.judged:
                assert ax.res is not None and ax.eff is not None
                statuses.append(ChannelStatus(ax.channel, t_us, ax.nu, ax.res.J,
                                              ax.res.cfg.threshold, ax.res.faulty, ESTIMATOR))
                statuses.append(ChannelStatus(EFF_CHANNELS[ax.index], t_us, ax.z, ax.eff.J,
                                              ax.eff.cfg.threshold, ax.eff.faulty, ESTIMATOR))
            sm = ax.alarm
            if sm is None or not ax.judged:
                continue
            r = ratios.get(ax.index, 0.0)
            raise_it = ax.faulty and (sm.active or (r >= iso * top
                                                    and r >= fdi.second_fault_ratio * active))
            if raise_it and not sm.active and ax.index == ENGINE and not self._engine_lost(ax):
                # the residual check saw deficits (the RMS of the one-sided residual), but the
                # classifier's history holds no loss the model can resolve: a transient (the
                # throttle moving faster than the lag models, a flight regime the model has
                # not learnt), not a lost engine; an alarm would name a loss of a few % or less
                raise_it = False
            if raise_it:
                if sm.active and t_us < ax.next_class_us:
                    continue
                ax.next_class_us = t_us + round(self.cfg.fdi.classify.reclassify_s * US_PER_S)
                ft, mag, msg, conf = self._classify(ax)
                events += sm.step(t_us, True, fault_type=ft, magnitude=mag, rms=ax.J,
                                  threshold=ax.threshold, message=msg, confidence=conf)
            elif sm.active:
                events += sm.step(t_us, False, rms=ax.J, threshold=ax.threshold,
                                  message=f"{ax.channel.axis}: response matches the model again")
        return events

    def _classify(self, ax: _Axis) -> tuple[FaultType, float, str, float]:
        """Fault class, magnitude, message and confidence (module docstring). The confidence
        is how far ``kappa`` sits inside its class's band, as a share of the band's half-width
        (1 at or beyond it); 0 for unknown."""
        c = self.cfg.fdi.classify
        ft, mag, msg = self._class_of(ax)
        kappa, lo = ax.effectiveness, c.stuck_gain
        hi = 1.0 - 0.5 * lo
        conf = 0.0
        if ax.index == ENGINE and ft is FaultType.LOSS_OF_EFFECTIVENESS:
            conf = min(1.0, mag / 0.5) if math.isfinite(mag) else 0.5
        elif ft is FaultType.STUCK and math.isfinite(kappa):
            conf = min(1.0, max(0.0, (lo - kappa) / lo))
        elif ft is FaultType.LOSS_OF_EFFECTIVENESS and math.isfinite(kappa):
            conf = min(1.0, max(0.0, min(kappa - lo, hi - kappa) / (0.5 * (hi - lo))))
        return ft, mag, msg, conf

    @staticmethod
    def _engine_balance(ax: _Axis) -> tuple[float, float]:
        """The engine's mean thrust deficit over the classifier's history and the mean thrust
        its reference model gives at the throttle there (m/s^2; NaN without history, the
        thrust NaN without a throttle)."""
        n = len(ax.hist)
        if not n:
            return math.nan, math.nan
        deficit = -sum(e for _, _, e, _ in ax.hist) / n
        if ax.mode != SERVO or ax.ref is None:
            return deficit, math.nan
        return deficit, float(ax.ref.theta[0]) * sum(x for _, x, _, _ in ax.hist) / n

    def _engine_lost(self, ax: _Axis) -> bool:
        """Whether the history shows a loss of thrust the engine model can resolve: a mean
        deficit of at least ``engine_min_loss`` of the modelled thrust (with a throttle), a
        positive one (without)."""
        deficit, thrust = self._engine_balance(ax)
        if thrust != thrust:
            return deficit > 0.0
        return thrust > 1e-9 and deficit >= self.cfg.fdi.classify.engine_min_loss * thrust

    def _class_of(self, ax: _Axis) -> tuple[FaultType, float, str]:
        """Fault class and magnitude from the history (module docstring)."""
        c = self.cfg.fdi.classify
        name = ax.channel.axis
        assert ax.ref is not None
        b = float(ax.ref.theta[0])
        h = np.array([(x, e, sq) for _, x, e, sq in ax.hist])
        src = "servo outputs" if ax.mode == SERVO else "setpoints"
        if len(h) < 4 or abs(b) < 1e-9:
            return FaultType.UNKNOWN, math.nan, f"{name}: response off its model ({src})"
        x, e, sq = h[:, 0], h[:, 1], h[:, 2]
        if ax.index == ENGINE:
            deficit, thrust = self._engine_balance(ax)
            if ax.mode == SERVO:
                loss = min(1.0, max(0.0, deficit / thrust)) if thrust > 1e-9 else math.nan
                what = "engine out" if loss >= 0.8 else f"{100 * loss:.0f} % of thrust lost"
                return (FaultType.LOSS_OF_EFFECTIVENESS, loss,
                        f"engine: {what} (thrust deficit {deficit:.2f} m/s^2 of the "
                        f"{thrust:.2f} m/s^2 its model gives at this throttle)")
            return (FaultType.LOSS_OF_EFFECTIVENESS, math.nan,
                    f"engine: thrust deficit {deficit:.2f} m/s^2 against the energy the "
                    f"autopilot asks for (no throttle: loss not quantified)")
        # the share of the command that still acts: the tracking model's effectiveness over
        # the reference's (the tracking model has refitted every term on recent flight)
        kappa = ax.effectiveness
        if not math.isfinite(kappa):
            return FaultType.UNKNOWN, math.nan, f"{name}: response off its model ({src})"
        if kappa < c.stuck_gain:
            if ax.mode != SERVO:
                return (FaultType.STUCK, math.nan,
                        f"{name}: stuck or without effect ({_share(kappa)} of the command "
                        "acts; position unobservable without servo outputs)")
            # the surface position that explains the response, averaged over the history
            pos = float(np.mean((x + e / b) / sq))
            if not abs(pos) <= 2.0 * self._max_defl[ax.index]:  # no stuck surface sits there
                return (FaultType.STUCK, math.nan,
                        f"{name}: stuck or without effect ({_share(kappa)} of the command "
                        "acts)")
            zero = abs(pos) < c.zero_position_ratio * self._max_defl[ax.index]
            # reported in steps of a tenth of a degree (and 0 at zero): the alarm is updated
            # when the position moves, not when its estimate wobbles
            pos = 0.0 if zero else round(pos * RAD2DEG, 1) / RAD2DEG
            where = "zero" if zero else f"{pos * RAD2DEG:.1f} deg"
            return FaultType.STUCK, pos, f"{name}: stuck at {where} ({_share(kappa)} of the " \
                f"command acts)"
        if kappa < 1.0 - 0.5 * c.stuck_gain:
            loss = round(1.0 - kappa, 2)
            return (FaultType.LOSS_OF_EFFECTIVENESS, loss,
                    f"{name}: {100 * loss:.0f} % of its effectiveness lost ({src})")
        return (FaultType.UNKNOWN, math.nan,
                f"{name}: response off its model, not explained by the command ({src})")

    # -- estimates ---------------------------------------------------------------------------
    def _estimates(self, t_us: int, frame: Frame) -> Estimate:
        nan = math.nan
        axes = self.axes
        measured = (tuple(frame.surf_pos_rad.tolist()) if frame.surf_pos_rad is not None
                    else (nan, nan, nan))
        states = {
            "command_rad": np.array([a.command_rad for a in axes[:3]]),
            "estimated_position_rad": np.array([a.position_rad for a in axes[:3]]),
            "measured_position_rad": np.array(measured),
            "effectiveness": np.array([a.effectiveness for a in axes]),
            "normalised_residual": np.array([a.nu for a in axes]),
        }
        virtual = {a.channel: a.position_rad for a in axes[:3] if a.position_rad == a.position_rad}
        return Estimate(ESTIMATOR, t_us, states=states, virtual=virtual,
                        residuals={a.channel: a.nu for a in axes if a.judged})
