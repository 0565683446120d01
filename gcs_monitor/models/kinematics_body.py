"""Approximate body-frame ground-speed kinematic model with IMU fault estimates (Atmaca2025).

State (Atmaca2025 eq. 3): ``x = [u, v, w, phi, theta, psi]`` -- ground velocity in body FRD axes
(m/s) and ZYX Euler angles (rad). Input (eq. 4): ``u_m = [A_x, A_y, A_z, p, q, r]`` measured
specific force (m/s^2, FRD) and body rates (rad/s, FRD). Fault estimates (eq. 6) ``f_hat`` have the
same layout as ``u_m``. Measurement (eqs. 16-19): NED ground velocity and the Euler angles over a
flat, non-rotating earth.

The "approximate" model (eqs. 9-14) subtracts each fault estimate only where its sensor is *not*
the one that drives the state's own drift: the accelerometer faults stay in ``A_m`` of eqs. 9-11,
``p_m`` stays raw in eq. 12, ``q_m`` in eq. 13 and ``r_m`` in eq. 14. The predicted state therefore
drifts at the rate :func:`own_drift_gain` times the true fault, which is what the HOSM
differentiator turns back into the fault estimate (eqs. 47-51).

All functions are pure and use plain float math (6-element models; numpy overhead dominates
otherwise).
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np

from gcs_monitor.core.optional import optional_module
from gcs_monitor.core.types import Mat, Vec

N_STATE = 6
N_INPUT = 6
N_MEAS = 6


def body_gs_derivative(x: Vec, u_m: Vec, f_hat: Vec, g_mps2: float) -> Vec:
    """Time derivative of the approximate body-frame GS model (Atmaca2025 eqs. 9-14).

    Parameters
    ----------
    x : (6,) [u, v, w] body FRD ground velocity (m/s), [phi, theta, psi] (rad)
    u_m : (6,) measured [A_x, A_y, A_z] (m/s^2, FRD) and [p, q, r] (rad/s, FRD)
    f_hat : (6,) current IMU fault estimates, same layout as ``u_m``
    g_mps2 : gravity magnitude (m/s^2)

    Returns
    -------
    (6,) state derivative
    """
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
    """Jacobian F = df/dx of :func:`body_gs_derivative` (Atmaca2025 eq. 26).

    Returns
    -------
    (6, 6) continuous-time state Jacobian
    """
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
    """Noise distribution matrix G(x) = -df/du_m (Atmaca2025 eq. 15, corrected).

    Atmaca2025 eq. 15 prints ``u_GS`` in row 1, column 5; the derivative of eq. 9 with respect to
    ``q_m`` is ``-w``, so ``G[0, 4] = +w`` (Lu2015 has the same matrix). Every other entry is as
    printed. A unit test checks ``G = -df/du_m`` by finite differences.

    Returns
    -------
    (6, 6) matrix mapping IMU noise (layout of ``u_m``) into the state derivative
    """
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
    """Measurement model h(x) = [T_EB v_b, phi, theta, psi] (Atmaca2025 eqs. 16-19).

    ``T_EB`` is the body-to-earth DCM of a flat, non-rotating earth, i.e. ``C_ned_frd``.

    Returns
    -------
    (6,) [v_N, v_E, v_D] (m/s, NED) and the Euler angles (rad)
    """
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


def own_drift_gain(euler_rad: Vec) -> Vec:
    """Rate at which each true IMU fault drives its own state's drift in eqs. 9-14.

    With the other faults compensated (``f_hat ~ f``), the predicted state of eqs. 9-14 drifts
    from the true state at ``d mu / dt = D f`` with
    ``D = diag(1, 1, 1, 1, cos phi, cos phi / cos theta)``: the raw ``A_m`` in eqs. 9-11, the raw
    ``p_m`` in eq. 12 (coefficient 1), ``q_m cos phi`` in eq. 13 and ``r_m cos phi / cos theta``
    in eq. 14.

    Returns
    -------
    (6,) diagonal of D
    """
    cph = math.cos(float(euler_rad[0]))
    cth = math.cos(float(euler_rad[1]))
    return np.array([1.0, 1.0, 1.0, 1.0, cph, cph / cth])


def drift_rate_to_fault(drift_rate: Vec, euler_rad: Vec, *, mapping: str = "flat") -> Vec:
    """IMU fault estimate from the estimated state-drift rate (Atmaca2025 eqs. 46, 51).

    Atmaca2025 eq. 51 sets the fault estimates equal to ``z_1``, the derivative of the drift
    (``mapping="paper"``). Its own flatness argument (eqs. 43-46) says the two are *algebraically*
    related; for eqs. 9-14 that relation is ``d mu / dt = D f`` (:func:`own_drift_gain`), so
    ``mapping="flat"`` (the default) inverts ``D``. The two agree when ``phi = theta = 0`` and
    differ by ``1 - cos(phi)`` in the pitch and yaw gyro channels (13 % at 30 deg of bank).

    Parameters
    ----------
    drift_rate : (6,) ``z_1`` of the HOSM differentiator (m/s^2 and rad/s)
    euler_rad : (3,) [phi, theta, psi] (rad)
    mapping : ``"flat"`` or ``"paper"``

    Returns
    -------
    (6,) [f_Ax, f_Ay, f_Az, f_p, f_q, f_r]
    """
    if mapping == "paper":
        return np.array(drift_rate, dtype=np.float64)
    if mapping != "flat":
        raise ValueError(f"unknown drift-to-fault mapping {mapping!r}")
    return np.asarray(drift_rate, dtype=np.float64) / own_drift_gain(euler_rad)


# ---------------------------------------------------------------------------------------------
# Compiled versions (numba, models/_kinematics_body_jit.py), imported lazily so that importing
# this module stays cheap. tests/gcs_monitor/models/test_kinematics_body.py checks they agree with
# the functions above.
# ---------------------------------------------------------------------------------------------


class CompiledBodyGs(Protocol):
    """What ``_kinematics_body_jit`` provides (all write into caller-supplied arrays)."""

    def derivative(self, x: Vec, u_m: Vec, f_hat: Vec, g: float, out: Vec) -> None: ...
    def jac_x(self, x: Vec, u_m: Vec, f_hat: Vec, g: float, F: Mat) -> None: ...
    def noise_matrix(self, x: Vec, G: Mat) -> None: ...
    def measurement(self, x: Vec, h: Vec, H: Mat) -> None: ...
    def prediction(self, *args: object) -> None: ...


def compiled_kernels() -> CompiledBodyGs | None:
    """The numba versions of this model, imported on first use (None if numba is missing)."""
    return optional_module("gcs_monitor.models._kinematics_body_jit")  # type: ignore[return-value]
