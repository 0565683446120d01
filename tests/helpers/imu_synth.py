"""Synthetic truth for the IMU fault estimators, independent of sim_vehicle.

Integrates the GS-KM (Lu2016 eq. 11) over the round rotating earth with RK4 at a fine step
(latitude and altitude integrated too), with a smooth true input: body rates from a gentle
roll/pitch/yaw manoeuvre and a specific force that holds 1 g plus small smooth accelerations.
Measurements get the Lu2016 Table 1 noise; the IMU gets the Lu2016 Table 2 faults for
10 s < t < 30 s. GPS velocity is produced at 100 Hz or at 10 Hz and linearly interpolated to
the IMU time (as the telemetry layer does), then packed into Frames.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gcs_monitor.core import constants as c
from gcs_monitor.core.atmosphere import cas_from_tas
from gcs_monitor.core.frames import dcm_ned_frd
from gcs_monitor.core.types import Mat, Vec
from gcs_monitor.families.imu.imu_ts import Lu2016Table1
from gcs_monitor.models.kinematics import gs_km_f
from gcs_monitor.telemetry.frame import Frame, ImuSample

FAULT_START_S = 10.0  # Lu2016 Table 2
FAULT_END_S = 30.0


def lu2016_table2_faults(t_s: float) -> Vec:
    """Lu2016 Table 2 IMU faults [f_Ax, f_Ay, f_Az (m/s^2), f_p, f_q, f_r (rad/s)] at t."""
    if not FAULT_START_S < t_s < FAULT_END_S:
        return np.zeros(6)
    d = math.pi / 180.0
    return np.array(
        [
            3.0,
            0.1 * (t_s - 10.0),
            4.0 * math.sin(0.5 * math.pi * t_s),
            1.5 * d,
            d * math.sin(0.5 * math.pi * (t_s - 10.0)),
            3.0 * d,
        ]
    )


def _true_input(t: float, x: Vec) -> Vec:
    """Smooth manoeuvre: body rates, and a specific force that carries the velocity vector
    with the body (A = omega x V_b - g_b, so the body velocity obeys AS-KM eq. 18 with only
    small smooth extra accelerations: AoA and sideslip stay small as the heading turns)."""
    omega = np.array(
        [0.15 * math.sin(0.4 * t), 0.04 * math.sin(0.25 * t), 0.05 * math.cos(0.2 * t) + 0.02]
    )
    g = c.GRAVITY_EQUATOR_MPS2
    C = dcm_ned_frd(x[3], x[4], x[5])
    v_b = C.T @ x[:3]
    a_hold = np.cross(omega, v_b) - C.T @ np.array([0.0, 0.0, g])
    a_extra = np.array(
        [0.4 * math.sin(0.3 * t), 0.3 * math.sin(0.35 * t), 0.5 * math.sin(0.45 * t)]
    )
    return np.concatenate([a_hold + a_extra, omega])


@dataclass(frozen=True)
class SynthRun:
    """Arrays at the IMU rate plus the Frames built from them."""

    t_s: Vec  # (K,)
    x_true: Mat  # (K, 6) GS-KM state
    u_true: Mat  # (K, 6) true IMU input u^0
    f_true: Mat  # (K, 6) injected faults
    tas_mps: Vec  # (K,) true airspeed (no wind: = ground speed)
    frames: list[Frame]


def make_run(
    rng: np.random.Generator,
    *,
    duration_s: float = 40.0,
    rate_hz: float = 100.0,
    gps_rate_hz: float = 100.0,
    noise: Lu2016Table1 | None = None,
    faults: bool = True,
    lat0_rad: float = math.radians(52.0),
    alt0_m: float = 1000.0,
    psi0_rad: float = 2.9,
    substeps: int = 4,
) -> SynthRun:
    """Generate one run. The default heading starts near +pi so the yaw wraps during the run."""
    noise = noise or Lu2016Table1()
    dt = 1.0 / rate_hz
    n = int(round(duration_s * rate_hz)) + 1
    eul0 = np.array([0.0, 0.05, psi0_rad])
    v0_ned = dcm_ned_frd(*eul0) @ np.array([60.0, 1.0, 2.0])  # body airspeed: small AoA, sideslip
    x = np.concatenate([v0_ned, eul0])
    lat, alt = lat0_rad, alt0_m
    ts = np.arange(n) * dt
    xs = np.zeros((n, 6))
    us = np.zeros((n, 6))
    lats = np.zeros(n)
    alts = np.zeros(n)
    h = dt / substeps

    def deriv(t: float, z: Vec) -> Vec:
        xx, la, al = z[:6], z[6], z[7]
        rr = c.EARTH_RADIUS_M + al
        return np.concatenate([gs_km_f(xx, _true_input(t, xx), la, al), [xx[0] / rr, -xx[2]]])

    z = np.concatenate([x, [lat, alt]])
    for k in range(n):
        xs[k], lats[k], alts[k] = z[:6], z[6], z[7]
        xs[k, 5] = math.remainder(z[5], 2.0 * math.pi)  # true heading in (-pi, pi]
        us[k] = _true_input(ts[k], z[:6])
        for j in range(substeps):  # RK4
            t = ts[k] + j * h
            k1 = deriv(t, z)
            k2 = deriv(t + h / 2, z + h / 2 * k1)
            k3 = deriv(t + h / 2, z + h / 2 * k2)
            k4 = deriv(t + h, z + h * k3)
            z = z + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    fs = np.array([lu2016_table2_faults(t) if faults else np.zeros(6) for t in ts])
    sig_u = np.array([noise.acc_sigma_mps2] * 3 + [noise.gyro_sigma_radps] * 3)
    u_meas = us + fs + rng.normal(size=(n, 6)) * sig_u
    vel_meas = xs[:, :3] + rng.normal(size=(n, 3)) * noise.vel_sigma_mps
    if gps_rate_hz < rate_hz:  # sample at the GPS rate, then interpolate to the IMU time
        step = int(round(rate_hz / gps_rate_hz))
        idx = np.arange(0, n, step)
        vel_meas = np.stack([np.interp(ts, ts[idx], vel_meas[idx, i]) for i in range(3)], axis=1)
    eul_meas = xs[:, 3:] + rng.normal(size=(n, 3)) * noise.euler_sigma_rad
    eul_meas[:, 2] = np.angle(np.exp(1j * eul_meas[:, 2]))  # ATTITUDE yaw is wrapped
    # air data (no wind): body airspeed = C^T v_ned
    tas = np.linalg.norm(xs[:, :3], axis=1)
    frames = []
    for k in range(n):
        C = dcm_ned_frd(*xs[k, 3:])
        va = C.T @ xs[k, :3]
        aoa = math.atan2(va[2], va[0]) + rng.normal() * noise.aoa_sigma_rad
        ssa = math.asin(va[1] / tas[k]) + rng.normal() * noise.aoa_sigma_rad
        tas_m = tas[k] + rng.normal() * noise.tas_sigma_mps
        t_us = int(round(ts[k] * 1e6))
        frames.append(
            Frame(
                t_us=t_us,
                imu=[ImuSample(t_us, 0, u_meas[k, :3].copy(), u_meas[k, 3:].copy())],
                euler_rad=eul_meas[k].copy(),
                att_age_s=0.0,
                gps_vel_ned_mps=vel_meas[k].copy(),
                gps_age_s=0.0,
                gps_new=True,
                lat_rad=float(lats[k]),
                lon_rad=0.0,
                alt_msl_m=float(alts[k]),
                aoa_rad=np.array([aoa, np.nan, np.nan]),
                aoa_age_s=np.array([0.0, np.inf, np.inf]),
                cas_mps=np.array([cas_from_tas(tas_m, float(alts[k])), np.nan, np.nan]),
                cas_age_s=np.array([0.0, np.inf, np.inf]),
                air_new=True,
                ssa_rad=ssa,
                air_age_s=0.0,
            )
        )
    return SynthRun(t_s=ts, x_true=xs, u_true=us, f_true=fs, tas_mps=tas, frames=frames)
