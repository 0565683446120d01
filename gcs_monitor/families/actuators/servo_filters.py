"""Lu2017's two fault-reconstruction filters on one control-surface servo.

Per surface, on every SURF sample (surface command, surface position, rod position):

* the **IOTSEKF** (Lu2017 sec. IV, eqs. 14-36; ``filters/iotsekf.py``) estimates the servo's
  state ``x = [q, q_dot, dP/P_s]``, the states of its reference model (internal to the servo
  electronics, see below) and the *input* fault ``f^i`` added to the valve command (liquid and
  solid OFC) from the rod position sensor (Lu2017 eq. 5, ``m = 1``);
* the **RTS-EKF** (Lu2017 sec. V, eqs. 37-48; ``filters/three_step.py``) estimates the state of
  the nominal (fault-free) servo and the *output* faults of the rod sensor and of the surface
  sensor (``m = p = 2``, ``F = I``): the deviation of each sensor from what the healthy servo
  would show (liquid jam: the two sensors disagree; solid jam and runaway: both deviate).

The model is the servo's closed loop (``models/_servo_jit.py``): the third-order reference
model driven by the commanded rod position (surface command over the rod gain, clipped to the
stroke, linear between samples), the NDI law (relative degree 3) on the model's own states and
the hydraulic plant, integrated over each sample interval in RK4 substeps with the transition,
fault input matrix and process noise of the filters. The valve command never reaches the ground:
the model computes it, as the servo electronics do (Lu2017 sec. III.B.3: the NDI controller
runs on the estimated states).

Process noise (Lu2017 gives none): a valve-command uncertainty (PSD ``valve_noise_psd``, through
``G``: unmodelled hinge loads, parameter errors) and small state noises; ``Q^{f^i}`` of the
fault random walk (eq. 14) from the fastest fault slope to follow, ``(fault_rate_sigma *
dt)^2`` with the measured interval. The command is sampled at the SURF rate, slower than the
autopilot changes it: when a change happened inside an interval is unknown, and its effect
lives on in the servo's reference model for a tenth of a second. The IOTSEKF therefore carries
the reference states in its state vector, with the covariance of that timing uncertainty as
extra process noise on the interval (``models.servo.command_timing_noise``): the measurements
correct the reference states instead of reading the mismatch as an input fault.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gcs_monitor.core.kernels import load_kernels
from gcs_monitor.core.params import param
from gcs_monitor.core.units import DEG2RAD
from gcs_monitor.models.servo import ServoLoopParams, ServoParams, pack_params

_MODEL = "gcs_monitor.models._servo_jit"
_IOTSEKF = "gcs_monitor.filters._iotsekf_jit"
_RTS = "gcs_monitor.filters._three_step_jit"


@dataclass(frozen=True, slots=True)
class ServoSensors:
    """The servo's geometry and position sensors, as the SURF message reports them."""

    rod_gain_radpm: float = param(1.4, "surface deflection per rod displacement, rad/m (the "
                                  "lever; ours: the simulator's transport airframe)", unit="si",
                                  positive=True)
    rod_stroke_m: float = param(0.35, "mechanical stop of the rod, |q| <= stroke (ours: the "
                                "transport airframe)", positive=True)
    rod_sigma_m: float = param(1.0e-4, "rod position sensor noise, 1 sigma (R of the filters; "
                               "Lu2017 eq. 3 gives no value)", positive=True)
    surf_sigma_rad: float = param(0.05 * DEG2RAD, "surface position sensor noise, 1 sigma",
                                  positive=True)


@dataclass(frozen=True, slots=True)
class ServoFilterConfig:
    """Settings of the two filters (Lu2017 gives no noise or random-walk values; ours)."""

    substep_s: float = param(0.005, "longest RK4 substep of the model over a sample interval",
                             positive=True)
    valve_noise_psd: float = param(1.0e-6, "PSD of the valve-command uncertainty (process "
                                   "noise through G; valve units^2 s)", positive=True)
    state_noise_psd: tuple[float, float, float] = param(
        (0.0, 1.0e-6, 0.0), "PSDs of direct state noises on q, q_dot, dP/P_s (SI^2 s)")
    reference_init_sigma: tuple[float, float, float] = param(
        (1.0e-3, 0.05, 1.0), "initial sigmas of the reference states r, r', r'' (m, m/s, "
        "m/s^2) at a (re)start")
    fault_rate_sigma: float = param(0.5, "random-walk rate of the input fault per second: "
                                    "Q^f = (rate dt)^2 (Lu2017 eq. 14; an OFC of 0.05 at "
                                    "up to ~3 Hz)", positive=True)
    fault_init_sigma: float = param(0.1, "initial input-fault sigma (valve units)",
                                    positive=True)
    bias_free_from_blend: bool = param(True, "predict the bias-free state as the nonlinear "
                                       "prediction of the blended state minus its fault part "
                                       "(identical to Lu2017 eq. 17 for a linear model; "
                                       "false: eq. 17 as printed, with f^i = 0)")
    command_lead_s: float = param(0.01, "the command a SURF sample reports took effect this "
                                  "long before the sample (the autopilot's servo-output "
                                  "period; ours: the simulator's 100 Hz): the model's command "
                                  "reaches it that much earlier")
    command_step_noise: bool = param(True, "a change of the rod command between two samples "
                                     "adds the covariance of its unknown instant to the "
                                     "IOTSEKF's process noise (ours, module docstring)")
    velocity_init_sigma_mps: float = param(0.05, "initial rod velocity sigma", positive=True)
    pressure_init_sigma: float = param(0.05, "initial dP/P_s sigma", positive=True)
    gate_sigma: float = param(3.0, "gate of the innovation test ratios (reporting)",
                              positive=True)


