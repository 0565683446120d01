"""The simulated aircraft: 6-DOF round-rotating-earth dynamics, Lu2017 servos, wind, autopilot.

``Simulation.step()`` advances ``dt_s`` (RK4, one step per ``dt_s``; default 10 ms = 100 Hz) and
returns the :class:`TrueState` at the new time. Per step:

1. the autopilot computes surface and throttle commands from ``feedback(state)`` (or the state),
2. the three servos integrate over the step (Lu2017 model, faults applied),
3. turbulence advances one sample (body axes, rotated with the attitude at the step start),
4. the rigid body integrates with surfaces and wind varying linearly between the step's ends,
5. outputs (specific force, air data) are evaluated at the new state with the end-of-step inputs.

Altitude is geometric above the sphere; the atmosphere is ISA standard day, so the pressure
altitude equals the geometric altitude (no temperature/pressure offsets).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gcs_monitor.core import atmosphere as atm
from gcs_monitor.core import constants as c
from gcs_monitor.core.kernels import load_kernels
from gcs_monitor.core.units import DEG2RAD
from sim_vehicle.actuators.faults import ActuatorFault, effectiveness
from sim_vehicle.actuators.servo_bank import ActuatorGeometry, ServoBank
from sim_vehicle.autopilot.loops import Autopilot, Feedback
from sim_vehicle.autopilot.manoeuvres import ManoeuvreScript, ManoeuvreSpec
from sim_vehicle.autopilot.trim import Trim, trim_level
from sim_vehicle.dynamics.airframe import Airframe, load_airframe
from sim_vehicle.dynamics.rigid_body import RigidBody, dcm_from_quat_fast, gravity_fast
from sim_vehicle.environment.wind import WindField
from sim_vehicle.state import TrueState


@dataclass(frozen=True, slots=True)
class InitialCondition:
    lat_deg: float = 52.0
    lon_deg: float = 4.4
    alt_m: float = 1000.0
    tas_mps: float | None = None  # None = the airframe's default trim speed
    heading_deg: float = 0.0


@dataclass(frozen=True, slots=True)
class WindConfig:
    kind: str = "calm"  # "calm" | "constant" | "shear" | "turbulence" | "shear+turbulence"
    mean_ned_mps: tuple[float, float, float] = (0.0, 0.0, 0.0)
    turbulence_sigma_mps: float = 3.54  # Lu2016 sec. 2.2.1
    turbulence_scale_m: float = 530.0  # Lu2016 sec. 2.2.1
    shear_start_s: float = 15.0
    shear_amplitude_mps: float = 10.0


@dataclass(frozen=True, slots=True)
class ManoeuvreConfig:
    kind: str = "level"  # see sim_vehicle.autopilot.manoeuvres for kinds and defaults
    start_s: float = 10.0
    amplitude: float = 0.0  # SI, meaning per kind; 0 = the kind's documented default
    surface: str = "elevator"
    period_s: float = 0.0  # 0 = documented default
    repeat: bool = False


def euler_from_quat(q0: float, q1: float, q2: float, q3: float) -> tuple[float, float, float]:
    """ZYX Euler angles of q_ned_frd (same convention as gcs_monitor.core.frames.euler_from_dcm)."""
    phi = math.atan2(2.0 * (q2 * q3 + q0 * q1), 1.0 - 2.0 * (q1 * q1 + q2 * q2))
    s = 2.0 * (q1 * q3 - q0 * q2)
    theta = -math.asin(max(-1.0, min(1.0, s)))
    psi = math.atan2(2.0 * (q1 * q2 + q0 * q3), 1.0 - 2.0 * (q2 * q2 + q3 * q3))
    return phi, theta, psi


def _feedback(
    alt: float, vn: float, ve: float, vd: float, tas: float, p_static: float, oat: float,
    phi: float, theta: float, psi: float, p: float, q: float, r: float, beta: float,
    acc_z: float,
) -> Feedback:
    gs = math.sqrt(vn**2 + ve**2 + vd**2)
    gamma = math.asin(max(-1.0, min(1.0, -vd / gs))) if gs > 0.0 else 0.0
    return Feedback(
        alt_m=alt, vd_mps=vd, tas_mps=tas, rho_kgpm3=p_static / (c.ISA_R_JPKGK * oat),
        phi=phi, theta=theta, psi=psi, p=p, q=q, r=r, beta=beta, acc_z_mps2=acc_z,
        gamma_rad=gamma,
    )


class Simulation:
    """Fixed-step simulation of one aircraft (see module docstring)."""

    def __init__(
        self,
        airframe: str,
        init: InitialCondition = InitialCondition(),
        wind: WindConfig = WindConfig(),
        manoeuvre: ManoeuvreConfig = ManoeuvreConfig(),
        *,
        actuator_faults: Sequence[ActuatorFault] = (),
        seed: int = 0,
        dt_s: float = 0.01,
        feedback: Callable[[TrueState], TrueState] | None = None,
    ) -> None:
        self.airframe: Airframe = load_airframe(
            Path(airframe) if airframe.endswith(".toml") else airframe
        )
        self.body = RigidBody(self.airframe)
        self.dt_s = float(dt_s)
        self.t_s = 0.0
        self.feedback = feedback
        self.rng = np.random.default_rng(seed)
        lat = init.lat_deg * DEG2RAD
        lon = init.lon_deg * DEG2RAD
        hdg = init.heading_deg * DEG2RAD
        tas = init.tas_mps if init.tas_mps is not None else self.airframe.default_tas_mps
        self.wind = WindField(
            wind.kind,
            wind.mean_ned_mps,
            sigma_mps=wind.turbulence_sigma_mps,
            scale_m=wind.turbulence_scale_m,
            shear_start_s=wind.shear_start_s,
            shear_amplitude_mps=wind.shear_amplitude_mps,
            shear_heading_rad=hdg,
            dt_s=self.dt_s,
            rng=self.rng,
        )
        mean = self.wind.mean
        self.trim: Trim = trim_level(self.body, lat, lon, init.alt_m, tas, hdg, mean)
        self.x = list(self.trim.state)
        self._rbj = rbj = load_kernels("sim_vehicle.dynamics._rigid_body_jit")
        self._prm = rbj.pack_params(self.body)
        act = self.airframe.actuators
        # aerodynamic / thrust effectiveness of the aileron, elevator, rudder, engine (faults)
        self._act_faults = tuple(actuator_faults)
        self._eff_faulted = tuple(
            any(f.surface == i and f.kind in ("loss_of_effectiveness", "engine_out")
                for f in self._act_faults) for i in range(4))
        self._eff = [1.0, 1.0, 1.0, 1.0]
        self.servos = ServoBank(
            ActuatorGeometry(act.rod_gain_radpm, act.rod_stroke_m),
            (0.0, self.trim.elevator_rad, 0.0),
            faults=actuator_faults,
        )
        self.autopilot = Autopilot(self.airframe, self.trim, gravity_fast(lat, init.alt_m))
        self.manoeuvre = ManoeuvreScript(
            ManoeuvreSpec(
                manoeuvre.kind,
                manoeuvre.start_s,
                manoeuvre.amplitude,
                manoeuvre.surface,
                manoeuvre.period_s,
                manoeuvre.repeat,
            ),
            self.airframe.autopilot,
            init.alt_m,
            tas,
            hdg,
        )
        # Turbulence sample for t = 0 (stationary start); the wind at the step ends is cached.
        self.wind.advance_turbulence(tas)
        self._wind_now = self.wind.wind_ned(0.0, dcm_from_quat_fast(*self.x[6:10]))
        self._thr_cmd = self.trim.throttle
        self._xa = np.array(self.x)
        self._deriv = np.empty(len(self.x))
        out = np.empty(rbj.N_OUT)
        rbj.evaluate(self._xa, np.array((*self._surf(), self._thr_cmd, *self._wind_now)),
                     self._prm, self._deriv, out)
        self._state = self._make_state(out.tolist())

    # ------------------------------------------------------------------ helpers
    def _surf(self) -> tuple[float, float, float]:
        """The deflections the aerodynamics sees: the surfaces' positions times their
        effectiveness (a surface that lost part of its effect still moves as commanded)."""
        s = self.servos
        e = self._eff
        return (e[0] * s.deflection_rad(0), e[1] * s.deflection_rad(1),
                e[2] * s.deflection_rad(2))

    def _update_effectiveness(self, t_s: float) -> None:
        for i, faulted in enumerate(self._eff_faulted):
            if faulted:
                self._eff[i] = effectiveness(self._act_faults, i, t_s)

    def _make_state(self, out: list[float]) -> TrueState:
        """The published state from ``self.x`` and the outputs of ``RigidBody.evaluate``.

        Also caches the autopilot's :class:`Feedback` of that state (``self._fb``), built from
        the same floats as :meth:`_feedback_of` would take from it.
        """
        sp = self.autopilot.setpoints
        x = self.x
        s = self.servos
        da, de, dr = s.deflection_rad(0), s.deflection_rad(1), s.deflection_rad(2)
        ax, ay, az, tas, alpha, beta, _rho, _thrust = out
        h = x[2]
        phi, theta, psi = euler_from_quat(x[6], x[7], x[8], x[9])
        p_static = atm.isa_pressure_pa(h)
        oat = atm.isa_temperature_k(h)
        self._fb = _feedback(
            h, x[3], x[4], x[5], tas, p_static, oat, phi, theta, psi, x[10], x[11], x[12],
            beta, az,
        )
        return TrueState(
            t_s=self.t_s,
            lat_rad=x[0],
            lon_rad=x[1],
            alt_m=h,
            vel_ned_mps=np.array(x[3:6]),
            euler_rad=np.array((phi, theta, psi)),
            omega_frd_radps=np.array(x[10:13]),
            acc_frd_mps2=np.array((ax, ay, az)),
            wind_ned_mps=np.array(self._wind_now),
            tas_mps=tas,
            aoa_rad=alpha,
            ssa_rad=beta,
            pressure_alt_m=h,
            static_pressure_pa=p_static,
            oat_k=oat,
            cas_mps=atm.cas_from_tas(tas, h),
            surf_cmd_rad=np.array(s.cmd_rad),
            surf_pos_rad=np.array((da, de, dr)),
            rod_pos_m=np.array((s.rod_sensor_m(0), s.rod_sensor_m(1), s.rod_sensor_m(2))),
            throttle=x[13],
            throttle_cmd=self._thr_cmd,
            att_cmd_rad=np.array((sp.phi_rad, sp.theta_rad, sp.psi_rad)),
            rate_cmd_radps=np.array((sp.p_radps, sp.q_radps, sp.r_radps)),
            alt_cmd_m=sp.alt_m,
            tas_cmd_mps=sp.tas_mps,
            effectiveness=np.array(self._eff),
        )

    @staticmethod
    def _feedback_of(st: TrueState) -> Feedback:
        """The autopilot's inputs taken from a (possibly corrupted) state."""
        v = st.vel_ned_mps
        e = st.euler_rad
        w = st.omega_frd_radps
        return _feedback(
            st.alt_m, float(v[0]), float(v[1]), float(v[2]), st.tas_mps, st.static_pressure_pa,
            st.oat_k, float(e[0]), float(e[1]), float(e[2]), float(w[0]), float(w[1]),
            float(w[2]), st.ssa_rad, float(st.acc_frd_mps2[2]),
        )

    # ------------------------------------------------------------------ public API
    def state(self) -> TrueState:
        """Current state without stepping."""
        return self._state

    def step(self) -> TrueState:
        """Advance ``dt_s``; return the state at the new time."""
        dt = self.dt_s
        fb = self._fb if self.feedback is None else self._feedback_of(self.feedback(self._state))
        tg = self.manoeuvre.targets(self.t_s, fb)
        da, de, dr, thr = self.autopilot.update(fb, tg, dt)
        self._thr_cmd = thr
        s0 = self._surf()
        self._update_effectiveness(self.t_s)
        self.servos.step(self.t_s, dt, (da, de, dr))
        s1 = self._surf()
        w0 = self._wind_now
        self.wind.advance_turbulence(self._state.tas_mps)
        w1 = self.wind.wind_ned(self.t_s + dt, dcm_from_quat_fast(*self.x[6:10]))
        # The derivative evaluated for the published state is this step's k1 (same state, surfaces
        # and wind); only the engine-lag term depends on the new throttle command. The kernel
        # is the RK4 step followed by ``evaluate`` at the new state.
        k1 = self._deriv
        rbj = self._rbj
        xa = np.empty(rbj.N_STATE)
        deriv = np.empty(rbj.N_STATE)
        out = np.empty(rbj.N_OUT)
        thr_eff = self._eff[3] * thr  # engine faults: the thrust the throttle still gets
        k1[13] = (thr_eff - self.x[13]) / self.body.tau_engine_s
        rbj.step(self._xa, dt, np.array((*s0, thr_eff, *w0, *s1, thr_eff, *w1)), k1, self._prm,
                 xa, deriv, out)
        self._xa = xa
        self._deriv = deriv
        self.x = self._xa.tolist()
        self.t_s += dt
        self._wind_now = w1
        self._state = self._make_state(out.tolist())
        return self._state
