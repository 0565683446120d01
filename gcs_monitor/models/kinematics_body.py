"""Approximate body-frame ground-speed kinematic model with IMU fault estimates (Atmaca2025).

State (Atmaca2025 eq. 3): ``x = [u, v, w, phi, theta, psi]`` -- ground velocity in body FRD axes
(m/s) and ZYX Euler angles (rad). Input (eq. 4): ``u_m = [A_x, A_y, A_z, p, q, r]`` measured
specific force (m/s^2, FRD) and body rates (rad/s, FRD). Fault estimates (eq. 6) ``f_hat`` have the
same layout as ``u_m``. Measurement (eqs. 16-19): NED ground velocity and the Euler angles over a
flat, non-rotating earth.

The "approximate" model (eqs. 9-14) subtracts each fault estimate only where its sensor is *not*
the one that drives the state's own drift: the accelerometer faults stay in ``A_m`` of eqs. 9-11,
``p_m`` stays raw in eq. 12, ``q_m`` in eq. 13 and ``r_m`` in eq. 14. A fault moves the state
derivative by ``A(x) f`` (:func:`fault_input_matrix`, ``-G`` of eq. 15) and the estimates by
``M(x) f_hat`` (:func:`fault_estimate_matrix`), so the predicted state drifts at
``d mu / dt = A f + M f_hat``; that is the diagonal ``D f`` (:func:`own_drift_gain`) only once
``f_hat = f``. :func:`fault_from_drift_rate` solves ``A(x) f = d mu / dt`` in closed form (the
map the estimator uses, with ``f_hat = 0`` in the filter as eq. 20 prints it);
:func:`drift_rate_to_fault` also keeps the diagonal maps.

Checked against physics: with exact inputs and ``f_hat = 0`` eqs. 9-14 equal the flat,
non-rotating limit of the GS-KM (``kinematics.py``, Lu2016 eq. 11) rotated into body axes,
``d(C^T v_ned)/dt = C^T v_ned' - omega x v_b`` (tests/gcs_monitor/models/test_kinematics_body.py),
and the simulator's truth in a 30 deg coordinated turn to 0.01-0.06 m/s^2 RMS
(docs/papers-notes.md).

The model runs in the numba kernels of ``models/_kinematics_body_jit.py``: the functions below
wrap them (each allocates its result), and the estimator's hot path calls them directly
(``estimators/imu_hosm.py``). The plain-float reference that the equivalence test compares
them with is ``tests/reference/kinematics_body.py``.
"""

from __future__ import annotations

import math

import numpy as np

from gcs_monitor.core.kernels import load_kernels
from gcs_monitor.core.types import Mat, Vec

N_STATE = 6
N_INPUT = 6
N_MEAS = 6


def _f64(a: Vec) -> Vec:
    return np.asarray(a, dtype=np.float64)


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
    out = np.empty(N_STATE)
    kern = load_kernels("gcs_monitor.models._kinematics_body_jit")
    kern.derivative(_f64(x), _f64(u_m), _f64(f_hat), float(g_mps2), out)
    return out


def body_gs_jac_x(x: Vec, u_m: Vec, f_hat: Vec, g_mps2: float) -> Mat:
    """Jacobian F = df/dx of :func:`body_gs_derivative` (Atmaca2025 eq. 26).

    Returns
    -------
    (6, 6) continuous-time state Jacobian
    """
    F = np.empty((N_STATE, N_STATE))
    kern = load_kernels("gcs_monitor.models._kinematics_body_jit")
    kern.jac_x(_f64(x), _f64(u_m), _f64(f_hat), float(g_mps2), F)
    return F


def body_gs_noise_matrix(x: Vec) -> Mat:
    """Noise distribution matrix G(x) = -df/du_m (Atmaca2025 eq. 15, corrected).

    Atmaca2025 eq. 15 prints ``u_GS`` in row 1, column 5; the derivative of eq. 9 with respect to
    ``q_m`` is ``-w``, so ``G[0, 4] = +w`` (Lu2015 has the same matrix). Every other entry is as
    printed. A unit test checks ``G = -df/du_m`` by finite differences.

    Returns
    -------
    (6, 6) matrix mapping IMU noise (layout of ``u_m``) into the state derivative
    """
    G = np.empty((N_STATE, N_INPUT))
    load_kernels("gcs_monitor.models._kinematics_body_jit").noise_matrix(_f64(x), G)
    return G


def body_gs_measurement(x: Vec) -> Vec:
    """Measurement model h(x) = [T_EB v_b, phi, theta, psi] (Atmaca2025 eqs. 16-19).

    ``T_EB`` is the body-to-earth DCM of a flat, non-rotating earth, i.e. ``C_ned_frd``.

    Returns
    -------
    (6,) [v_N, v_E, v_D] (m/s, NED) and the Euler angles (rad)
    """
    h, H = np.empty(N_MEAS), np.empty((N_MEAS, N_STATE))
    load_kernels("gcs_monitor.models._kinematics_body_jit").measurement(_f64(x), h, H)
    return h


def body_gs_meas_jac(x: Vec) -> Mat:
    """Jacobian H = dh/dx of :func:`body_gs_measurement` (Atmaca2025 eq. 26)."""
    h, H = np.empty(N_MEAS), np.empty((N_MEAS, N_STATE))
    load_kernels("gcs_monitor.models._kinematics_body_jit").measurement(_f64(x), h, H)
    return H