# layout of one surface's output row (ServoFilters.step)
(O_F_IN, O_U, O_X1, O_X2, O_X3, O_N1, O_N2, O_N3, O_F_ROD, O_F_SURF, O_NU, O_S, O_Q_COM,
 O_Y_ROD, O_Y_SURF) = range(15)
N_OUT = 15


class ServoFilters:
    """The IOTSEKF and the RTS-EKF of one surface (module docstring).

    ``step`` runs one SURF interval and returns the output row (``O_*`` indices): the input
    fault estimate, the valve command it implies ``u_NDI(x_hat) + f^i``, the IOTSEKF state, the
    RTS-EKF (nominal servo) state, its rod and surface output faults, the IOTSEKF innovation
    and its variance, the rod command and the two measurements (surface in m of rod).
    """

    def __init__(self, servo: ServoParams, loop: ServoLoopParams, sensors: ServoSensors,
                 cfg: ServoFilterConfig) -> None:
        self.cfg = cfg
        self.sensors = sensors
        self.prm = pack_params(servo, loop, sensors.rod_stroke_m)
        self._model = load_kernels(_MODEL)
        self._iots = load_kernels(_IOTSEKF)
        self._rts = load_kernels(_RTS)
        g = sensors.rod_gain_radpm
        self._H1 = np.array([[1.0, 0.0, 0.0, 0.0, 0.0, 0.0]])
        self._R1 = np.array([[sensors.rod_sigma_m ** 2]])
        self._H2 = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
        self._R2 = np.diag([sensors.rod_sigma_m ** 2, (sensors.surf_sigma_rad / g) ** 2])
        self._F2 = np.eye(2)
        self._qs = np.concatenate([np.array(cfg.state_noise_psd, dtype=np.float64),
                                   np.zeros(3)])
        # work arrays
        self._Phi = np.empty((6, 6))
        self._Gam = np.empty((6, 1))
        self._Qd = np.empty((6, 6))
        self._Phi_r = np.empty((6, 6))
        self._Gam_r = np.empty(6)
        self._Qd_r = np.empty((6, 6))
        self._s = np.empty(6)
        self._sb = np.empty(6)
        self._Qf = np.empty((1, 1))
        self._ots = np.empty(6 + 36 + 1 + 1 + 6 + 6 + 36)
        self._oin = np.empty(3)
        self._grad = np.empty(3)
        self._y2 = np.empty(2)
        self._hx2 = np.empty(2)
        self._Pp = np.empty((3, 3))
        self._xr = np.empty(3)
        self._Pr = np.empty((3, 3))
        self._Qt = np.zeros((6, 6))
        self._fr = np.empty(2)
        self._Pfr = np.empty((2, 2))
        self._nu2 = np.empty(2)
        self._sd2 = np.empty(2)
        self._ra2 = np.empty(2)
        self.started = False
        self.q_com = 0.0

    def rod_command(self, cmd_rad: float) -> float:
        """Rod command (m) of a surface command: over the rod gain, clipped to the stroke (as the
        servo's own input stage)."""
        st = self.sensors.rod_stroke_m
        q = cmd_rad / self.sensors.rod_gain_radpm
        return st if q > st else (-st if q < -st else q)

    def start(self, cmd_rad: float, y_rod_m: float) -> None:
        """(Re)start on a sample: the rod at rest where its sensor says, the reference model on
        it; no fault estimate yet."""
        c = self.cfg
        self.q_com = self.rod_command(cmd_rad)
        sig = [self.sensors.rod_sigma_m, c.velocity_init_sigma_mps, c.pressure_init_sigma,
               *c.reference_init_sigma]
        P0 = np.diag(np.square(sig))
        # IOTSEKF over [x, r]: the rod at rest where its sensor says, the reference on it
        self.x_bar = np.array([y_rod_m, 0.0, 0.0, y_rod_m, 0.0, 0.0])
        self.P_bar = P0.copy()
        self.f = np.zeros(1)
        self.Pf = np.array([[c.fault_init_sigma ** 2]])
        self.V = np.zeros((6, 1))
        self.x_hat = self.x_bar.copy()
        self.Px = P0.copy()
        # RTS-EKF: the nominal servo x (its reference model r_nom carried, not estimated)
        self.x_nom = self.x_bar[:3].copy()
        self.r_nom = self.x_bar[3:].copy()
        self.P_nom = P0[:3, :3].copy()
        self.f_out = np.zeros(2)
        self.started = True

    def step(self, dt_s: float, cmd_rad: float, y_rod_m: float, y_surf_rad: float,
             out: np.ndarray) -> bool:
        """One SURF interval of both filters; fills ``out`` (N_OUT,). False on a numerical
        failure (the filters keep their previous state; the caller restarts them)."""
        c = self.cfg
        mk = self._model
        prm = self.prm
        qc0 = self.q_com
        qc1 = self.rod_command(cmd_rad)
        n_sub = max(1, math.ceil(dt_s / c.substep_s - 1e-9))
        # the reported command took effect command_lead_s before its sample instant
        knee = max(dt_s - c.command_lead_s, 0.0)
        qv = c.valve_noise_psd
        f0 = float(self.f[0])
        # IOTSEKF: linearise along the blended estimate with the fault held (Lu2017 eqs.
        # 19-20, note 1 of filters/iotsekf.py); propagate the bias-free state with f = 0 (17)
        s, sb = self._s, self._sb
        s[:] = self.x_hat
        if c.command_step_noise:
            mk.command_timing_noise(s, qc0, qc1, f0, dt_s, n_sub, prm, self._Qt)
        mk.propagate(s, qc0, qc1, f0, dt_s, knee, n_sub, prm, True, qv, self._qs,
                     self._Phi, self._Gam[:, 0], self._Qd)
        if c.command_step_noise:
            self._Qd += self._Qt
            self._Qt[:, :] = 0.0
        if c.bias_free_from_blend:
            # x_bar_{k|k-1} + U f_hat = the nonlinear prediction of x_hat (papers-notes,
            # Lu2017 eq. 17): x_bar propagated = F(x_hat, f_hat) - (Phi V + Gamma) f_hat
            sb[:] = s - (self._Phi @ self.V[:, 0] + self._Gam[:, 0]) * f0
        else:  # eq. 17 as printed: the bias-free state propagated with f^i = 0
            sb[:] = self.x_bar
            mk.propagate(sb, qc0, qc1, 0.0, dt_s, knee, n_sub, prm, False, qv, self._qs,
                         self._Phi_r, self._Gam_r, self._Qd_r)
        rf = c.fault_rate_sigma * dt_s
        self._Qf[0, 0] = rf * rf
        y1 = np.array([y_rod_m])
        code = self._iots.step(sb.copy(), self._Phi, self._Gam, self._Qd, self._Qf,
                               self.x_bar, self.P_bar, self.f, self.Pf, self.V, self._H1, y1,
                               self._R1, c.gate_sigma, self._ots, self._oin)
        if code != 0:
            return False
        o = self._ots
        self.x_bar = o[0:6].copy()
        self.P_bar = o[6:42].reshape(6, 6).copy()
        self.f = o[42:43].copy()
        self.Pf = o[43:44].reshape(1, 1).copy()
        self.V = o[44:50].reshape(6, 1).copy()
        self.x_hat = o[50:56].copy()
        self.Px = o[56:92].reshape(6, 6).copy()
        # RTS-EKF: the nominal servo (no input fault, eq. 38), P by eq. 39 on the plant block
        # (the reference states are given to it), eqs. 40-48
        s[:3] = self.x_nom
        s[3:] = self.r_nom
        mk.propagate(s, qc0, qc1, 0.0, dt_s, knee, n_sub, prm, True, qv, self._qs, self._Phi_r,
                     self._Gam_r, self._Qd_r)
        self._rts.predict_covariance(self.P_nom, np.ascontiguousarray(self._Phi_r[:3, :3]),
                                     np.ascontiguousarray(self._Qd_r[:3, :3]), self._Pp)
        xr_pred = s[:3].copy()
        g = self.sensors.rod_gain_radpm
        y_surf_m = y_surf_rad / g
        self._y2[0] = y_rod_m
        self._y2[1] = y_surf_m
        self._hx2[0] = xr_pred[0]
        self._hx2[1] = xr_pred[0]
        ok = self._rts.update(xr_pred, self._Pp, self._hx2, self._H2, self._F2, self._y2,
                              self._R2, c.gate_sigma, self._xr, self._Pr, self._fr, self._Pfr,
                              self._nu2, self._sd2, self._ra2)
        if not ok:
            return False
        self.x_nom = self._xr.copy()
        self.r_nom = s[3:].copy()
        self.P_nom = self._Pr.copy()
        self.f_out = self._fr.copy()
        self.q_com = qc1
        # the valve command the IOTSEKF's estimate implies: u_NDI(x_hat) + f^i
        s[:] = self.x_hat
        u = mk.ndi(s, qc1, prm, self._grad) + float(self.f[0])
        out[O_F_IN] = float(self.f[0])
        out[O_U] = u
        out[O_X1:O_X3 + 1] = self.x_hat[:3]
        out[O_N1:O_N3 + 1] = self.x_nom
        out[O_F_ROD] = float(self.f_out[0])
        out[O_F_SURF] = float(self.f_out[1])
        out[O_NU] = float(self._oin[0])
        out[O_S] = float(self._oin[1])
        out[O_Q_COM] = qc1
        out[O_Y_ROD] = y_rod_m
        out[O_Y_SURF] = y_surf_m
        return True
