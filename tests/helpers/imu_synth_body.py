"""Synthetic truth for the Atmaca2025 IMU estimator, independent of sim_vehicle.

Flat, non-rotating earth (the model of Atmaca2025 eqs. 9-19). The manoeuvre is analytic: the Euler
angles and the NED ground velocity are sums of sinusoids (an S-turn with up to ~17 deg of bank,
+-20 deg heading, speed and climb variations, and small 0.7-1.1 Hz components standing in for
turbulence), so the body rates and the specific force follow *exactly* from their derivatives
(no integration error):

    [p, q, r] = W(phi, theta)^{-1} [phi', theta', psi']
    A_frd     = C_ned_frd^T (v_ned' - [0, 0, g])

Sensors (Atmaca2025 Table 1): IMU and attitude at 100 Hz with white noise; GPS ground velocity at
10 Hz with white noise, linearly interpolated to the 100 Hz frames (non-causally, i.e. between the
samples around each frame, ``gps_delay_us = 0``). Faults: Atmaca2025 Table 2 (accelerometers) and
Table 3 (gyros), added to the measurement, ``u_m = u + w + f`` (eq. 4).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from gcs_monitor.core.atmosphere import gravity_mps2
from gcs_monitor.core.frames import dcm_ned_frd
from gcs_monitor.core.types import Vec
from gcs_monitor.families.imu.imu_hosm import AtmacaSensorNoise
from gcs_monitor.telemetry.frame import Frame, ImuSample

LAT_RAD = math.radians(52.0)
ALT_M = 1000.0
TWO_PI = 2.0 * math.pi
IMU_RATE_HZ = 100.0  # Atmaca2025 Table 1
GPS_RATE_HZ = 10.0  # Atmaca2025 Table 1
FAULT_WINDOWS_S = ((10.0, 30.0), (35.0, 55.0))  # Atmaca2025 Tables 2 and 3

FaultFn = Callable[[float], Vec]


def _sin(a: float, f_hz: float, t: float, ph: float = 0.0) -> tuple[float, float]:
    w = TWO_PI * f_hz
    return a * math.sin(w * t + ph), a * w * math.cos(w * t + ph)


def truth_at(t: float, g_mps2: float) -> tuple[Vec, Vec, Vec]:
    """True state and IMU input at time t.

    Returns
    -------
    x : (6,) body FRD ground velocity (m/s) and Euler angles (rad)
    u : (6,) true specific force (m/s^2, FRD) and body rates (rad/s, FRD)
    vel_ned : (3,) NED ground velocity (m/s)
    """
    f_turn = 1.0 / 40.0
    a, ad = _sin(0.35, f_turn, t)
    psi, psid = 0.4 + a, ad
    b, bd = _sin(0.3, f_turn, t, math.pi / 2.0)
    c1, c1d = _sin(0.02, 0.8, t)
    phi, phid = b + c1, bd + c1d
    d1, d1d = _sin(0.02, 0.1, t)
    d2, d2d = _sin(0.005, 1.1, t, 0.3)
    theta, thetad = 0.05 + d1 + d2, d1d + d2d
    e1, e1d = _sin(1.0, 0.05, t)
    e2, e2d = _sin(0.3, 0.7, t, 1.0)
    V, Vd = 60.0 + e1 + e2, e1d + e2d
    k1, k1d = _sin(0.05, 0.03, t)
    chi, chid = psi + k1, psid + k1d
    h1, h1d = _sin(0.5, 0.1, t)
    h2, h2d = _sin(0.3, 0.9, t, 2.0)
    vel_ned = np.array([V * math.cos(chi), V * math.sin(chi), h1 + h2])
    acc_ned = np.array(
        [
            Vd * math.cos(chi) - V * math.sin(chi) * chid,
            Vd * math.sin(chi) + V * math.cos(chi) * chid,
            h1d + h2d,
        ]
    )
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(theta), math.cos(theta)
    p = phid - psid * sth
    q = thetad * cph + psid * cth * sph
    r = -thetad * sph + psid * cth * cph
    C = dcm_ned_frd(phi, theta, psi)
    spec = C.T @ (acc_ned - np.array([0.0, 0.0, g_mps2]))
    x = np.concatenate([C.T @ vel_ned, [phi, theta, psi]])
    u = np.concatenate([spec, [p, q, r]])
    return x, u, vel_ned


TURN_SPEED_MPS = 125.0
TURN_BANK_RAD = math.radians(30.0)
TURN_PITCH_RAD = math.radians(3.0)


def turn_truth_at(t: float, g_mps2: float) -> tuple[Vec, Vec, Vec]:
    """Steady level coordinated turn (same outputs as :func:`truth_at`).

    Constant bank and pitch, ground speed ``TURN_SPEED_MPS`` along the heading, turn rate
    ``Omega = g tan(phi) / V``: ``psi = 0.2 + Omega t``, so the body-axis ground velocity is
    constant and the NED velocity rotates, ``v_ned' = Omega [-v_E, v_N, 0]``.
    """
    V, phi, theta = TURN_SPEED_MPS, TURN_BANK_RAD, TURN_PITCH_RAD
    om = g_mps2 * math.tan(phi) / V
    psi = 0.2 + om * t
    vel_ned = np.array([V * math.cos(psi), V * math.sin(psi), 0.0])
    acc_ned = om * np.array([-vel_ned[1], vel_ned[0], 0.0])
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(theta), math.cos(theta)
    C = dcm_ned_frd(phi, theta, psi)
    spec = C.T @ (acc_ned - np.array([0.0, 0.0, g_mps2]))
    x = np.concatenate([C.T @ vel_ned, [phi, theta, psi]])
    u = np.concatenate([spec, [-om * sth, om * cth * sph, om * cth * cph]])
    return x, u, vel_ned


def _in(t: float, w: tuple[float, float]) -> bool:
    return w[0] < t < w[1]


def table2_faults(t: float) -> Vec:
    """Accelerometer fault cases, Atmaca2025 Table 2 (m/s^2), layout [Ax, Ay, Az, p, q, r]."""
    f = np.zeros(6)
    if _in(t, FAULT_WINDOWS_S[0]):
        f[0] = 2.0
        f[1] = -0.1 * (t - 10.0)
        f[2] = 2.0 * math.sin(0.5 * math.pi * t)
    elif _in(t, FAULT_WINDOWS_S[1]):
        f[0] = 2.0 * math.sin(math.pi * t)
        f[1] = 1.0
        f[2] = 0.1 * (t - 35.0)
    return f


def table3_faults(t: float) -> Vec:
    """Rate-gyro fault cases, Atmaca2025 Table 3 (rad/s), layout [Ax, Ay, Az, p, q, r]."""
    f = np.zeros(6)
    if _in(t, FAULT_WINDOWS_S[0]):
        f[3] = (math.pi / 180.0) * math.sin(math.pi * t)
        f[4] = 0.1 * (math.pi / 360.0) * (t - 10.0)
        f[5] = -math.pi / 360.0
    elif _in(t, FAULT_WINDOWS_S[1]):
        f[3] = -0.125 * (math.pi / 360.0) * (t - 35.0)
        f[4] = 1.5 * math.pi / 360.0
        f[5] = (math.pi / 180.0) * math.sin(0.5 * math.pi * t)
    return f


def no_faults(t: float) -> Vec:
    return np.zeros(6)


@dataclass(frozen=True)
class SynthRun:
    """A synthetic run: frames plus the truth to score them against.

    Attributes
    ----------
    t_s : (N,) frame times
    frames : the Frames, one per IMU sample
    x_true : (N, 6) true body ground velocity and Euler angles
    u_true : (N, 6) true IMU input
    f_true : (N, 6) true faults added to the IMU
    """

    t_s: Vec
    frames: list[Frame]
    x_true: Vec
    u_true: Vec
    f_true: Vec


def make_run(
    duration_s: float,
    *,
    faults: FaultFn = no_faults,
    seed: int = 0,
    noise: AtmacaSensorNoise | None = None,
    truth: Callable[[float, float], tuple[Vec, Vec, Vec]] = truth_at,
) -> SynthRun:
    """Build Frames for ``duration_s`` of flight with the given fault function (seeded);
    ``truth`` is :func:`truth_at` (S-turn) or :func:`turn_truth_at` (steady turn)."""
    nz = noise if noise is not None else AtmacaSensorNoise()
    rng = np.random.default_rng(seed)
    g = gravity_mps2(LAT_RAD, ALT_M)
    dt = 1.0 / IMU_RATE_HZ
    n = int(round(duration_s / dt)) + 1
    t_s = np.arange(n) * dt
    # GPS samples at 10 Hz, one beyond the end so every frame can interpolate
    gps_dt = 1.0 / GPS_RATE_HZ
    n_gps = int(math.ceil(duration_s / gps_dt)) + 2
    t_gps = np.arange(n_gps) * gps_dt
    v_gps = np.array([truth(float(tg), g)[2] for tg in t_gps])
    v_gps += rng.normal(0.0, nz.gps_vel_sigma_mps, v_gps.shape)
    x_true = np.empty((n, 6))
    u_true = np.empty((n, 6))
    f_true = np.empty((n, 6))
    frames: list[Frame] = []
    imu_sig = np.array([nz.acc_sigma_mps2] * 3 + [nz.gyro_sigma_radps] * 3)
    att_sig = np.array([nz.phi_theta_sigma_rad] * 2 + [nz.psi_sigma_rad])
    for i, t in enumerate(t_s):
        x, u, _ = truth(float(t), g)
        f = faults(float(t))
        x_true[i], u_true[i], f_true[i] = x, u, f
        u_m = u + rng.normal(0.0, 1.0, 6) * imu_sig + f
        eul = x[3:] + rng.normal(0.0, 1.0, 3) * att_sig
        j = min(int(t / gps_dt + 1e-9), n_gps - 2)
        a = (t - t_gps[j]) / gps_dt
        vel = (1.0 - a) * v_gps[j] + a * v_gps[j + 1]
        t_us = int(round(t * 1e6))
        frames.append(
            Frame(
                t_us=t_us,
                imu=[ImuSample(t_us, 0, u_m[:3].copy(), u_m[3:].copy())],
                euler_rad=eul,
                att_age_s=0.0,
                gps_vel_ned_mps=vel,
                gps_age_s=float(t - t_gps[j]),
                gps_delay_us=0,
                gps_new=bool(abs(a) < 1e-9),
                lat_rad=LAT_RAD,
                lon_rad=0.0,
                alt_msl_m=ALT_M,
            )
        )
    return SynthRun(t_s=t_s, frames=frames, x_true=x_true, u_true=u_true, f_true=f_true)
