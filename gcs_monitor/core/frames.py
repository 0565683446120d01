"""NED/FRD frame conversions: Euler angles (ZYX), DCMs, quaternions (scalar first).

``C_ned_frd`` rotates FRD vectors into NED: ``v_ned = C_ned_frd @ v_frd``.
"""

from __future__ import annotations

import math

import numpy as np

from gcs_monitor.core.types import Mat, Vec


def dcm_ned_frd(phi: float, theta: float, psi: float) -> Mat:
    """DCM from body FRD to NED for ZYX Euler angles (the matrix in Lu2016 eq. 11, rows 1-3)."""
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(theta), math.cos(theta)
    sps, cps = math.sin(psi), math.cos(psi)
    return np.array(
        [
            [cth * cps, sph * sth * cps - cph * sps, cph * sth * cps + sph * sps],
            [cth * sps, sph * sth * sps + cph * cps, cph * sth * sps - sph * cps],
            [-sth, sph * cth, cph * cth],
        ]
    )


def euler_from_dcm(C_ned_frd: Mat) -> Vec:
    """ZYX Euler angles [phi, theta, psi] (rad) of a body-to-NED DCM; psi in (-pi, pi]."""
    phi = math.atan2(C_ned_frd[2, 1], C_ned_frd[2, 2])
    theta = -math.asin(max(-1.0, min(1.0, C_ned_frd[2, 0])))
    psi = math.atan2(C_ned_frd[1, 0], C_ned_frd[0, 0])
    return np.array([phi, theta, psi])


def quat_from_euler(phi: float, theta: float, psi: float) -> Vec:
    """Unit quaternion ``q_ned_frd`` = [w, x, y, z] for ZYX Euler angles."""
    cr, sr = math.cos(phi / 2), math.sin(phi / 2)
    cp, sp = math.cos(theta / 2), math.sin(theta / 2)
    cy, sy = math.cos(psi / 2), math.sin(psi / 2)
    return np.array(
        [
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ]
    )


def dcm_from_quat(q: Vec) -> Mat:
    """Body-to-NED DCM of a scalar-first unit quaternion."""
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def euler_rates(phi: float, theta: float, omega_frd_radps: Vec) -> Vec:
    """Euler angle rates [phi_dot, theta_dot, psi_dot] from body rates (Lu2016 eq. 18, rows 4-6)."""
    p, q, r = omega_frd_radps
    sph, cph = math.sin(phi), math.cos(phi)
    cth, tth = math.cos(theta), math.tan(theta)
    return np.array(
        [p + q * sph * tth + r * cph * tth, q * cph - r * sph, (q * sph + r * cph) / cth]
    )