def own_drift_gain(euler_rad: Vec) -> Vec:
    """Rate at which each true IMU fault drives its own state's drift in eqs. 9-14.

    With the other faults compensated (``f_hat = f``), the predicted state of eqs. 9-14 drifts
    from the true state at ``d mu / dt = D f`` with
    ``D = diag(1, 1, 1, 1, cos phi, cos phi / cos theta)``: the raw ``A_m`` in eqs. 9-11, the raw
    ``p_m`` in eq. 12 (coefficient 1), ``q_m cos phi`` in eq. 13 and ``r_m cos phi / cos theta``
    in eq. 14. ``D`` is the diagonal of :func:`fault_input_matrix`; it is the whole story only at
    ``f_hat = f`` (see :func:`drift_rate_to_fault`).

    Returns
    -------
    (6,) diagonal of D
    """
    cph = math.cos(float(euler_rad[0]))
    cth = math.cos(float(euler_rad[1]))
    return np.array([1.0, 1.0, 1.0, 1.0, cph, cph / cth])


def fault_input_matrix(x: Vec) -> Mat:
    """Fault input matrix ``A(x) = d f / d u_m`` of eqs. 9-14 (equal to ``-G(x)``, eq. 15).

    A sensor fault adds to the measurement (eq. 4, ``u_m = u + w + f``), so the model's
    derivative moves by ``A f``: ``d mu / dt = A(x) f + M(x) f_hat`` with ``M`` of
    :func:`fault_estimate_matrix`. ``A`` is full in a bank: ``q_m`` and ``r_m`` both enter
    eqs. 13-14 (through ``cos phi`` and ``sin phi``), and every gyro enters eqs. 9-11 multiplied
    by the ground speed.

    Returns
    -------
    (6, 6) matrix, columns in the layout of ``u_m``
    """
    return -body_gs_noise_matrix(x)


def fault_estimate_matrix(x: Vec) -> Mat:
    """``M(x) = d f / d f_hat`` of eqs. 9-14: where the fault estimates enter the model.

    Eqs. 9-14 subtract ``f_hat`` only in the cross terms, so ``M = D - A`` with ``A`` of
    :func:`fault_input_matrix` and ``D = diag(`` :func:`own_drift_gain` ``)``.

    Returns
    -------
    (6, 6) matrix, columns in the layout of ``f_hat``
    """
    M = -fault_input_matrix(x)
    M[np.diag_indices(N_STATE)] += own_drift_gain(x[3:])
    return M


def fault_from_drift_rate(drift_rate: Vec, x: Vec) -> Vec:
    """Solve ``A(x) f = drift_rate`` for the fault (:func:`fault_input_matrix`).

    ``A`` is square and block upper triangular, ``[[I, [v]x], [0, W]]``, with ``W`` the
    body-rate to Euler-rate matrix of eqs. 12-14 (``det A = det W = 1 / cos theta``). Its inverse
    is closed form and has no singularity: ``f_omega = W^{-1} r_euler`` with
    ``W^{-1} = [[1, 0, -sin theta], [0, cos phi, sin phi cos theta], [0, -sin phi,
    cos phi cos theta]]`` (Euler rates to body rates), then ``f_A = r_vel - v x f_omega``. No
    least squares is needed.

    Parameters
    ----------
    drift_rate : (6,) ``d s / dt`` (m/s^2 and rad/s), layout of the state
    x : (6,) state at which ``A`` is evaluated

    Returns
    -------
    (6,) [f_Ax, f_Ay, f_Az (m/s^2), f_p, f_q, f_r (rad/s)]
    """
    out = np.empty(N_INPUT)
    kern = load_kernels("gcs_monitor.models._kinematics_body_jit")
    kern.fault_from_drift_rate(_f64(drift_rate), _f64(x), out)
    return out


def drift_rate_to_fault(drift_rate: Vec, x: Vec, *, mapping: str = "exact") -> Vec:
    """IMU fault estimate from the HOSM derivative ``z_1`` (Atmaca2025 eqs. 46, 51).

    ``mapping="exact"`` (default): ``d mu / dt = A(x) f`` for a drift of the model with
    ``f_hat = 0`` (eq. 20 as printed); the fault is ``A(x)^{-1} z_1``
    (:func:`fault_from_drift_rate`).
    (The estimator applies the same linear map to each drift increment before differentiating,
    ``estimators/imu_hosm.py``, so that its ``z_1`` is the fault itself.)

    ``mapping="flat"`` (``z_1 / D``) and ``"paper"`` (``z_1``, eq. 51 as printed) are for the
    drift of eqs. 9-14 *with* ``f_hat`` in the cross terms. Both assume ``d mu / dt = D f``,
    which holds only at ``f_hat = f``; otherwise
    ``d mu / dt = D f_hat + A (f - f_hat)``, so in a bank (``A`` not diagonal) the gyro estimates
    feed back through the ``sin phi`` terms of eqs. 13-14 with loop gain ``tan phi`` (and into
    eqs. 9-11 times the ground speed). Measured in a 30 deg coordinated turn: a sustained ~1 Hz
    oscillation of 0.8 deg/s on f_q/f_r and 2.6 m/s^2 on f_Ay/f_Az with zero true fault
    (docs/papers-notes.md, Atmaca2025). Kept to reproduce the paper and earlier results.

    Parameters
    ----------
    drift_rate : (6,) ``z_1`` of the HOSM differentiator (m/s^2 and rad/s)
    x : (6,) current state estimate [u, v, w (m/s, FRD), phi, theta, psi (rad)]
    mapping : ``"exact"``, ``"flat"`` or ``"paper"``

    Returns
    -------
    (6,) [f_Ax, f_Ay, f_Az, f_p, f_q, f_r]
    """
    if mapping == "exact":
        return fault_from_drift_rate(drift_rate, x)
    if mapping == "paper":
        return np.array(drift_rate, dtype=np.float64)
    if mapping != "flat":
        raise ValueError(f"unknown drift-to-fault mapping {mapping!r}")
    return np.asarray(drift_rate, dtype=np.float64) / own_drift_gain(x[3:])
