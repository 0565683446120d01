"""The simulator's lateral-directional dynamics linearised at trim (Chen2020 sec. V model).

:func:`lateral_lti` trims the 6-DOF rigid body (:func:`sim_vehicle.autopilot.trim.trim_level`,
wings level, calm air) and differentiates it numerically in the lateral states
``[phi, beta, p, r]`` (body rates as perturbations of the trim rates) and the aileron and rudder
deflections, with the longitudinal states, throttle and elevator held at trim. The lateral state
rates are directional derivatives of the state map along the full state derivative, so the
kinematics (Euler rates, the sideslip of the body air velocity) come from the simulator itself.
:func:`lateral_lpv` does this across a speed range and fits the LPV model of
:mod:`gcs_monitor.models.lateral` (Chen2020 eq. 59).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gcs_monitor.core.frames import dcm_ned_frd, quat_from_euler
from gcs_monitor.core.types import Mat, Vec
from gcs_monitor.models.lateral import (
    N_U,
    N_X,
    LateralLpv,
    LpvFitError,
    eas_from_tas,
    fit_lpv,
)
from sim_vehicle.autopilot.trim import Trim, trim_level
from sim_vehicle.dynamics.airframe import load_airframe
from sim_vehicle.dynamics.rigid_body import RigidBody, dcm_from_quat_fast

LAT_DEG = 52.0  # the scenarios' default position (physics.InitialCondition)
LON_DEG = 4.4
STATE_STEP = 1.0e-5  # central-difference step of the lateral states and inputs (rad, rad/s)
TIME_STEP_S = 1.0e-6  # step along the full state derivative


@dataclass(frozen=True, slots=True)
class LateralLti:
    """One linearisation: ``x' = A x + B u`` about a trim at ``tas_mps``/``alt_m``."""

    tas_mps: float
    alt_m: float
    eas_mps: float
    trim: Trim
    A: Mat  # (4, 4)
    B: Mat  # (4, 2)


def _lateral_of(s: Vec) -> Vec:
    """[phi, beta, p, r] of a rigid-body state (calm air: air velocity = ground velocity)."""
    C = np.array(dcm_from_quat_fast(*s[6:10])).reshape(3, 3)
    phi = math.atan2(C[2, 1], C[2, 2])
    vb = C.T @ s[3:6]
    return np.array([phi, math.asin(vb[1] / np.linalg.norm(vb)), s[10], s[12]])


def lateral_lti(airframe: str, tas_mps: float, alt_m: float, *,
                heading_rad: float = 0.0) -> LateralLti:
    """Trim and linearise the lateral dynamics of ``airframe`` at one speed and altitude."""
    body = RigidBody(load_airframe(airframe))
    lat, lon = math.radians(LAT_DEG), math.radians(LON_DEG)
    tr = trim_level(body, lat, lon, alt_m, tas_mps, heading_rad)
    a = tr.alpha_rad

    def full_state(x: Vec) -> list[float]:
        phi, beta, p, r = x
        q = quat_from_euler(phi, a, heading_rad)  # theta = alpha: level trim
        vb = np.array([tas_mps * math.cos(a) * math.cos(beta), tas_mps * math.sin(beta),
                       tas_mps * math.sin(a) * math.cos(beta)])
        s = list(tr.state)
        s[3:6] = (dcm_ned_frd(phi, a, heading_rad) @ vb).tolist()
        s[6:10] = [float(v) for v in q]
        s[10] = tr.state[10] + p
        s[12] = tr.state[12] + r
        return s

    def xdot(x: Vec, u: Vec) -> Vec:
        s = full_state(x)
        d, _ = body.evaluate(s, float(u[0]), tr.elevator_rad, float(u[1]), tr.throttle,
                             0.0, 0.0, 0.0)
        sa, da = np.array(s), np.array(d)
        h = TIME_STEP_S
        return (_lateral_of(sa + h * da) - _lateral_of(sa - h * da)) / (2.0 * h)

    x0, u0 = np.zeros(N_X), np.zeros(N_U)
    A = np.zeros((N_X, N_X))
    B = np.zeros((N_X, N_U))
    e = STATE_STEP
    for j in range(N_X):
        dx = np.zeros(N_X)
        dx[j] = e
        A[:, j] = (xdot(x0 + dx, u0) - xdot(x0 - dx, u0)) / (2.0 * e)
    for j in range(N_U):
        du = np.zeros(N_U)
        du[j] = e
        B[:, j] = (xdot(x0, u0 + du) - xdot(x0, u0 - du)) / (2.0 * e)
    return LateralLti(tas_mps, alt_m, eas_from_tas(tas_mps, alt_m), tr, A, B)


