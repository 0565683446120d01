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

    substep_s: float = param(0.01, "longest RK4 substep of the model over a sample interval "
                             "(the closed loop's fastest poles, ~60 rad/s, give |lambda h| ~ "
                             "0.6: RK4 stays accurate; half of it changes no estimate by 1e-4)",
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
                                  "period): the model's command reaches it that much earlier; "
                                  "with command_lead_window_s > 0 only the first guess, until "
                                  "the rod says otherwise")
    command_lead_window_s: float = param(20.0, "time constant (s) of the discounted rod "
                                         "prediction errors that identify the command lead "
                                         "among 0, 1/4, 1/2 and 1 SURF period (ours, "
                                         "ServoFilters); 0: always command_lead_s")
    command_lead_switch: float = param(25.0, "a candidate lead replaces the one in use when "
                                       "its discounted squared rod error is smaller by this "
                                       "many rod-noise variances (hysteresis)", positive=True)
    command_lead_segment: int = param(10, "samples each candidate's nominal servo runs "
                                      "uncorrected from the IOTSEKF's estimate before it is "
                                      "anchored again", positive=True)
    command_step_noise: bool = param(True, "a change of the rod command between two samples "
                                     "adds the covariance of its unknown instant to the "
                                     "IOTSEKF's process noise (ours, module docstring)")
    command_jitter_noise: bool = param(True, "a command that jumps between samples (faster "
                                       "than the SURF stream) adds the covariance of the "
                                       "unseen samples in between (ours, see ServoFilters)")
    command_jitter_window_s: float = param(0.4, "window of the (trimmed) RMS of the command's "
                                           "second differences that measures the unseen "
                                           "samples' spread", positive=True)
    velocity_init_sigma_mps: float = param(0.05, "initial rod velocity sigma", positive=True)
    pressure_init_sigma: float = param(0.05, "initial dP/P_s sigma", positive=True)
    gate_sigma: float = param(3.0, "gate of the innovation test ratios (reporting)",
                              positive=True)


# the output row of one surface (ServoFilters.step): the kernel's O_* indices
(O_F_IN, O_U, O_X1, O_X2, O_X3, O_N1, O_N2, O_N3, O_F_ROD, O_F_SURF, O_NU, O_S, O_Q_COM,
 O_Y_ROD, O_Y_SURF, O_SF_ROD, O_SF_D, O_JIT, O_LEAD, O_ENV) = range(20)
N_OUT = 20
_KERNEL = "gcs_monitor.families.actuators._servo_filters_jit"


def pack_config(sensors: ServoSensors, cfg: ServoFilterConfig) -> np.ndarray:
    """The kernel's configuration vector (``C_*`` indices)."""
    k = load_kernels(_KERNEL)
    out = np.empty(k.N_CFG)
    out[k.C_GAIN] = sensors.rod_gain_radpm
    out[k.C_STROKE] = sensors.rod_stroke_m
    out[k.C_ROD_SIG] = sensors.rod_sigma_m
    out[k.C_SURF_SIG] = sensors.surf_sigma_rad
    out[k.C_SUBSTEP] = cfg.substep_s
    out[k.C_QVALVE] = cfg.valve_noise_psd
    out[k.C_QS0], out[k.C_QS1], out[k.C_QS2] = cfg.state_noise_psd
    out[k.C_FRATE] = cfg.fault_rate_sigma
    out[k.C_GATE] = cfg.gate_sigma
    out[k.C_LEAD] = cfg.command_lead_s
    out[k.C_STEP_NOISE] = float(cfg.command_step_noise)
    out[k.C_JIT_NOISE] = float(cfg.command_jitter_noise)
    out[k.C_JIT_WINDOW] = cfg.command_jitter_window_s
    out[k.C_BLEND] = float(cfg.bias_free_from_blend)
    out[k.C_LEAD_TAU] = cfg.command_lead_window_s
    out[k.C_LEAD_SWITCH] = cfg.command_lead_switch
    out[k.C_LEAD_SEGMENT] = cfg.command_lead_segment
    return out


