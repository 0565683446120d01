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
Thrust acts along body x through the centre of gravity: ``T = throttle T_max (rho / rho0)^n``
(jet) or ``T = 1/2 rho S_prop C_prop ((k_motor throttle)^2 - V^2)`` (prop, Beard & McLain ch. 4).

:class:`AeroModel` holds the airframe's derived constants; the forces are evaluated in the
rigid-body kernel (``_rigid_body_jit.evaluate``), their one implementation.
"""

from __future__ import annotations

import math

from sim_vehicle.dynamics.airframe import Airframe


class AeroModel:
    """The aerodynamic and propulsive constants of one airframe (see the module docstring)."""

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
