"""IMU fault identification by OTSEKF + HOSM differentiation (Atmaca2025).

Chain per Frame (Atmaca2025 Fig. 1): the body-frame ground-speed model (eqs. 9-14,
``models/kinematics_body.py``; with zero fault estimate as eq. 20 prints it, or with the current
fault estimates in the cross terms for ``mapping="flat"``/``"paper"``), the optimal two-stage EKF
(eqs. 20-42, ``filters/otsekf.py``) whose bias stage estimates the state drift ``mu`` (eq. 29),
the Levant differentiator (eqs. 47-50, ``filters/sliding_mode.py``) and the drift-rate to fault
mapping (eq. 51, :func:`drift_rate_to_fault`).

What is differentiated, and how the derivative becomes the fault (``mapping="exact"``,
default). The fault-neglecting state estimator integrates the model with zero fault estimate,
``f(x, u_m, 0)``, as eq. 20 prints it, so the drift rate is ``d mu / dt = A(x) f`` with ``A`` the
fault input matrix of the model at the estimate (``fault_input_matrix``, ``-G`` of eq. 15): full
in a bank and with the ground speed in eqs. 9-11. Each drift increment is taken into fault
coordinates, ``g_k = g_{k-1} + A(x_hat_{k-1})^{-1} (mu_k - mu_{k-1})`` (closed form, no
singularity), so that ``dg/dt = f``, and the HOSM differentiates ``g``: ``z_1`` *is* the fault, as
eq. 51 says. The alternatives ``mapping="flat"`` / ``"paper"`` put ``f_hat`` into the cross terms
of eqs. 9-14 and differentiate ``mu``, dividing by ``D`` / taking ``z_1`` as it is (eq. 51
printed). Both assume ``d mu / dt = D f``, true only at ``f_hat = f``; otherwise it is
``D f_hat + A (f - f_hat)``, and the loop ``f_hat -> eqs. 9-14 -> mu -> HOSM -> f_hat`` (gain
``tan phi`` through the ``sin phi`` terms of eqs. 13-14) oscillates at ~1 Hz in a 30 deg
coordinated turn with zero true fault (docs/papers-notes.md, Atmaca2025).

How the drift enters the two-stage filter (not written out in Atmaca2025, see
docs/papers-notes.md): ``mu`` is the model state minus the true state. The true state obeys the
model of eqs. 9-14 minus the drift increments, ``x_k = f_d(x_{k-1}, u_m) - (mu_k - mu_{k-1})``, so
in the two-stage form the drift increments are the bias noise and reappear with the opposite sign
in the state noise: ``Qx = Gamma Q Gamma^T + Q^mu``, ``Q^{x mu} = -Q^mu`` (the "correlation between
process and fault noise" of eq. 36), and the bias-to-state matrix of eq. 37 is ``B = 0`` when the
model is evaluated at the drift-corrected estimate (``propagate="corrected"``, default), or
``B = Phi - I`` when it is evaluated at the drifting ``x_bar`` as eq. 20 literally reads
(``propagate="paper"``).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import cast

import numpy as np

from gcs_monitor.core import constants as c
from gcs_monitor.core.atmosphere import gravity_mps2
from gcs_monitor.core.kernels import load_kernels
from gcs_monitor.core.params import param, section
from gcs_monitor.core.types import ChannelId, Mat, Vec
from gcs_monitor.fdi.records import Estimate
from gcs_monitor.filters.otsekf import (
    OtsekfPrediction,
    OtsekfState,
    otsekf_init,
    otsekf_step,
)
from gcs_monitor.filters.sliding_mode import HosmState, LevantGains, hosm_init, hosm_step
from gcs_monitor.models.kinematics_body import (
    N_STATE,
    body_gs_meas_jac,
    drift_rate_to_fault,
)
from gcs_monitor.telemetry.frame import Frame
from gcs_monitor.telemetry.period import SamplePeriod

log = logging.getLogger(__name__)

FAULT_CHANNELS: tuple[ChannelId, ...] = (
    ChannelId("acc", 0, "x"),
    ChannelId("acc", 0, "y"),
    ChannelId("acc", 0, "z"),
    ChannelId("gyro", 0, "p"),
    ChannelId("gyro", 0, "q"),
    ChannelId("gyro", 0, "r"),
)
RESIDUAL_CHANNELS: tuple[ChannelId, ...] = (
    ChannelId("gps_vel", 0, "n"),
    ChannelId("gps_vel", 0, "e"),
    ChannelId("gps_vel", 0, "d"),
    ChannelId("euler", 0, "phi"),
    ChannelId("euler", 0, "theta"),
    ChannelId("euler", 0, "psi"),
)
_PHI, _PSI = 3, 5  # roll and heading wrap at +-pi (a vehicle on its back rolls past pi)


@dataclass(frozen=True, slots=True)
class AtmacaSensorNoise:
    """Sensor 1-sigma noise (Atmaca2025 Table 1; its rates, GPS 10 Hz and IMU 100 Hz, are the
    simulator's: the estimator works from the measured sample times)."""

    gps_vel_sigma_mps: float = param(0.030, "GPS velocity noise", positive=True)
    phi_theta_sigma_rad: float = param(8.7e-5, "roll and pitch noise", positive=True,
                                       unit="si")
    psi_sigma_rad: float = param(1.7e-4, "heading noise", positive=True, unit="si")
    acc_sigma_mps2: float = param(6.9e-4, "accelerometer noise", positive=True)
    gyro_sigma_radps: float = param(4.1e-6, "gyro noise", positive=True, unit="si")


@dataclass(frozen=True, slots=True)
class ImuHosmConfig:
    """Estimator tuning. Atmaca2025 gives no values for the drift noise and the HOSM gains
    ("trial and error", Sec. III.B.2); the defaults below are this project's tuning, validated by
    tests/gcs_monitor/families/imu/test_imu_hosm.py on the Table 2 and Table 3 fault cases."""

    noise: AtmacaSensorNoise = section(AtmacaSensorNoise, "sensor noise (Atmaca2025 Table 1)")
    drift_acc_sigma_mps_rs: float = param(0.1, "random-walk intensity of the velocity drift "
                                          "Q^mu (m/s per sqrt(s))", positive=True)
    drift_gyro_sigma_rad_rs: float = param(3.0e-4, "random-walk intensity of the attitude "
                                           "drift Q^mu (rad per sqrt(s))", positive=True)
    hosm_lipschitz_acc: float = param(100.0, "Levant L of the velocity-drift channels, bound "
                                      "of the third derivative of f_A (m/s^5)", positive=True)
    hosm_lipschitz_gyro: float = param(0.5, "Levant L of the attitude-drift channels, bound of "
                                       "the third derivative of f_omega (rad/s^4)",
                                       positive=True)
    levant: LevantGains = section(LevantGains, "Levant differentiator coefficients "
                                  "(Atmaca2025 eqs. 47-50)")
    gps_r_scale: float = param(1.0, "multiplies the GPS velocity variance (interpolated GPS "
                               "gives correlated copies of each sample)", positive=True)
    gate_sigma: float = param(3.0, "innovation gate of the reported test ratio", positive=True)
    max_gps_age_s: float = param(0.5, "older GPS velocity makes the estimate unavailable",
                                 positive=True)
    max_att_age_s: float = param(0.1, "older attitude makes the estimate unavailable",
                                 positive=True)
    max_dt_s: float = param(0.1, "a larger gap between frames resets the filter",
                            positive=True)
    max_gap_periods: float = param(2.5, "the gap limit is at least this many measured sample "
                                   "periods (a slow IMU is not a gap)", positive=True)
    mapping: str = param("exact", "drift-rate to fault mapping: exact, flat, or paper (eq. 51 "
                         "as printed); see the module docstring",
                         choices=("exact", "flat", "paper"))
    propagate: str = param("corrected", "model evaluated at the drift-corrected estimate "
                           "(corrected) or at x_bar as eq. 20 reads (paper)",
                           choices=("corrected", "paper"))


@dataclass(frozen=True, slots=True)
class _Step:
    """Everything one OTSEKF+HOSM step needs besides the filter states."""

    u_m: Vec
    y: Vec
    dt_s: float
    g_mps2: float


class ImuHosmEstimator:
    """OTSEKF + HOSM IMU fault estimator (Atmaca2025), one per vehicle and IMU instance 0."""

    name = "imu_hosm"

    def __init__(self, cfg: ImuHosmConfig | None = None) -> None:
        self.cfg = cfg if cfg is not None else ImuHosmConfig()
        n = self.cfg.noise
        self._R: Mat = np.diag(
            [self.cfg.gps_r_scale * n.gps_vel_sigma_mps**2] * 3
            + [n.phi_theta_sigma_rad**2] * 2
            + [n.psi_sigma_rad**2]
        )
        self._Q_imu: Mat = np.diag([n.acc_sigma_mps2**2] * 3 + [n.gyro_sigma_radps**2] * 3)
        self._lambdas: Mat = self.cfg.levant.lambdas(
            np.array([self.cfg.hosm_lipschitz_acc] * 3 + [self.cfg.hosm_lipschitz_gyro] * 3)
        )
        self._drift_var_rate = np.array(
            [self.cfg.drift_acc_sigma_mps_rs**2] * 3 + [self.cfg.drift_gyro_sigma_rad_rs**2] * 3
        )
        self._q_imu_diag: Vec = self._Q_imu.diagonal().copy()
        self._eye = np.eye(N_STATE)
        self._zero_B = np.zeros((N_STATE, N_STATE))
        kb = "gcs_monitor.models._kinematics_body_jit"
        self._kb = load_kernels(kb)
        # Work arrays of the kernels: they overwrite them every step and the filter does not
        # keep them, so one OtsekfPrediction is reused.
        ns = N_STATE
        self._pred_buf = OtsekfPrediction(
            x_bar_prop=np.zeros(ns),
            Phi=np.zeros((ns, ns)),
            B=np.zeros((ns, ns)),
            Qx=np.zeros((ns, ns)),
            Qxmu=np.zeros((ns, ns)),
            Qmu=np.zeros((ns, ns)),
        )
        self._h_buf: Vec = np.zeros(ns)
        self._H_buf: Mat = np.zeros((ns, ns))
        self._g_key = (math.nan, math.nan)
        self._g = math.nan
        self._zero_f: Vec = np.zeros(ns)
        if self.cfg.mapping not in ("exact", "flat", "paper"):
            raise ValueError(
                f"mapping must be 'exact', 'flat' or 'paper', got {self.cfg.mapping!r}"
            )
        if self.cfg.propagate not in ("corrected", "paper"):
            raise ValueError(
                f"propagate must be 'corrected' or 'paper', got {self.cfg.propagate!r}"
            )
        self._instance: int | None = None  # the IMU instance monitored (the primary)
        self._channels = FAULT_CHANNELS
        self.reset()

    def reset(self) -> None:
        self._filt: OtsekfState | None = None
        self._hosm: HosmState | None = None
        self._f_hat: Vec = np.zeros(N_STATE)
        self._f_int: Vec = np.zeros(N_STATE)
        self._t_prev_us: int | None = None
        self._period = SamplePeriod()  # of its usable samples: the gap limit

    # ------------------------------------------------------------------ helpers
    def _init(self, y: Vec) -> None:
        phi, theta, psi = (float(a) for a in y[3:])
        H = body_gs_meas_jac(np.array([0.0, 0.0, 0.0, phi, theta, psi]))
        C = H[:3, :3]  # C_ned_frd at the measured attitude
        x0 = np.concatenate([C.T @ y[:3], y[3:]])
        P0 = self._R.copy()  # initial state uncertainty = one measurement
        self._filt = otsekf_init(x0, P0, np.zeros(N_STATE), np.zeros((N_STATE, N_STATE)))
        self._hosm = hosm_init(np.zeros(N_STATE))
        self._f_hat = np.zeros(N_STATE)
        self._f_int = np.zeros(N_STATE)

    def _prediction(self, s: OtsekfState, st: _Step) -> OtsekfPrediction:
        """Model quantities for k-1 -> k (Atmaca2025 eqs. 20, 25-27), through the model kernel
        (its numpy reference: tests/reference/imu_hosm.py)."""
        p = self._pred_buf
        self._kb.prediction(
            s.x_hat, s.x_bar, s.V, s.mu, st.u_m, self._f_model(), st.g_mps2, st.dt_s,
            self._q_imu_diag, self._drift_var_rate, self.cfg.propagate == "corrected",
            p.Phi, p.B, p.Qx, p.Qxmu, p.Qmu, p.x_bar_prop,
        )  # fmt: skip
        return p

    def _f_model(self) -> Vec:
        """Fault estimate inside eqs. 9-14: zero for ``mapping="exact"`` (eq. 20 as printed)."""
        return self._zero_f if self.cfg.mapping == "exact" else self._f_hat

    def _measurement(self, x: Vec) -> tuple[Vec, Mat]:
        """h(x) and its Jacobian (Atmaca2025 eq. 15)."""
        self._kb.measurement(x, self._h_buf, self._H_buf)
        return self._h_buf, self._H_buf

    def _fault_increment(self, x_prev: Vec, mu: Vec, mu_prev: Vec) -> None:
        """``f_int += A(x_prev)^-1 (mu - mu_prev)``: the drift increment in fault coordinates
        (module docstring), in place."""
        self._kb.fault_integral_step(x_prev, mu, mu_prev, self._f_int)

    def _frame_inputs(self, frame: Frame) -> tuple[_Step | None, str]:
        imu = frame.primary_imu
        if imu is None or imu.t_us != frame.t_us:
            return None, f"imu{frame.primary} missing"
        if frame.primary != self._instance:  # the primary IMU changed: a clean restart
            if self._instance is not None:
                self.reset()
            self._instance = frame.primary
            self._channels = tuple(ChannelId(c.kind, frame.primary, c.axis)
                                   for c in FAULT_CHANNELS)
        if frame.euler_rad is None or not _all_finite(frame.euler_rad):
            return None, "attitude missing"
        if frame.att_age_s > self.cfg.max_att_age_s:
            return None, "attitude stale"
        if frame.gps_vel_ned_mps is None or not _all_finite(frame.gps_vel_ned_mps):
            return None, "gps velocity missing"
        if not frame.gps_fresh(self.cfg.max_gps_age_s):
            return None, "gps velocity stale"
        u_m = np.concatenate([imu.acc_frd_mps2, imu.omega_frd_radps])
        if not _all_finite(u_m):
            return None, "imu not finite"
        y = np.concatenate([frame.gps_vel_ned_mps, frame.euler_rad])
        if math.isfinite(frame.lat_rad) and math.isfinite(frame.alt_msl_m):
            key = (frame.lat_rad, frame.alt_msl_m)
            if key != self._g_key:  # once per GPS position, not per IMU sample
                self._g_key = key
                self._g = gravity_mps2(frame.lat_rad, frame.alt_msl_m)
            g = self._g
        else:
            g = c.GRAVITY_STD_MPS2
        dt = 0.0 if self._t_prev_us is None else (frame.t_us - self._t_prev_us) * 1.0e-6
        return _Step(u_m=u_m, y=y, dt_s=dt, g_mps2=g), ""

    # ------------------------------------------------------------------ protocol
    def step(self, frame: Frame) -> Estimate:
        """Process one Frame; see the module docstring for the chain."""
        st, reason = self._frame_inputs(frame)
        if st is None:
            return Estimate.unavailable(self.name, frame.t_us, reason)
        self._period.add(frame.t_us)
        max_dt_s = max(self.cfg.max_dt_s, self.cfg.max_gap_periods * self._period.seconds()) \
            if self._period.known else self.cfg.max_dt_s
        if self._filt is None or st.dt_s <= 0.0 or st.dt_s > max_dt_s:
            if self._filt is not None:
                log.info("imu_hosm: frame gap %.3f s, reset", st.dt_s)
            self._init(st.y)
            self._t_prev_us = frame.t_us
            return self._estimate(frame.t_us, st, np.zeros(N_STATE), np.zeros(N_STATE), True)
        assert self._hosm is not None
        x_prev, mu_prev = self._filt.x_hat, self._filt.mu
        pred = self._prediction(self._filt, st)
        filt, innov = otsekf_step(
            self._filt,
            pred,
            self._measurement,
            st.y,
            self._R,
            gate_sigma=self.cfg.gate_sigma,
            wrap_idx=(_PHI, _PSI),
        )
        self._t_prev_us = frame.t_us
        if not innov.numerics_ok:
            log.warning("imu_hosm: numerical failure at t_us=%d, reset", frame.t_us)
            self._init(st.y)
            return self._estimate(frame.t_us, st, np.zeros(N_STATE), np.zeros(N_STATE), False)
        self._filt = filt
        self._f_hat = self._fault_update(x_prev, mu_prev, filt, st.dt_s)
        return self._estimate(frame.t_us, st, innov.nu, innov.test_ratio, True)

    def _fault_update(self, x_prev: Vec, mu_prev: Vec, filt: OtsekfState, dt_s: float) -> Vec:
        """Eqs. 47-50 and eq. 51 (``mapping``, see the module docstring)."""
        assert self._hosm is not None
        if self.cfg.mapping != "exact":
            self._hosm = hosm_step(self._hosm, filt.mu, self._lambdas, dt_s)
            return drift_rate_to_fault(self._hosm.z[1], filt.x_hat, mapping=self.cfg.mapping)
        # drift increment of step k-1 -> k into fault coordinates at the state the model used
        self._fault_increment(x_prev, filt.mu, mu_prev)
        self._hosm = hosm_step(self._hosm, self._f_int, self._lambdas, dt_s)
        return cast(Vec, self._hosm.z[1].copy())

    def _estimate(self, t_us: int, st: _Step, nu: Vec, ratio: Vec, ok: bool) -> Estimate:
        assert self._filt is not None
        x = self._filt.x_hat
        fh = self._f_hat
        virt = st.u_m - fh
        vel_ned = self._measurement(x)[0][:3].copy()
        states: dict[str, Vec] = {
            "vel_frd_mps": x[:3].copy(),
            "vel_ned_mps": vel_ned,
            "euler_rad": x[3:].copy(),
            "drift": self._filt.mu.copy(),
            "fault_hat": fh.copy(),
            "test_ratio": np.array(ratio, dtype=np.float64),
        }
        return Estimate(
            name=self.name,
            t_us=t_us,
            states=states,
            faults=dict(zip(self._channels, fh.tolist(), strict=True)),
            residuals=dict(zip(RESIDUAL_CHANNELS, np.asarray(nu).tolist(), strict=True)),
            virtual=dict(zip(self._channels, virt.tolist(), strict=True)),
            numerics_ok=ok,
        )


def _all_finite(a: Vec) -> bool:
    """``np.isfinite(a).all()`` for a short vector, on Python floats (cheaper at n = 3-6)."""
    return all(map(math.isfinite, a.ravel().tolist() if isinstance(a, np.ndarray) else a))
