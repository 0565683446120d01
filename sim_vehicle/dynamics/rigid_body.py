"""6-DOF rigid-body fixed-wing over a spherical rotating earth.

State (14 floats): ``[lat, lon, h, v_N, v_E, v_D, q0, q1, q2, q3, p, q, r, thrust_state]``:
geodetic latitude/longitude (rad) and altitude (m) on the sphere R_e, NED ground velocity
(m/s), attitude quaternion ``q_ned_frd`` (scalar first), body rates relative to *inertial*
space (rad/s, what a gyro measures), and the engine's effective throttle (first-order lag).

Translational dynamics are the ground-speed navigation equations of Lu2016 eq. 11 rows 1-3
(transport rate + Coriolis, gravity eq. 12)::

    v_N' = f_N + v_N v_D/(R+h) - v_E^2 tan(lat)/(R+h) - 2 Omega v_E sin(lat)
    v_E' = f_E + v_N v_E tan(lat)/(R+h) + v_E v_D/(R+h) + 2 Omega (v_N sin(lat) + v_D cos(lat))
    v_D' = f_D - (v_N^2 + v_E^2)/(R+h) - 2 Omega v_E cos(lat) + g(lat, h)

with ``f_ned = C_ned_frd f_frd`` and ``f_frd = (aero + thrust)/m`` the specific force.
Attitude: ``q' = 1/2 q (x) [0, omega_nb]`` with
``omega_nb = omega_ib - C_frd_ned (omega_ie + omega_en)``,
``omega_ie^n = Omega [cos lat, 0, -sin lat]``, ``omega_en^n = [v_E, -v_N, -v_E tan lat]/(R+h)``;
the resulting Euler rates are exactly Lu2016 eq. 11 rows 4-6. Rotational dynamics: Euler's
equations with J_xz (Beard & McLain eq. 3.17, Gamma terms).

The equations run in the numba kernels of ``_rigid_body_jit.py`` (their one implementation):
:meth:`RigidBody.evaluate` wraps the derivative for the trim, the simulation loop calls the RK4
step directly (``sim_vehicle.physics``). The plain-float reference of the equivalence test is
``tests/reference/rigid_body.py``.
"""

from __future__ import annotations

import numpy as np

from gcs_monitor.core.kernels import load_kernels
from sim_vehicle.dynamics.aero import AeroModel
from sim_vehicle.dynamics.airframe import Airframe

N_STATE = 14


def gravity_fast(lat: float, h: float) -> float:
    """Lu2016 eq. 12 (same as gcs_monitor.core.atmosphere.gravity_mps2), the kernel's."""
    kern = load_kernels("sim_vehicle.dynamics._rigid_body_jit")
    return float(kern.gravity(float(lat), float(h)))


def dcm_from_quat_fast(q0: float, q1: float, q2: float, q3: float) -> tuple[float, ...]:
    """Row-major C_ned_frd of a unit quaternion (as gcs_monitor.core.frames.dcm_from_quat), the
    kernel's."""
    kern = load_kernels("sim_vehicle.dynamics._rigid_body_jit")
    return tuple(kern.dcm_from_quat(float(q0), float(q1), float(q2), float(q3)))


class RigidBody:
    """Equations of motion of one airframe: the constants of the kernels and :meth:`evaluate`."""

    def __init__(self, af: Airframe) -> None:
        self.af = af
        self.aero = AeroModel(af)
        m = af.mass
        self.mass_kg = m.mass_kg
        jx, jy, jz, jxz = m.jx_kgm2, m.jy_kgm2, m.jz_kgm2, m.jxz_kgm2
        gam = jx * jz - jxz * jxz
        # Beard & McLain eq. 3.13 Gamma terms
        self.g1 = jxz * (jx - jy + jz) / gam
        self.g2 = (jz * (jz - jy) + jxz * jxz) / gam
        self.g3 = jz / gam
        self.g4 = jxz / gam
        self.g5 = (jz - jx) / jy
        self.g6 = jxz / jy
        self.g7 = ((jx - jy) * jx + jxz * jxz) / gam
        self.g8 = jx / gam
        self.jy = jy
        self.tau_engine_s = af.propulsion.time_constant_s
        self._params: np.ndarray | None = None  # _rigid_body_jit.pack_params(self), on first use

    def evaluate(
        self,
        s: list[float],
        da: float,
        de: float,
        dr: float,
        thr_cmd: float,
        wn: float,
        we: float,
        wd: float,
    ) -> tuple[list[float], tuple[float, ...]]:
        """State derivative and outputs (the kernel ``_rigid_body_jit.evaluate``).

        Returns
        -------
        deriv : (14,) list
        out : (f_x, f_y, f_z, tas, alpha, beta, rho, thrust) specific force FRD (m/s^2), air data
        """
        kern = load_kernels("sim_vehicle.dynamics._rigid_body_jit")
        if self._params is None:
            self._params = kern.pack_params(self)
        deriv, out = np.empty(N_STATE), np.empty(kern.N_OUT)
        inp = np.array((da, de, dr, thr_cmd, wn, we, wd), dtype=np.float64)
        kern.evaluate(np.array(s, dtype=np.float64), inp, self._params, deriv, out)
        return deriv.tolist(), tuple(out.tolist())