def lateral_lpv(airframe: str, tas_mps: tuple[float, ...], alt_m: float) -> tuple[
        LateralLpv, LpvFitError, list[LateralLti]]:
    """Linearise at every speed of ``tas_mps`` and fit the LPV model (Chen2020 eq. 59)."""
    ltis = [lateral_lti(airframe, v, alt_m) for v in tas_mps]
    model, err = fit_lpv([m.eas_mps for m in ltis], [m.A for m in ltis], [m.B for m in ltis],
                         source=f"sim_vehicle {airframe} linearised at {alt_m:g} m, TAS "
                                f"{min(tas_mps):g}-{max(tas_mps):g} m/s")
    return model, err, ltis


# the autopilot's lateral loops closed around the linearised plant ---------------------------------

AUTOPILOT_STEP_S = 1.0e-6  # integrator derivatives from one tiny autopilot step


def lateral_closed_loop(airframe: str, lti: LateralLti) -> tuple[Mat, Mat, Mat]:
    """The simulator autopilot's lateral loops (bank hold at 0, sideslip 0; ``loops.py``)
    closed around ``lti``, linearised numerically through the autopilot's own code.

    State ``x_c = [phi, beta, p, r, int_p, int_r]`` (the roll-attitude and yaw-rate integrators),
    input ``e_f`` = the yaw-rate gyro's fault-estimation error: the autopilot reads the corrected
    gyro ``r - e_f`` (Chen2020 eq. 24). Returns ``A_c`` (6, 6), ``H_c`` (6, 1) and ``C_c``
    (4, 6) with ``x_p = C_c x_c``; the uncertainty enters as ``[M_p; 0]``.
    """
    from sim_vehicle.autopilot.loops import Autopilot, Feedback, Targets
    from sim_vehicle.dynamics.rigid_body import gravity_fast

    af = load_airframe(airframe)
    tr = lti.trim
    lat = math.radians(LAT_DEG)
    g = gravity_fast(lat, lti.alt_m)
    from gcs_monitor.core.atmosphere import isa_density_kgpm3

    rho = isa_density_kgpm3(lti.alt_m)
    tg = Targets(lti.alt_m, lti.tas_mps, 0.0, bank_rad=0.0, beta_rad=0.0)

    def f(x: Vec, e_f: float) -> Vec:
        ap = Autopilot(af, tr, g)
        ap.int_p, ap.int_r = float(x[4]), float(x[5])
        fb = Feedback(alt_m=lti.alt_m, vd_mps=0.0, tas_mps=lti.tas_mps, rho_kgpm3=rho,
                      phi=float(x[0]), theta=tr.alpha_rad, psi=0.0, p=float(x[2]), q=0.0,
                      r=float(x[3]) - e_f, beta=float(x[1]), acc_z_mps2=-g, gamma_rad=0.0)
        h = AUTOPILOT_STEP_S
        da, _, dr, _ = ap.update(fb, tg, h)
        xp = lti.A @ x[:4] + lti.B @ np.array([da, dr])
        return np.concatenate([xp, [(ap.int_p - x[4]) / h, (ap.int_r - x[5]) / h]])

    n = 6
    e = STATE_STEP
    A = np.zeros((n, n))
    for j in range(n):
        dx = np.zeros(n)
        dx[j] = e
        A[:, j] = (f(dx, 0.0) - f(-dx, 0.0)) / (2.0 * e)
    H = ((f(np.zeros(n), e) - f(np.zeros(n), -e)) / (2.0 * e)).reshape(n, 1)
    C = np.hstack([np.eye(N_X), np.zeros((N_X, 2))])
    return A, H, C
