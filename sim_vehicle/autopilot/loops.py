"""Autopilot: documented PID-style loops, gain-scheduled on dynamic pressure.

Longitudinal
  altitude -> climb-rate command  ``hdot_c = sat(w_h (h_c - h), +-max_climb)``
  climb rate -> pitch command     ``theta_c = theta_b + asin(hdot_c/V) + (hdot_c - hdot)/V``,
                                  ``theta_b' = k_i (hdot_c - hdot)/V`` (integral)
  or load factor (zero-g)         ``q_c = (g/V)[(n_c - cos(gamma)) + 3 (n_c - n)]``
  pitch -> pitch-rate command     ``q_c = w_theta [e + (w_theta/5) int e] + q_turn``,
                                  e = theta_c - theta
  pitch rate -> elevator          ``de = de_trim + K_q (q_c - q)``,
                                  ``K_q = J_y w_q / (qbar S c Cm_de)`` (model-scaled PI)
  airspeed -> throttle            ``dt = dt_trim + k_p (V_c - V) + k_i int (V_c - V)``
Lateral-directional
  heading -> bank command         ``phi_c = atan(w_psi wrap(psi_c - psi) V / g)``, saturated
  bank -> roll-rate command       ``p_c = sat(w_phi [e + (w_phi/5) int e], 0.7 p_max)``,
                                  e = phi_c - phi,
                                  p_max = |Cl_da da_max / Cl_p| 2V/b (integral frozen when limited)
  roll rate -> aileron            ``da = K_p (p_c - p) - (Cl_p p + Cl_r r) b/(2V) / Cl_da``,
                                  ``K_p = J_x w_p/(qbar S b Cl_da)``
  sideslip -> yaw-rate command    ``r_c = g sin(phi) cos(theta)/V + k_beta (beta - beta_c)``
  yaw rate -> rudder              ``dr = K_r [(r_c - r) + (w_r/5) int (r_c - r)]``,
                                  ``K_r = J_z w_r/(qbar S b Cn_dr)``

Bandwidths ``w_*`` and limits come from the airframe file's ``[autopilot]`` table
(``altitude_ki`` is k_i above, 1/s). Dividing by the control derivative makes the loop signs
follow the airframe's own sign conventions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sim_vehicle.autopilot.trim import Trim
from sim_vehicle.dynamics.airframe import Airframe

INTEGRAL_RATIO = 0.2  # integral corner of the yaw-rate loop as a fraction of its bandwidth
ROLL_RATE_MARGIN = 0.7  # fraction of the full-aileron steady roll rate the loop may ask for
INTEGRAL_ZONE_RAD = 0.05  # attitude integrators run only within this error
ATT_INTEGRAL_RATIO = 0.2  # integral corner of the attitude loops as a fraction of their bandwidth
MIN_QBAR_PA = 1.0
LOAD_FACTOR_GAIN = 3.0  # feedback on the n_z error, in units of the feed-forward g/V


@dataclass(frozen=True, slots=True)
class Targets:
    """What the manoeuvre asks of the autopilot at one instant (SI)."""

    alt_m: float
    tas_mps: float
    heading_rad: float
    bank_rad: float | None = None  # None: heading hold
    beta_rad: float = 0.0
    load_factor: float | None = None  # not None: track this n_z instead of altitude
    surface_offset_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True, slots=True)
class Feedback:
    """The autopilot's inputs (taken from a TrueState, possibly corrupted by ``feedback``)."""

    alt_m: float
    vd_mps: float
    tas_mps: float
    rho_kgpm3: float
    phi: float
    theta: float
    psi: float
    p: float
    q: float
    r: float
    beta: float
    acc_z_mps2: float
    gamma_rad: float


@dataclass(frozen=True, slots=True)
class Setpoints:
    """What the loops commanded on their last step (SI; published as NAV_CONTROLLER_OUTPUT and
    ATTITUDE_TARGET): attitude, body rates, heading, and the altitude and airspeed targets."""

    phi_rad: float = 0.0
    theta_rad: float = 0.0
    psi_rad: float = 0.0
    p_radps: float = 0.0
    q_radps: float = 0.0
    r_radps: float = 0.0
    alt_m: float = 0.0
    tas_mps: float = 0.0
    throttle: float = 0.0


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def _sat(x: float, lim: float) -> float:
    return lim if x > lim else (-lim if x < -lim else x)