class ServoFilters:
    """The IOTSEKF and the RTS-EKF of one surface (module docstring), one kernel call per SURF
    sample (``_servo_filters_jit.surface_step``).

    ``step`` runs one SURF interval and fills the output row (``O_*`` indices): the input
    fault estimate, the valve command it implies ``u_NDI(x_hat) + f^i``, the IOTSEKF state, the
    RTS-EKF (nominal servo) state, its rod and surface output faults, the IOTSEKF innovation
    and its variance, the rod command, the two measurements (surface in m of rod), the standard
    deviations of the rod output fault and of the rod-surface disagreement (from the RTS-EKF's
    ``P^f``, eq. 43) and the unseen-command spread (m).

    Per interval: the covariance of the command's unknown profile inside it (a change at an
    unknown instant; unseen samples when the command jumps between samples, their spread from
    the trimmed RMS of its second differences, ``_servo_filters_jit.unseen_spread``) is
    evaluated
    at the IOTSEKF's estimate
    and added to both filters' process noise; the IOTSEKF propagates its blended estimate with
    the fault held (Phi, Gamma, Q_d along it) and predicts the bias-free state from it
    (``bias_free_from_blend``); the RTS-EKF propagates the nominal servo. The sigma of the rod
    output fault adds the nominal servo's timing envelope: two more copies of it run the same
    command sequence with every change at the start and at the end of its interval (a command
    step that saturates the valve leaves the rod a rate x interval apart for the whole slew,
    which no linearised covariance carries); uniform between the two, variance
    ``(x1_early - x1_late)^2 / 12``.

    The command a SURF sample reports took effect one autopilot step before the sample (the
    loop computes it and holds it for a step), so the model's command ramps from the previous
    sample's value and reaches the new one ``lead`` before the sample. The lead is the
    autopilot's servo-output period, which the telemetry does not carry: the kernel
    identifies it (``_servo_filters_jit.identify_lead``; ``command_lead_s`` is only the first
    guess) by running the nominal servo once per candidate (0, 1/4, 1/2, 1 of the SURF period)
    from the IOTSEKF's estimate over segments of ``command_lead_segment`` samples and keeping
    the one whose rod stays closest to the sensor. A wrong lead shows as an input fault that
    follows the command's rate (a loop at 200 Hz taken for 100 Hz: 0.02-0.03 of the valve
    command in the simulator's turns, above the threshold).
    """

    def __init__(self, servo: ServoParams, loop: ServoLoopParams, sensors: ServoSensors,
                 cfg: ServoFilterConfig, state: np.ndarray | None = None) -> None:
        """``state``: the (N_STATE,) array to keep the packed state in (a row of the servo
        tier's array of all surfaces, stepped at once by ``_servo_filters_jit.surfaces_step``);
        a new one by default."""
        self.cfg = cfg
        self.sensors = sensors
        self.prm = pack_params(servo, loop, sensors.rod_stroke_m)
        self._k = k = load_kernels(_KERNEL)
        self._cfgv = pack_config(sensors, cfg)
        if state is None:
            state = np.zeros(k.N_STATE)
        elif state.shape != (k.N_STATE,):
            raise ValueError(f"state must have shape ({k.N_STATE},), got {state.shape}")
        else:
            state[:] = 0.0
        self.st = state
        self.started = False

    def rod_command(self, cmd_rad: float) -> float:
        """Rod command (m) of a surface command: over the rod gain, clipped to the stroke (as the
        servo's own input stage)."""
        st = self.sensors.rod_stroke_m
        q = cmd_rad / self.sensors.rod_gain_radpm
        return st if q > st else (-st if q < -st else q)

    def start(self, cmd_rad: float, y_rod_m: float) -> None:
        """(Re)start on a sample: the rod at rest where its sensor says, the reference model on
        it; no fault estimate yet."""
        c, k = self.cfg, self._k
        sig = [self.sensors.rod_sigma_m, c.velocity_init_sigma_mps, c.pressure_init_sigma,
               *c.reference_init_sigma]
        P0 = np.diag(np.square(sig)).ravel()
        x0 = np.array([y_rod_m, 0.0, 0.0, y_rod_m, 0.0, 0.0])
        st = self.st
        # the identified command timing belongs to the vehicle, not to this start: kept
        ident = st[k.S_LJ:k.S_DTREF + 1].copy() if self.started else None
        st[:] = 0.0
        if ident is None:
            st[k.S_LI] = -1.0  # no candidate chosen yet (the configured lead first)
        else:
            st[k.S_LJ:k.S_DTREF + 1] = ident
        st[k.S_XBAR:k.S_XBAR + 6] = x0
        st[k.S_PBAR:k.S_PBAR + 36] = P0
        st[k.S_PF] = c.fault_init_sigma ** 2
        st[k.S_XHAT:k.S_XHAT + 6] = x0
        st[k.S_PX:k.S_PX + 36] = P0
        # RTS-EKF: the nominal servo [x, r] (m = p = 2: propagated, never corrected)
        st[k.S_XNOM:k.S_XNOM + 6] = x0
        st[k.S_PNOM:k.S_PNOM + 36] = P0
        st[k.S_XE:k.S_XE + 6] = x0
        st[k.S_XL:k.S_XL + 6] = x0
        st[k.S_QCOM] = self.rod_command(cmd_rad)
        st[k.S_QPREV] = math.nan
        self.started = True

    def step(self, dt_s: float, cmd_rad: float, y_rod_m: float, y_surf_rad: float,
             out: np.ndarray) -> bool:
        """One SURF interval of both filters; fills ``out`` (N_OUT,). False on a numerical
        failure (the filters keep their previous state; the caller restarts them)."""
        code = self._k.surface_step(self.st, dt_s, cmd_rad, y_rod_m, y_surf_rad, self.prm,
                                    self._cfgv, out)
        return bool(code == 0)

    # views of the packed state (for views, tests and evaluations)
    @property
    def x_hat(self) -> np.ndarray:
        """(6,) the IOTSEKF's blended estimate of [q, q_dot, dP/P_s, r, r', r'']."""
        return self.st[self._k.S_XHAT:self._k.S_XHAT + 6]

    @property
    def f(self) -> float:
        """The IOTSEKF's input-fault estimate (valve units)."""
        return float(self.st[self._k.S_F])

    @property
    def Px(self) -> np.ndarray:
        """(6, 6) its covariance."""
        return self.st[self._k.S_PX:self._k.S_PX + 36].reshape(6, 6)

    @property
    def x_nom(self) -> np.ndarray:
        """(6,) the RTS-EKF's nominal servo."""
        return self.st[self._k.S_XNOM:self._k.S_XNOM + 6]

    @property
    def P_nom(self) -> np.ndarray:
        """(6, 6) its covariance."""
        return self.st[self._k.S_PNOM:self._k.S_PNOM + 36].reshape(6, 6)

    @property
    def f_out(self) -> np.ndarray:
        """(2,) the RTS-EKF's output faults of the rod and surface sensors (m of rod)."""
        return self.st[self._k.S_FOUT:self._k.S_FOUT + 2]

    @property
    def q_com(self) -> float:
        """The rod command of the last sample (m)."""
        return float(self.st[self._k.S_QCOM])


