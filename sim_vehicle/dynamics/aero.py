"""Aerodynamic and propulsive forces and moments, body FRD (coefficients from the airframe file).

Force model (Beard & McLain 2012 eqs. 4.6-4.15 structure, linear derivatives):

* ``CL = CL0 + CL_alpha alpha + (CL_q + CL_alphadot) c q / (2V) + CL_de de``, optionally blended
  into a flat plate beyond ``alpha0`` (Beard eq. 4.9),
* ``CD = CD0 + CD_alpha alpha + CD_de |de| + (CL - CL_mindrag)^2 / (pi e AR)``
  (e = 0: no induced term),
* ``X = qbar S (-CD cos(alpha) + CL sin(alpha))``, ``Z = qbar S (-CD sin(alpha) - CL cos(alpha))``,
  ``Y = qbar S CY(beta, p, r, da, dr)``, moments ``qbar S (b Cl, c Cm, b Cn)``.

The alpha-dot derivatives (Roskam) are folded into the q derivatives (alpha_dot ~ q in the
short-period mode): a documented approximation that keeps the model explicit.
Thrust acts along body x through the centre of gravity.
"""

from __future__ import annotations

import math
from typing import cast

from sim_vehicle.dynamics.airframe import Airframe


class AeroModel:
    """Evaluates forces/moments with plain floats (it runs inside RK4)."""

    def __init__(self, af: Airframe) -> None:
        a = af.aero
        g = af.geometry
        self.S = g.wing_area_m2
        self.b = g.span_m
        self.c = g.chord_m
        ar = g.span_m**2 / g.wing_area_m2
        self.k_ind = 1.0 / (math.pi * a.oswald_e * ar) if a.oswald_e > 0.0 else 0.0
        self.coef = a
        self.cl_q_eff = a.cl_q + a.cl_alphadot
        self.cm_q_eff = a.cm_q + a.cm_alphadot
        self.blend = a.stall_blend_m > 0.0
        pr = af.propulsion
        self.prop = pr
        self.jet = pr.model == "jet"
        if pr.model not in ("jet", "prop"):
            raise ValueError(f"unknown propulsion model {pr.model!r}")

    def lift_coeff(self, alpha: float, qhat: float, de: float) -> float:
        a = self.coef
        lin = a.cl0 + a.cl_alpha * alpha
        if self.blend:
            m = a.stall_blend_m
            a0 = a.stall_alpha0_rad
            e1 = math.exp(-m * (alpha - a0))
            e2 = math.exp(m * (alpha + a0))
            sig = (1.0 + e1 + e2) / ((1.0 + e1) * (1.0 + e2))
            sa = math.sin(alpha)
            flat = 2.0 * math.copysign(1.0, alpha) * sa * sa * math.cos(alpha)
            lin = (1.0 - sig) * lin + sig * flat
        return lin + self.cl_q_eff * qhat + a.cl_de * de

    def thrust_n(
        self, throttle: float, tas_mps: float, rho_kgpm3: float, rho0_kgpm3: float
    ) -> float:
        pr = self.prop
        if self.jet:
            return cast(float, throttle * pr.max_thrust_n
                        * (rho_kgpm3 / rho0_kgpm3) ** pr.density_exponent)
        k = pr.k_motor_mps * throttle
        return 0.5 * rho_kgpm3 * pr.s_prop_m2 * pr.c_prop * (k * k - tas_mps * tas_mps)

    def forces_moments(
        self,
        u: float,
        v: float,
        w: float,
        p: float,
        q: float,
        r: float,
        da: float,
        de: float,
        dr: float,
        rho: float,
    ) -> tuple[float, float, float, float, float, float]:
        """Aerodynamic force (N) and moment (N m) in FRD from body air velocity (u, v, w) m/s."""
        a = self.coef
        tas = math.sqrt(u * u + v * v + w * w)
        if tas < 1.0e-3:
            return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        alpha = math.atan2(w, u)
        beta = math.asin(v / tas)
        qbar_s = 0.5 * rho * tas * tas * self.S
        half_inv_v = 0.5 / tas
        qhat = self.c * q * half_inv_v
        phat = self.b * p * half_inv_v
        rhat = self.b * r * half_inv_v
        cl = self.lift_coeff(alpha, qhat, de)
        dcl = cl - a.cl_mindrag
        cd = a.cd0 + a.cd_alpha * alpha + a.cd_de * abs(de) + self.k_ind * dcl * dcl
        ca = math.cos(alpha)
        sa = math.sin(alpha)
        fx = qbar_s * (-cd * ca + cl * sa)
        fz = qbar_s * (-cd * sa - cl * ca)
        fy = qbar_s * (
            a.cy_beta * beta + a.cy_p * phat + a.cy_r * rhat + a.cy_da * da + a.cy_dr * dr
        )
        ml = (
            qbar_s
            * self.b
            * (
                a.croll_beta * beta
                + a.croll_p * phat
                + a.croll_r * rhat
                + a.croll_da * da
                + a.croll_dr * dr
            )
        )
        mm = qbar_s * self.c * (a.cm0 + a.cm_alpha * alpha + self.cm_q_eff * qhat + a.cm_de * de)
        mn = (
            qbar_s
            * self.b
            * (a.cn_beta * beta + a.cn_p * phat + a.cn_r * rhat + a.cn_da * da + a.cn_dr * dr)
        )
        return fx, fy, fz, ml, mm, mn
