"""Plain-float reference of the body-frame GS model kernels (Atmaca2025 eqs. 9-19, 26;
``models/_kinematics_body_jit.py``).

The model functions as ``gcs_monitor.models.kinematics_body`` computed them before they
wrapped the kernels (the equation choices are documented there).
"""

from __future__ import annotations

import math

import numpy as np

from gcs_monitor.core.types import Mat, Vec

N_MEAS = 6
N_STATE = 6


def body_gs_derivative(x: Vec, u_m: Vec, f_hat: Vec, g_mps2: float) -> Vec:
    """Time derivative of the approximate body-frame GS model (Atmaca2025 eqs. 9-14)."""
    u, v, w, phi, theta, _ = (float(a) for a in x)
    ax, ay, az, pm, qm, rm = (float(a) for a in u_m)
    pe = pm - float(f_hat[3])
    qe = qm - float(f_hat[4])
    re = rm - float(f_hat[5])
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(theta), math.cos(theta)
    tth = sth / cth
    return np.array(
        [
            v * re - w * qe + ax - g_mps2 * sth,  # eq. 9
            -u * re + w * pe + ay + g_mps2 * cth * sph,  # eq. 10
            u * qe - v * pe + az + g_mps2 * cth * cph,  # eq. 11
            pm + qe * sph * tth + re * cph * tth,  # eq. 12
            qm * cph - re * sph,  # eq. 13
            qe * sph / cth + rm * cph / cth,  # eq. 14
        ]
    )


def body_gs_jac_x(x: Vec, u_m: Vec, f_hat: Vec, g_mps2: float) -> Mat:
    """Jacobian F = df/dx of :func:`body_gs_derivative` (Atmaca2025 eq. 26)."""
    _, _, _, phi, theta, _ = (float(a) for a in x)
    _, _, _, pm, qm, rm = (float(a) for a in u_m)
    pe = pm - float(f_hat[3])
    qe = qm - float(f_hat[4])
    re = rm - float(f_hat[5])
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(theta), math.cos(theta)
    tth = sth / cth
    c2 = cth * cth
    g = g_mps2
    return np.array(
        [
            [0.0, re, -qe, 0.0, -g * cth, 0.0],
            [-re, 0.0, pe, g * cth * cph, -g * sth * sph, 0.0],
            [qe, -pe, 0.0, -g * cth * sph, -g * sth * cph, 0.0],
            [0.0, 0.0, 0.0, (qe * cph - re * sph) * tth, (qe * sph + re * cph) / c2, 0.0],
            [0.0, 0.0, 0.0, -qm * sph - re * cph, 0.0, 0.0],
            [0.0, 0.0, 0.0, (qe * cph - rm * sph) / cth, (qe * sph + rm * cph) * sth / c2, 0.0],
        ]
    )


def body_gs_noise_matrix(x: Vec) -> Mat:
    """Noise distribution matrix G(x) = -df/du_m (Atmaca2025 eq. 15, corrected)."""
    u, v, w, phi, theta, _ = (float(a) for a in x)
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(theta), math.cos(theta)
    tth = sth / cth
    return np.array(
        [
            [-1.0, 0.0, 0.0, 0.0, w, -v],
            [0.0, -1.0, 0.0, -w, 0.0, u],
            [0.0, 0.0, -1.0, v, -u, 0.0],
            [0.0, 0.0, 0.0, -1.0, -sph * tth, -cph * tth],
            [0.0, 0.0, 0.0, 0.0, -cph, sph],
            [0.0, 0.0, 0.0, 0.0, -sph / cth, -cph / cth],
        ]
    )


def _dcm_and_partials(phi: float, theta: float, psi: float) -> tuple[Mat, Mat, Mat, Mat]:
    """C_ned_frd (ZYX) and its partial derivatives with respect to phi, theta, psi."""
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(theta), math.cos(theta)
    sps, cps = math.sin(psi), math.cos(psi)
    C = np.array(
        [
            [cth * cps, sph * sth * cps - cph * sps, cph * sth * cps + sph * sps],
            [cth * sps, sph * sth * sps + cph * cps, cph * sth * sps - sph * cps],
            [-sth, sph * cth, cph * cth],
        ]
    )
    dphi = np.array(
        [
            [0.0, cph * sth * cps + sph * sps, -sph * sth * cps + cph * sps],
            [0.0, cph * sth * sps - sph * cps, -sph * sth * sps - cph * cps],
            [0.0, cph * cth, -sph * cth],
        ]
    )
    dth = np.array(
        [
            [-sth * cps, sph * cth * cps, cph * cth * cps],
            [-sth * sps, sph * cth * sps, cph * cth * sps],
            [-cth, -sph * sth, -cph * sth],
        ]
    )
    dpsi = np.array(
        [
            [-cth * sps, -sph * sth * sps - cph * cps, -cph * sth * sps + sph * cps],
            [cth * cps, sph * sth * cps - cph * sps, cph * sth * cps + sph * sps],
            [0.0, 0.0, 0.0],
        ]
    )
    return C, dphi, dth, dpsi


def body_gs_measurement(x: Vec) -> Vec:
    """Measurement model h(x) = [T_EB v_b, phi, theta, psi] (Atmaca2025 eqs. 16-19)."""
    C, _, _, _ = _dcm_and_partials(float(x[3]), float(x[4]), float(x[5]))
    out = np.empty(N_MEAS)
    out[:3] = C @ x[:3]
    out[3:] = x[3:]
    return out


def body_gs_meas_jac(x: Vec) -> Mat:
    """Jacobian H = dh/dx of :func:`body_gs_measurement` (Atmaca2025 eq. 26)."""
    C, dphi, dth, dpsi = _dcm_and_partials(float(x[3]), float(x[4]), float(x[5]))
    vb = x[:3]
    H = np.zeros((N_MEAS, N_STATE))
    H[:3, :3] = C
    H[:3, 3] = dphi @ vb
    H[:3, 4] = dth @ vb
    H[:3, 5] = dpsi @ vb
    H[3, 3] = H[4, 4] = H[5, 5] = 1.0
    return H


def fault_from_drift_rate(drift_rate: Vec, x: Vec) -> Vec:
    """Solve ``A(x) f = drift_rate`` for the fault (:func:`fault_input_matrix`)."""
    u, v, w, phi, theta, _ = (float(a) for a in x)
    r = [float(a) for a in drift_rate]
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(theta), math.cos(theta)
    fp = r[3] - sth * r[5]
    fq = cph * r[4] + sph * cth * r[5]
    fr = -sph * r[4] + cph * cth * r[5]
    return np.array(
        [
            r[0] - (v * fr - w * fq),
            r[1] - (w * fp - u * fr),
            r[2] - (u * fq - v * fp),
            fp,
            fq,
            fr,
        ]
    )