class Autopilot:
    def __init__(self, af: Airframe, trim: Trim, g_mps2: float) -> None:
        self.af = af
        self.gains = af.autopilot
        self.trim = trim
        self.g = g_mps2
        self.theta_b = trim.alpha_rad
        self.int_q = 0.0
        self.int_p = 0.0
        self.int_r = 0.0
        self.int_v = 0.0
        self.de_trim = trim.elevator_rad
        self.thr_trim = trim.throttle
        self.setpoints = Setpoints(theta_rad=trim.alpha_rad, throttle=trim.throttle)

    def update(self, fb: Feedback, tg: Targets, dt_s: float) -> tuple[float, float, float, float]:
        """One autopilot step: returns (aileron, elevator, rudder) rad and throttle (0..1)."""
        gn = self.gains
        af = self.af
        a = af.aero
        geo = af.geometry
        m = af.mass
        v = max(fb.tas_mps, 1.0)
        qbar_s = max(0.5 * fb.rho_kgpm3 * v * v, MIN_QBAR_PA) * geo.wing_area_m2
        g = self.g
        # --- longitudinal
        turn_q = g * math.sin(fb.phi) * math.tan(fb.phi) * math.cos(fb.theta) / v
        hdot = -fb.vd_mps
        if tg.load_factor is None:
            hdot_c = _sat(gn.altitude_bw_radps * (tg.alt_m - fb.alt_m), gn.max_climb_mps)
            err = (hdot_c - hdot) / v
            self.theta_b += dt_s * gn.altitude_ki * err
            self.theta_b = _sat(self.theta_b, gn.max_pitch_rad)
            theta_c = _sat(self.theta_b + math.asin(_sat(hdot_c / v, 0.5)) + err, gn.max_pitch_rad)
            eth = theta_c - fb.theta
            if abs(eth) < INTEGRAL_ZONE_RAD:
                self.int_q += dt_s * eth  # anti-windup: only near the target
            q_c = (
                gn.attitude_bw_radps
                * (eth + ATT_INTEGRAL_RATIO * gn.attitude_bw_radps * self.int_q)
                + turn_q
            )
        else:
            theta_c = fb.theta  # load-factor tracking: no pitch-attitude setpoint
            n = -fb.acc_z_mps2 / g
            q_c = (g / v) * (
                (tg.load_factor - math.cos(fb.gamma_rad)) + LOAD_FACTOR_GAIN * (tg.load_factor - n)
            )
            self.theta_b = (
                fb.theta - fb.gamma_rad
            )  # keep the altitude loop aligned for the hand-back
        wq = gn.rate_bw_radps
        kq = m.jy_kgm2 * wq / (qbar_s * geo.chord_m * a.cm_de)
        de = self.de_trim + kq * (q_c - fb.q)
        de = _sat(de + tg.surface_offset_rad[1], af.actuators.max_deflection_rad[1])
        # --- speed
        ev = tg.tas_mps - fb.tas_mps
        thr = self.thr_trim + gn.speed_kp_per_mps * ev + self.int_v
        if 0.0 < thr < 1.0 or (thr >= 1.0 and ev < 0.0) or (thr <= 0.0 and ev > 0.0):
            self.int_v += dt_s * gn.speed_ki_per_mps_s * ev
        thr = min(1.0, max(0.0, thr))
        # --- lateral
        if tg.bank_rad is None:
            psidot_c = gn.heading_bw_radps * _wrap(tg.heading_rad - fb.psi)
            phi_c = math.atan(psidot_c * v / g)
            psi_c = tg.heading_rad
        else:
            phi_c = tg.bank_rad
            psi_c = fb.psi
        phi_c = _sat(phi_c, gn.max_bank_rad)
        wp = gn.rate_bw_radps
        eph = phi_c - fb.phi
        p_c = gn.attitude_bw_radps * (eph + ATT_INTEGRAL_RATIO * gn.attitude_bw_radps * self.int_p)
        # Achievable steady roll rate with full aileron: p_max = |Cl_da da_max / Cl_p| 2V/b.
        lim_a = af.actuators.max_deflection_rad[0]
        p_max = ROLL_RATE_MARGIN * abs(a.croll_da * lim_a / a.croll_p) * 2.0 * v / geo.span_m
        if abs(p_c) < p_max and abs(eph) < INTEGRAL_ZONE_RAD:
            self.int_p += dt_s * eph  # anti-windup: only near the target and when not rate-limited
        p_c = _sat(p_c, p_max)
        kp = m.jx_kgm2 * wp / (qbar_s * geo.span_m * a.croll_da)
        # Feed-forward cancelling the rate-dependent rolling moment (Cl_p p + Cl_r r), which
        # otherwise leaves a bank error in steady turns.
        da_ff = -(a.croll_p * fb.p + a.croll_r * fb.r) * geo.span_m / (2.0 * v) / a.croll_da
        da = _sat(
            kp * (p_c - fb.p) + da_ff + tg.surface_offset_rad[0], af.actuators.max_deflection_rad[0]
        )
        r_c = g * math.sin(fb.phi) * math.cos(fb.theta) / v + gn.beta_gain * (fb.beta - tg.beta_rad)
        kr = m.jz_kgm2 * wp / (qbar_s * geo.span_m * a.cn_dr)
        er = r_c - fb.r
        dr = kr * (er + INTEGRAL_RATIO * wp * self.int_r)
        lim_r = af.actuators.max_deflection_rad[2]
        if abs(dr) < lim_r:
            self.int_r += dt_s * er
        dr = _sat(dr + tg.surface_offset_rad[2], lim_r)
        self.setpoints = Setpoints(phi_c, theta_c, psi_c, p_c, q_c, r_c,
                                   tg.alt_m if tg.load_factor is None else fb.alt_m,
                                   tg.tas_mps, thr)
        return da, de, dr, thr
