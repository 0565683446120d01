"""Fault-tolerant air-data estimation (Wan2018): CMHE, UMHE or EKF on the wind model.

Step 3 of the Wan2018 FTE scheme (Fig. 1): joint state and wind estimation and the
one-step-ahead predictions ``alpha_hat_{k|k-1}``, ``V_c_hat_{k|k-1}`` that the FDI layer turns
into residuals (eq. 17), RMS windows (eq. 18) and the fused measurement (eq. 19).

Calling order per Frame, done by the FDI layer::

    pred = est.predict(frame)                          # (alpha, V_c)_{k|k-1}: eq. 17 reference
    est.set_fused_measurements(aoa_fused, cas_fused)   # eq. 19 with the J of sample k; None = lost
    estimate = est.step(frame)

Without ``set_fused_measurements`` the estimator fuses the valid instances with equal weights
(eq. 19 with equal J), which is what eq. 19 gives before any residual history exists.
The filter steps only on frames with new air data (20 Hz); other frames return an Estimate
without residuals, so residual windows count air-data samples (N_eval = 10, Wan2018 sec. V-C).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import cast

import numpy as np

from gcs_monitor.core.params import param
from gcs_monitor.core.types import ChannelId, Vec
from gcs_monitor.fdi.records import Estimate
from gcs_monitor.filters.airdata_ekf import EkfState, ekf_predict, ekf_update
from gcs_monitor.filters.mhe import (
    IpSettings,
    MheBounds,
    MheState,
    MheWeights,
    mhe_init,
    mhe_predict,
    mhe_step,
)
from gcs_monitor.models.airdata import (
    IT_AX,
    IT_AZ,
    IT_Q,
    IY_AOA,
    IY_CAS,
    N_U,
    N_X,
    AirDataModel,
    AirDataModelParams,
    WindEnvelope,
    airdata_initial_state,
    envelope_bounds,
)
from gcs_monitor.telemetry.frame import Frame

logger = logging.getLogger(__name__)

VARIANTS = ("cmhe", "umhe", "ekf")
VIRTUAL_AOA = ChannelId("aoa_virtual")
VIRTUAL_CAS = ChannelId("cas_virtual")
_IT_RATES = [IT_Q, IT_AX, IT_AZ]  # the entries of Theta averaged over the IMU samples


@dataclass(frozen=True, slots=True)
class AirDataEstimatorConfig:
    """Tuning of the Wan2018 estimator (SI units; squared units for the weights).

    Wan2018 gives N = 3, n_kappa = n_QP = 2 (sec. V-C), p_w = 0.01 and q_w = 0.1 or 1
    (Figs. 3-5) and the rule "R = measurement noise variances"; the other weights and the wind
    bounds are not published, ours are chosen for a transport aircraft (see
    docs/papers-notes.md "Wan2018").

    Wind bounds (eq. 21b) per flight condition: with ``envelope`` set (the declared weather of
    the flight) they are recomputed at every air-data sample from it, the measured V_g, bank
    angle and t_s (:func:`gcs_monitor.models.airdata.envelope_bounds`; Wan2018 sec. III-B:
    "the bounds ... can be time varying"); with ``envelope=None`` the fixed
    ``wind_x_max_mps``, ``wind_z_max_mps``, ``wind_rate_max_mps2`` below hold, and
    :meth:`AirDataEstimator.set_wind_bounds` replaces them.

    q_w: Wan2018 Fig. 4 uses 1; with our R_vc that wind random walk lags shears (fault-free CAS
    residual RMS up to 15 kt in 10 m/s microbursts) and never reaches the wind-rate bound, so the
    CMHE behaves as the UMHE. q_w = 25 lets the wind follow shears; the wind-rate bound then stops
    it absorbing CAS runaways, which is the paper's mechanism (Fig. 4/5 reproduced:
    docs/results.md, `gcs-monitor evaluate --experiment wan2018_fig45`).
    """

    horizon_n: int = param(3, "MHE horizon N (Wan2018 sec. V-C)", positive=True)
    max_dt_s: float = param(0.25, "a larger gap between air-data samples restarts the "
                            "estimator", positive=True)
    max_gps_age_s: float = param(0.5, "older GPS velocity makes the estimate unavailable",
                                 positive=True)
    max_att_age_s: float = param(0.5, "older attitude makes the estimate unavailable",
                                 positive=True)
    p_alpha_rad2: float = param(1.0e-6, "arrival-cost weight P of alpha (eq. 22)",
                                positive=True, unit="si")
    p_v_m2ps2: float = param(1.0e-2, "arrival-cost weight P of V_g (eq. 22)", positive=True)
    p_w_m2ps2: float = param(1.0e-2, "arrival-cost weight P of W_x, W_z (eq. 22; p_w of "
                             "Wan2018 Figs. 3-5)", positive=True)
    q_alpha_rad2ps2: float = param(1.0e-4, "process weight Q of alpha (eq. 22)", positive=True,
                                   unit="si")
    q_v_m2ps4: float = param(0.25, "process weight Q of V_g (eq. 22)", positive=True)
    q_w_m2ps4: float = param(25.0, "process weight Q of the wind rates u_w (eq. 22; Wan2018 "
                             "Fig. 4 uses 1, see the class docstring)", positive=True)
    r_vg_m2ps2: float = param(0.01, "measurement weight R of V_g (added: V_g is measured too)",
                              positive=True)
    r_vz_m2ps2: float = param(0.04, "measurement weight R of V_z (Wan2018 sec. VI-A: noise "
                              "variance)", positive=True)
    r_alpha_rad2: float = param(3.0e-6, "measurement weight R of alpha, (0.1 deg)^2",
                                positive=True, unit="si")
    r_vc_m2ps2: float = param(0.25, "measurement weight R of V_c, (0.5 m/s)^2", positive=True)
    wind_x_max_mps: float = param(20.0, "fixed |W_x| bound (eq. 21b) when no weather "
                                  "envelope is given", positive=True)
    wind_z_max_mps: float = param(8.0, "fixed |W_z| bound (eq. 21b) when no weather envelope "
                                  "is given", positive=True)
    wind_rate_max_mps2: float = param(2.0, "fixed |u_w| bound (eq. 21b) when no weather "
                                      "envelope is given", positive=True)
    envelope: WindEnvelope | None = param(None, "the declared weather ([airdata.weather])",
                                          toml=False)
    wind_accel_in_alpha: bool = param(True, "keep eq. 8's wind-acceleration term in "
                                      "alpha_dot (false = Wan2018 eq. 13 exactly)")
    lateral_terms: bool = param(False, "bank and sideslip in eqs. 12-15 (ours; "
                                "models.airdata.lateral); false = Wan2018's wings-level forms")
    step_aligned_rates: bool = param(True, "q, A_x, A_z of the step k-1 -> k are the IMU "
                                     "averages over (t_{k-1}, t_k] (false: the previous "
                                     "interval's, which lag by one t_s)")
    kappa_init: float = param(1.0e-2, "initial barrier parameter of the interior point "
                              "(Wan2018 Algorithm 2)", positive=True)
    n_s_max: int = param(12, "largest number of interior-point iterations per step",
                         positive=True)


class AirDataEstimator:
    """Wan2018 air-data estimator on telemetry Frames; ``variant`` = "cmhe" | "umhe" | "ekf"."""

    def __init__(self, config: AirDataEstimatorConfig | None = None, variant: str = "cmhe") -> None:
        if variant not in VARIANTS:
            raise ValueError(f"variant must be one of {VARIANTS}, got {variant!r}")
        self.cfg = config or AirDataEstimatorConfig()
        self.variant = variant
        self.name = f"airdata_{variant}"
        self.model = AirDataModel(
            AirDataModelParams(wind_accel_in_alpha=self.cfg.wind_accel_in_alpha)
        )
        c = self.cfg
        self.weights = MheWeights(
            p_diag=np.array([c.p_alpha_rad2, c.p_v_m2ps2, c.p_w_m2ps2, c.p_w_m2ps2]),
            q_diag=np.array([c.q_alpha_rad2ps2, c.q_v_m2ps4, c.q_w_m2ps4, c.q_w_m2ps4]),
            r_diag=np.array([c.r_vg_m2ps2, c.r_vz_m2ps2, c.r_alpha_rad2, c.r_vc_m2ps2]),
        )
        self.ip = IpSettings(
            kappa_init=c.kappa_init, n_s_max=c.n_s_max, constrained=(variant == "cmhe")
        )
        self.envelope = self.cfg.envelope
        self._ids: dict[tuple[str, int], ChannelId] = {}
        self.bounds = MheBounds.unbounded(N_X, N_U)
        self.set_wind_bounds(c.wind_x_max_mps, c.wind_z_max_mps, c.wind_rate_max_mps2)
        self.reset()

    # ------------------------------------------------------------------ public API
    def set_wind_bounds(
        self,
        wind_x_max_mps: float,
        wind_z_max_mps: float,
        wind_rate_max_mps2: float,
        *,
        wind_rate_z_max_mps2: float | None = None,
    ) -> None:
        """Symmetric bounds on W_x, W_z and on u_wx, u_wz (Wan2018 eq. 21b), per flight
        condition; ``wind_rate_z_max_mps2`` defaults to ``wind_rate_max_mps2``."""
        inf = math.inf
        rz = wind_rate_max_mps2 if wind_rate_z_max_mps2 is None else wind_rate_z_max_mps2
        self.bounds = MheBounds(
            x_lb=np.array([-inf, -inf, -wind_x_max_mps, -wind_z_max_mps]),
            x_ub=np.array([inf, inf, wind_x_max_mps, wind_z_max_mps]),
            u_lb=np.array([-inf, -inf, -wind_rate_max_mps2, -rz]),
            u_ub=np.array([inf, inf, wind_rate_max_mps2, rz]),
        )

    def _schedule_bounds(self, theta_p: Vec, dt_s: float, roll_rad: float) -> None:
        """Bounds of the current flight condition from the declared envelope (if any)."""
        env = self.envelope
        if env is None:
            return
        b = envelope_bounds(env, float(theta_p[0]), dt_s, roll_rad, self.model.params.g_mps2)
        self.set_wind_bounds(b.wind_x_max_mps, b.wind_z_max_mps, b.rate_x_max_mps2,
                             wind_rate_z_max_mps2=b.rate_z_max_mps2)

    def set_envelope(self, envelope: WindEnvelope | None) -> None:
        """The weather whose bounds (eq. 21b) hold from the next sample on (an estimate of the
        flight's weather replaces the declared one); None keeps the fixed bounds."""
        self.envelope = envelope

    def set_fused_measurements(self, aoa_rad: float | None, cas_mps: float | None) -> None:
        """Fused AoA / CAS of Wan2018 eq. 19 for the next :meth:`step`.

        ``None`` means every instance of that set is isolated as faulty: the corresponding row
        of C is zeroed (output configurations II-IV, Wan2018 Table I and sec. V-C).
        """
        self._fused: tuple[float | None, float | None] | None = (aoa_rad, cas_mps)

    def reset(self) -> None:
        self._mhe: MheState | None = None
        self._ekf: EkfState | None = None
        self._theta_prev: Vec | None = None
        self._t_prev_us: int | None = None
        self._fused = None
        # A_x, A_z, q summed since the last air-data step (Python floats: one IMU sample per
        # Frame, where numpy's per-call overhead exceeds the three additions)
        self._sum_ax = self._sum_az = self._sum_q = 0.0
        self._acc_n = 0
        self._prepared: _Prepared | None = None
        self._last_states: dict[str, Vec] = {}
        self._last_virtual: dict[ChannelId, float] = {}

    @property
    def x_hat(self) -> Vec | None:
        """x_hat_{k|k} = [alpha, V_g, W_x, W_z] after the last air-data step."""
        if self._mhe is not None:
            return cast(Vec, self._mhe.x[self._mhe.n - 1].copy())
        if self._ekf is not None:
            return self._ekf.x.copy()
        return None

    def predict(self, frame: Frame) -> tuple[float, float] | None:
        """One-step-ahead AoA and CAS ``(alpha_hat_{k|k-1}, V_c_hat_{k|k-1})`` for the air-data
        sample of ``frame`` (eq. 29 through eq. 16), or None when there is none (no new air
        data, start-up, gap, missing Theta). Every frame's IMU sample enters Theta's averages,
        so a caller that steps only on air-data frames calls this on the others.

        The prediction uses x_hat_{k-1|k-1} and Theta only, never y_k, so the FDI layer can
        take the residuals of eq. 17 against it and form the eq. 19 fusion before
        :meth:`step` of the same frame uses that fusion. Call it before :meth:`step`; the
        work is shared (IMU samples are counted once per frame).
        """
        p = self._prepare(frame)
        if p is None or p.y_pred is None:
            return None
        return float(p.y_pred[IY_AOA]), float(p.y_pred[IY_CAS])

    def step(self, frame: Frame) -> Estimate:
        p = self._prepare(frame)
        self._prepared = None
        if p is None:
            return Estimate(
                name=self.name,
                t_us=frame.t_us,
                reason="no new air data",
                states=self._last_states,
                virtual=self._last_virtual,
            )
        fused = self._fused
        self._fused = None
        theta_p = p.theta_p
        if theta_p is None:
            return Estimate.unavailable(self.name, frame.t_us, p.reason)
        y, mask = self._measurements(frame, theta_p, fused)
        if p.y_pred is None:  # start-up or gap
            self._start(frame.t_us, theta_p, y, mask)
            return Estimate(name=self.name, t_us=frame.t_us, reason=p.reason)
        dt_s, y_pred = p.dt_s, p.y_pred
        residuals: dict[ChannelId, float] = {}
        aoa_pred, cas_pred = float(y_pred[IY_AOA]), float(y_pred[IY_CAS])
        for i, v in enumerate(floats(frame.aoa_rad)):
            if math.isfinite(v):
                residuals[self._channel("aoa", i)] = v - aoa_pred  # eq. 17
        for i, v in enumerate(floats(frame.cas_mps)):
            if math.isfinite(v):
                residuals[self._channel("cas", i)] = v - cas_pred  # eq. 17

        ok = True
        if self._mhe is not None:
            self._mhe, info = mhe_step(
                self._mhe, self.model, y, mask, theta_p, dt_s, self.weights, self.bounds, self.ip,
                x_node=p.x_pred,
            )
            ok = info.numerics_ok
            x_hat = self._mhe.x[self._mhe.n - 1]
        else:
            assert self._ekf is not None and self._theta_prev is not None  # y_pred needs it
            pred = ekf_predict(self._ekf, self.model, self._theta_prev, dt_s, self.weights.q_diag)
            upd = ekf_update(pred, self.model, y, mask, theta_p, self.weights.r_diag)
            self._ekf = upd.state
            ok = upd.numerics_ok
            x_hat = self._ekf.x
        if not ok or not all(math.isfinite(v) for v in x_hat.tolist()):
            logger.warning("%s: numerical failure at t_us=%d, reset", self.name, frame.t_us)
            self.reset()
            return Estimate(
                name=self.name,
                t_us=frame.t_us,
                residuals=residuals,
                numerics_ok=False,
                reason="numerical failure, reset",
            )
        self._theta_prev = theta_p
        self._t_prev_us = frame.t_us
        y_hat = self.model.h(x_hat, theta_p)
        self._last_states = {
            "aoa_pred_rad": np.array([y_pred[IY_AOA]]),
            "cas_pred_mps": np.array([y_pred[IY_CAS]]),
            "x_hat": x_hat.copy(),  # [alpha rad, V_g m/s, W_x m/s, W_z m/s down]
            "wind_xz_mps": x_hat[2:4].copy(),
            "aoa_rad": np.array([y_hat[IY_AOA]]),
            "cas_mps": np.array([y_hat[IY_CAS]]),
            "output_mask": mask.copy(),
        }
        self._last_virtual = {VIRTUAL_AOA: float(y_hat[IY_AOA]), VIRTUAL_CAS: float(y_hat[IY_CAS])}
        return Estimate(
            name=self.name,
            t_us=frame.t_us,
            states=self._last_states,
            residuals=residuals,
            virtual=self._last_virtual,
            numerics_ok=True,
        )

    # ------------------------------------------------------------------ internals
    def _channel(self, kind: str, instance: int) -> ChannelId:
        """``ChannelId(kind, instance)``, built once (frozen: one object serves every
        Estimate)."""
        c = self._ids.get((kind, instance))
        if c is None:
            c = self._ids[(kind, instance)] = ChannelId(kind, instance)
        return c

    def _prepare(self, frame: Frame) -> _Prepared | None:
        """Everything of an air-data step that does not need y_k: Theta_k, t_s, the bounds
        of the flight condition and x_hat_{k|k-1}. Once per frame (cached for :meth:`step`);
        None on frames without new air data."""
        if self._prepared is not None and self._prepared.frame is frame:
            return self._prepared
        imu = frame.primary_imu
        if imu is not None and imu.t_us == frame.t_us:
            # Anti-aliasing: Theta's A_x, A_z, q are averaged over the IMU samples of the interval.
            acc = imu.acc_frd_mps2
            self._sum_ax += float(acc[0])
            self._sum_az += float(acc[2])
            self._sum_q += float(imu.omega_frd_radps[1])
            self._acc_n += 1
        if not frame.air_new:
            self._prepared = None
            return None
        theta_p, why = self._theta(frame)
        self._sum_ax = self._sum_az = self._sum_q = 0.0
        self._acc_n = 0
        p = _Prepared(frame=frame, theta_p=theta_p, reason=why)
        self._prepared = p
        if theta_p is None:
            return p
        roll = float(frame.euler_rad[0]) if frame.euler_rad is not None else 0.0
        if self._t_prev_us is None or self._theta_prev is None:
            # the first node's bounds need t_s: the stream's measured period
            if self.envelope is not None and not math.isfinite(frame.air_period_s):
                p.theta_p, p.reason = None, "air-data sample period not measured yet"
                return p
            self._schedule_bounds(theta_p, frame.air_period_s, roll)
            p.reason = "initialised"
            return p
        dt_s = (frame.t_us - self._t_prev_us) * 1e-6
        if not 0.0 < dt_s <= self.cfg.max_dt_s:
            p.reason = f"air-data gap {dt_s:.3f} s"
            return p
        self._schedule_bounds(theta_p, dt_s, roll)
        if self.cfg.step_aligned_rates:
            self._align_rates(theta_p)
        # one-step-ahead prediction x_hat_{k|k-1} = F(x_hat_{k-1|k-1}, 0, Theta_{k-1}) (eq. 29)
        if self._mhe is not None:
            x_pred = mhe_predict(self._mhe, self.model, dt_s)
        else:
            assert self._ekf is not None
            x_pred = self.model.f(self._ekf.x, np.zeros(N_U), self._theta_prev, dt_s)
        p.dt_s, p.x_pred, p.y_pred = dt_s, x_pred, self.model.h(x_pred, theta_p)
        return p

    def _align_rates(self, theta_p: Vec) -> None:
        """Give the previous node's Theta the IMU averages of the interval just ended.

        Eq. 20 integrates F(x_{k-1}, Theta_{k-1}) over t_s; its q, A_x, A_z are the averages over
        (t_{k-1}, t_k], which ``theta_p`` (Theta_k) carries. The output equations (eqs. 15-16)
        do not use them, so node k-1's outputs are unchanged."""
        s = self._mhe
        if s is not None:
            th = s.theta.copy()
            j = s.n - 1
            th[j, IT_Q], th[j, IT_AX], th[j, IT_AZ] = theta_p[IT_Q], theta_p[IT_AX], theta_p[IT_AZ]
            self._mhe = MheState(x=s.x, u=s.u, theta=th, dt_s=s.dt_s, y=s.y, y_mask=s.y_mask,
                                 n=s.n)
        elif self._theta_prev is not None:
            th_prev = self._theta_prev.copy()
            th_prev[_IT_RATES] = theta_p[_IT_RATES]
            self._theta_prev = th_prev

    def _theta(self, frame: Frame) -> tuple[Vec | None, str]:
        """Theta = [V_g, theta, q, A_x, A_z, z] (Wan2018 eq. 2) from the Frame."""
        if self._acc_n == 0:
            return None, "no IMU sample"
        if frame.euler_rad is None or frame.att_age_s > self.cfg.max_att_age_s:
            return None, "attitude missing or stale"
        if not frame.gps_fresh(self.cfg.max_gps_age_s):
            return None, "gps velocity missing or stale"
        if not np.isfinite(frame.baro_alt_m):
            return None, "baro altitude missing"
        vg = self._ground_speed(frame)
        n = self._acc_n
        th = [vg, frame.euler_rad[1], self._sum_q / n, self._sum_ax / n, self._sum_az / n,
              frame.baro_alt_m]
        if self.cfg.lateral_terms:  # + [phi, beta] (models.airdata.lateral)
            th += [frame.euler_rad[0], frame.ssa_rad if math.isfinite(frame.ssa_rad) else 0.0]
        return np.array(th), ""

    @staticmethod
    def _ground_speed(frame: Frame) -> float:
        """V_g of Wan2018 eq. 10: |(u_g, w_g)|, the ground velocity in the aircraft's vertical
        plane, i.e. the horizontal component along the heading and the vertical component."""
        assert frame.gps_vel_ned_mps is not None and frame.euler_rad is not None
        vn, ve, vd = frame.gps_vel_ned_mps
        psi = frame.euler_rad[2]
        v_along = vn * math.cos(psi) + ve * math.sin(psi)
        return math.hypot(v_along, vd)

    def _measurements(
        self, frame: Frame, theta_p: Vec, fused: tuple[float | None, float | None] | None
    ) -> tuple[Vec, Vec]:
        assert frame.gps_vel_ned_mps is not None
        if fused is None:  # eq. 19 with equal weights
            aoa = _nanmean_or_none(frame.aoa_rad)
            cas = _nanmean_or_none(frame.cas_mps)
        else:
            aoa, cas = fused
        y = np.array(
            [
                theta_p[0],
                -frame.gps_vel_ned_mps[2],
                aoa if aoa is not None else 0.0,
                cas if cas is not None else 0.0,
            ]
        )
        mask = np.array([1.0, 1.0, float(aoa is not None), float(cas is not None)])
        return y, mask

    def _start(self, t_us: int, theta_p: Vec, y: Vec, mask: Vec) -> None:
        aoa = y[IY_AOA] if mask[IY_AOA] else theta_p[1]  # alpha ~ theta (Wan2018 eq. 15)
        if mask[IY_CAS]:
            x0 = airdata_initial_state(aoa, y[IY_CAS], theta_p)
        else:
            x0 = np.array([aoa, theta_p[0], 0.0, 0.0])
        x0[2] = float(np.clip(x0[2], self.bounds.x_lb[2], self.bounds.x_ub[2]))
        if self.variant == "ekf":
            self._ekf = EkfState(x=x0, P=np.diag(self.weights.p_diag))
        else:
            self._mhe = mhe_init(
                x0, np.where(mask > 0, y, 0.0), mask, theta_p, self.cfg.horizon_n, N_U
            )
        self._theta_prev = theta_p
        self._t_prev_us = t_us


@dataclass(slots=True)
class _Prepared:
    """The part of one air-data step known before y_k (see :meth:`AirDataEstimator._prepare`)."""

    frame: Frame
    theta_p: Vec | None
    reason: str = ""
    dt_s: float = 0.0
    x_pred: Vec | None = None  # x_hat_{k|k-1} (eq. 29), which the MHE's shift appends
    y_pred: Vec | None = None  # h(x_hat_{k|k-1}, Theta_k); None at start-up or after a gap


def floats(x: Vec) -> list[float]:
    """A Frame's per-instance array as a list of Python floats (the family's per-sample code
    works on these: numpy's per-call overhead exceeds the arithmetic for three instances)."""
    return cast(list[float], x.tolist()) if isinstance(x, np.ndarray) else [float(v) for v in x]


def _nanmean_or_none(v: Vec) -> float | None:
    ok = np.isfinite(v)
    return float(np.mean(v[ok])) if np.any(ok) else None