class ServoFilterBank:
    """The filters of ``n`` surfaces with the same servo, stepped together: their packed
    states are the rows of one (n, N_STATE) array and one kernel call
    (``_servo_filters_jit.surfaces_step``) runs :meth:`ServoFilters.step` of each, in order.

    ``filters[k]`` is surface ``k``'s :class:`ServoFilters` (start, views of its state)."""

    def __init__(self, n: int, servo: ServoParams, loop: ServoLoopParams, sensors: ServoSensors,
                 cfg: ServoFilterConfig) -> None:
        self._k = k = load_kernels(_KERNEL)
        self.states = np.zeros((n, k.N_STATE))
        self.filters = [ServoFilters(servo, loop, sensors, cfg, state=self.states[i])
                        for i in range(n)]
        self._prm = self.filters[0].prm
        self._cfgv = self.filters[0]._cfgv

    def freeze_lead(self, k: int, frozen: bool) -> None:
        """Surface ``k``'s samples teach the command timing nothing while ``frozen`` (the
        surface in alarm: a fault moves the rod away from every candidate)."""
        self.states[k, self._k.S_LFREEZE] = 1.0 if frozen else 0.0

    def step(self, dt_s: float, cmd_rad: np.ndarray, y_rod_m: np.ndarray,
             y_surf_rad: np.ndarray, out: np.ndarray) -> int:
        """One SURF interval of every surface (samples (n,), output rows ``out`` (n, N_OUT)):
        -1, or the index of the first surface with a numerical failure (it and the surfaces
        after it keep their previous state; the caller restarts them)."""
        return int(self._k.surfaces_step(self.states, dt_s, cmd_rad, y_rod_m, y_surf_rad,
                                         self._prm, self._cfgv, out))
