"""Trim for wings-level, constant-altitude flight: solve for alpha, elevator and throttle.

Unknowns ``(alpha, de, throttle)``; residuals: along-track and vertical ground acceleration and
pitch acceleration from the full equations of motion (:class:`RigidBody`), with
``theta = alpha`` (gamma = 0), ``beta = 0``, body rates equal to the earth + transport rate
so the attitude stays level. Solved with ``scipy.optimize.least_squares``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from gcs_monitor.core import constants as k
from gcs_monitor.core.frames import quat_from_euler
from sim_vehicle.dynamics.rigid_body import RigidBody, dcm_from_quat_fast


@dataclass(frozen=True, slots=True)
class Trim:
    tas_mps: float
    alt_m: float
    alpha_rad: float
    elevator_rad: float
    throttle: float
    state: tuple[float, ...]  # the 14-float RigidBody state at trim
    residual: float  # max |residual| (m/s^2, rad/s^2) at the solution


def level_state(
    body: RigidBody,
    lat_rad: float,
    lon_rad: float,
    alt_m: float,
    tas_mps: float,
    heading_rad: float,
    alpha_rad: float,
    throttle: float,
    wind_ned_mps: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> list[float]:
    """Rigid-body state flying level at ``tas_mps`` through the air mass (plus the wind)."""
    q = quat_from_euler(0.0, alpha_rad, heading_rad)
    c = dcm_from_quat_fast(*q)
    vn = tas_mps * math.cos(heading_rad) + wind_ned_mps[0]
    ve = tas_mps * math.sin(heading_rad) + wind_ned_mps[1]
    vd = wind_ned_mps[2]
    rh = k.EARTH_RADIUS_M + alt_m
    om = k.EARTH_RATE_RADPS
    win = (
        ve / rh + om * math.cos(lat_rad),
        -vn / rh,
        -ve * math.tan(lat_rad) / rh - om * math.sin(lat_rad),
    )
    p = c[0] * win[0] + c[3] * win[1] + c[6] * win[2]
    qq = c[1] * win[0] + c[4] * win[1] + c[7] * win[2]
    r = c[2] * win[0] + c[5] * win[1] + c[8] * win[2]
    return [
        lat_rad,
        lon_rad,
        alt_m,
        vn,
        ve,
        vd,
        *(float(x) for x in q),
        float(p),
        float(qq),
        float(r),
        throttle,
    ]


def trim_level(
    body: RigidBody,
    lat_rad: float,
    lon_rad: float,
    alt_m: float,
    tas_mps: float,
    heading_rad: float,
    wind_ned_mps: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> Trim:
    """Solve the level-flight trim (see module docstring)."""
    ch, sh = math.cos(heading_rad), math.sin(heading_rad)

    def resid(z: np.ndarray) -> np.ndarray:
        alpha, de, thr = (float(v) for v in z)
        s = level_state(
            body, lat_rad, lon_rad, alt_m, tas_mps, heading_rad, alpha, thr, wind_ned_mps
        )
        d, _ = body.evaluate(s, 0.0, de, 0.0, thr, *wind_ned_mps)
        return np.array([d[3] * ch + d[4] * sh, d[5], d[11]])

    sol = least_squares(
        resid,
        x0=np.array([0.05, 0.0, 0.5]),
        bounds=([-0.3, -0.6, 0.0], [0.5, 0.6, 1.0]),
        xtol=1e-12,
        ftol=1e-12,
        gtol=1e-12,
    )
    alpha, de, thr = (float(v) for v in sol.x)
    st = level_state(body, lat_rad, lon_rad, alt_m, tas_mps, heading_rad, alpha, thr, wind_ned_mps)
    return Trim(tas_mps, alt_m, alpha, de, thr, tuple(st), float(np.max(np.abs(resid(sol.x)))))
