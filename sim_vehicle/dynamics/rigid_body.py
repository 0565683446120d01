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

Everything is plain-float Python and serves as the reference (trim, tests); the simulation
loop runs the numba twin in ``_rigid_body_jit`` (same equations, same operation order,
checked to 1e-12 by a test).
"""

from __future__ import annotations

import math
from typing import cast

from gcs_monitor.core import constants as k
from sim_vehicle.dynamics.aero import AeroModel
from sim_vehicle.dynamics.airframe import Airframe

N_STATE = 14
_GAS_EXP = -k.GRAVITY_STD_MPS2 / (k.ISA_R_JPKGK * k.ISA_LAPSE_KPM)


def isa_density_fast(h_m: float) -> float:
    """ISA troposphere density (same as gcs_monitor.core.atmosphere.isa_density_kgpm3)."""
    t = k.ISA_T0_K + k.ISA_LAPSE_KPM * h_m
    return cast(float, k.ISA_P0_PA * (t / k.ISA_T0_K) ** _GAS_EXP / (k.ISA_R_JPKGK * t))


def gravity_fast(lat: float, h: float) -> float:
    """Lu2016 eq. 12 (same as gcs_monitor.core.atmosphere.gravity_mps2)."""
    s = math.sin(lat)
    s2 = math.sin(2.0 * lat)
    ratio = k.EARTH_RADIUS_M / (k.EARTH_RADIUS_M + h)
    return (
        k.GRAVITY_EQUATOR_MPS2
        * ratio
        * ratio
        * (1.0 + k.GRAVITY_LAT_K1 * s * s - k.GRAVITY_LAT_K2 * s2 * s2)
    )


def dcm_from_quat_fast(q0: float, q1: float, q2: float, q3: float) -> tuple[float, ...]:
    """Row-major C_ned_frd of a unit quaternion (as gcs_monitor.core.frames.dcm_from_quat)."""
    return (
        1.0 - 2.0 * (q2 * q2 + q3 * q3),
        2.0 * (q1 * q2 - q0 * q3),
        2.0 * (q1 * q3 + q0 * q2),
        2.0 * (q1 * q2 + q0 * q3),
        1.0 - 2.0 * (q1 * q1 + q3 * q3),
        2.0 * (q2 * q3 - q0 * q1),
        2.0 * (q1 * q3 - q0 * q2),
        2.0 * (q2 * q3 + q0 * q1),
        1.0 - 2.0 * (q1 * q1 + q2 * q2),
    )


class RigidBody:
    """Equations of motion of one airframe; :meth:`deriv` is the RK4 right-hand side."""

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
        """State derivative and outputs.

        Returns
        -------
        deriv : (14,) list
        out : (f_x, f_y, f_z, tas, alpha, beta, rho, thrust) specific force FRD (m/s^2), air data
        """
        lat, _lon, h, vn, ve, vd, q0, q1, q2, q3, p, q, r, thr = s
        c00, c01, c02, c10, c11, c12, c20, c21, c22 = dcm_from_quat_fast(q0, q1, q2, q3)
        # air velocity in body axes
        an, ae, ad = vn - wn, ve - we, vd - wd
        u = c00 * an + c10 * ae + c20 * ad
        v = c01 * an + c11 * ae + c21 * ad
        w = c02 * an + c12 * ae + c22 * ad
        rho = isa_density_fast(h)
        fx, fy, fz, ml, mm, mn = self.aero.forces_moments(u, v, w, p, q, r, da, de, dr, rho)
        tas = math.sqrt(u * u + v * v + w * w)
        thrust = self.aero.thrust_n(thr, tas, rho, k.ISA_RHO0_KGPM3)
        inv_m = 1.0 / self.mass_kg
        ax = (fx + thrust) * inv_m
        ay = fy * inv_m
        az = fz * inv_m
        # specific force to NED
        fn = c00 * ax + c01 * ay + c02 * az
        fe = c10 * ax + c11 * ay + c12 * az
        fd = c20 * ax + c21 * ay + c22 * az
        rh = k.EARTH_RADIUS_M + h
        om = k.EARTH_RATE_RADPS
        sl = math.sin(lat)
        cl = math.cos(lat)
        tl = sl / cl
        g = gravity_fast(lat, h)
        # Lu2016 eq. 11 rows 1-3
        vn_d = fn + vn * vd / rh - ve * ve * tl / rh - 2.0 * om * ve * sl
        ve_d = fe + vn * ve * tl / rh + ve * vd / rh + 2.0 * om * (vn * sl + vd * cl)
        vd_d = fd - vn * vn / rh - ve * ve / rh - 2.0 * om * ve * cl + g
        # omega_in (earth rate + transport rate), NED, then body
        win = ve / rh + om * cl
        wie = -vn / rh
        wid = -ve * tl / rh - om * sl
        pb = p - (c00 * win + c10 * wie + c20 * wid)
        qb = q - (c01 * win + c11 * wie + c21 * wid)
        rb = r - (c02 * win + c12 * wie + c22 * wid)
        q0d = 0.5 * (-q1 * pb - q2 * qb - q3 * rb)
        q1d = 0.5 * (q0 * pb + q2 * rb - q3 * qb)
        q2d = 0.5 * (q0 * qb - q1 * rb + q3 * pb)
        q3d = 0.5 * (q0 * rb + q1 * qb - q2 * pb)
        # Euler's equations (Beard eq. 3.17)
        pd = self.g1 * p * q - self.g2 * q * r + self.g3 * ml + self.g4 * mn
        qd = self.g5 * p * r - self.g6 * (p * p - r * r) + mm / self.jy
        rd = self.g7 * p * q - self.g1 * q * r + self.g4 * ml + self.g8 * mn
        thr_d = (thr_cmd - thr) / self.tau_engine_s
        deriv = [
            vn / rh,
            ve / (rh * cl),
            -vd,
            vn_d,
            ve_d,
            vd_d,
            q0d,
            q1d,
            q2d,
            q3d,
            pd,
            qd,
            rd,
            thr_d,
        ]
        alpha = math.atan2(w, u)
        beta = math.asin(max(-1.0, min(1.0, v / tas))) if tas > 0.0 else 0.0
        return deriv, (ax, ay, az, tas, alpha, beta, rho, thrust)


def rk4_step(
    body: RigidBody,
    s: list[float],
    dt_s: float,
    inp0: tuple[float, ...],
    inp1: tuple[float, ...],
    k1: list[float] | None = None,
) -> list[float]:
    """One classical RK4 step; inputs (da, de, dr, thr_cmd, wn, we, wd) vary linearly inp0->inp1.

    Linear interpolation of the surfaces and the wind keeps the specific force continuous
    across steps, so a trapezoidal re-integration of the published samples is O(dt^2) exact.
    ``k1`` may pass the derivative at (s, inp0) when the caller already has it.
    """
    mid = tuple(0.5 * (a + b) for a, b in zip(inp0, inp1, strict=True))
    ev = body.evaluate
    if k1 is None:
        k1, _ = ev(s, *inp0)
    h = 0.5 * dt_s
    s2 = [x + h * d for x, d in zip(s, k1, strict=True)]
    k2, _ = ev(s2, *mid)
    s3 = [x + h * d for x, d in zip(s, k2, strict=True)]
    k3, _ = ev(s3, *mid)
    s4 = [x + dt_s * d for x, d in zip(s, k3, strict=True)]
    k4, _ = ev(s4, *inp1)
    d6 = dt_s / 6.0
    out = [
        x + d6 * (a + 2.0 * (b + c) + e) for x, a, b, c, e in zip(s, k1, k2, k3, k4, strict=True)
    ]
    n = math.sqrt(out[6] ** 2 + out[7] ** 2 + out[8] ** 2 + out[9] ** 2)
    out[6] /= n
    out[7] /= n
    out[8] /= n
    out[9] /= n
    return out
