"""Synthetic truth for the Wan2018 air-data tests, independent of ``sim_vehicle``.

Transport-aircraft longitudinal kinematics (exact body-axis equations, Wan2018 eq. 5 with
``v = p = r = phi = psi = 0``, *not* the approximated model under test) driven by a lift-curve
point-mass autopilot, with wind = constant + altitude shear + smooth turbulence (sum of
sines, so the wind acceleration of eq. 5 is defined), triplex AoA/CAS sensors with noise and
Wan2018 Table II faults, and Frames at 100 Hz IMU / 20 Hz air data. Heading is north.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from gcs_monitor.core.atmosphere import cas_from_tas, isa_density_kgpm3
from gcs_monitor.core.constants import GRAVITY_STD_MPS2 as G
from gcs_monitor.core.units import DEG2RAD, KT2MPS
from gcs_monitor.telemetry.frame import Frame, ImuSample


@dataclass(frozen=True)
class SensorFault:
    """One Wan2018 Table II fault on one sensor instance (additive, eq. 4)."""

    kind: str  # "aoa" or "cas"
    instance: int
    t_start_s: float
    profile: str  # "runaway", "bias", "jam", "oscillation"
    value: float  # rate (SI/s) for runaway, amplitude (SI) otherwise
    freq_hz: float = 0.0

    def offset(self, t_s: float, true_value: float, jam_value: float) -> float:
        dt = t_s - self.t_start_s
        if dt < 0.0:
            return 0.0
        if self.profile == "runaway":
            return self.value * dt
        if self.profile == "bias":
            return self.value
        if self.profile == "jam":
            return jam_value - true_value
        if self.profile == "oscillation":
            return self.value * math.sin(2.0 * math.pi * self.freq_hz * dt)
        raise ValueError(f"unknown fault profile {self.profile!r}")


@dataclass(frozen=True)
class SynthConfig:
    duration_s: float = 60.0
    dt_imu_s: float = 0.01  # 100 Hz IMU / Frames
    air_every: int = 5  # air data at 20 Hz
    tas_kt: float = 250.0  # Wan2018: 160-360 kts
    alt_m: float = 1524.0  # 5000 ft (Wan2018 sec. VI-A)
    wind_x0_mps: float = -10.0  # constant wind, north (negative = headwind)
    wind_z0_mps: float = 0.0  # down
    shear_x_per_s: float = 0.004  # dW_x/dh (1/s)
    turb_sigma_mps: float = 1.0
    doublet_deg: float = 2.0  # pitch doublet at t = 10 s, 5 s per half
    wing_loading_npm2: float = 5000.0
    cl_alpha_per_rad: float = 5.5
    alpha0_rad: float = -0.035
    aoa_sigma_rad: float = 0.1 * DEG2RAD
    cas_sigma_mps: float = 0.5
    acc_sigma_mps2: float = 0.02
    gyro_sigma_radps: float = 2.0e-4
    theta_sigma_rad: float = 0.05 * DEG2RAD
    gps_vel_sigma_mps: float = 0.05
    baro_sigma_m: float = 0.5
    faults: tuple[SensorFault, ...] = ()


@dataclass
class SynthRun:
    frames: list[Frame]
    t_air_s: np.ndarray  # times of the air-data frames
    aoa_true_rad: np.ndarray
    cas_true_mps: np.ndarray
    wind_true_mps: np.ndarray  # (n_air, 2) [W_x, W_z down]
    air_frame_index: np.ndarray
    meta: dict[str, float] = field(default_factory=dict)


class _Turbulence:
    """Smooth turbulence: a sum of sines with seeded random frequencies and phases."""

    def __init__(self, rng: np.random.Generator, sigma: float, n: int = 6) -> None:
        self.w = 2.0 * math.pi * rng.uniform(0.02, 0.5, n)
        self.ph = rng.uniform(0.0, 2.0 * math.pi, n)
        self.a = np.full(n, sigma * math.sqrt(2.0 / n))

    def value_rate(self, t: float) -> tuple[float, float]:
        arg = self.w * t + self.ph
        return float(np.sum(self.a * np.sin(arg))), float(np.sum(self.a * self.w * np.cos(arg)))


def generate(cfg: SynthConfig, rng: np.random.Generator) -> SynthRun:
    """Integrate the truth (RK4 at the IMU rate) and sample the sensors."""
    tx, tz = _Turbulence(rng, cfg.turb_sigma_mps), _Turbulence(rng, 0.5 * cfg.turb_sigma_mps)
    v0 = cfg.tas_kt * KT2MPS
    h0 = cfg.alt_m

    def qbar(v: float, h: float) -> float:
        return 0.5 * isa_density_kgpm3(h) * v * v

    alpha_trim = cfg.alpha0_rad + cfg.wing_loading_npm2 / (qbar(v0, h0) * cfg.cl_alpha_per_rad)

    def wind(t: float, h: float, hdot: float) -> tuple[float, float, float, float]:
        ux, ux_dot = tx.value_rate(t)
        uz, uz_dot = tz.value_rate(t)
        wx = cfg.wind_x0_mps + cfg.shear_x_per_s * (h - h0) + ux
        return wx, cfg.wind_z0_mps + uz, cfg.shear_x_per_s * hdot + ux_dot, uz_dot

    def controls(t: float, s: np.ndarray) -> tuple[float, float, float]:
        u, w, th, _, h = s
        v = math.hypot(u, w)
        alpha = math.atan2(w, u)
        hdot = math.sin(th) * u - math.cos(th) * w  # approx (wind z small), only for damping
        dbl = 0.0
        if 10.0 <= t < 15.0:
            dbl = cfg.doublet_deg * DEG2RAD
        elif 15.0 <= t < 20.0:
            dbl = -cfg.doublet_deg * DEG2RAD
        th_cmd = alpha_trim + dbl + 0.002 * (h0 - h) - 0.01 * hdot
        q = 0.8 * (th_cmd - th)
        az = (
            -qbar(v, h)
            * cfg.cl_alpha_per_rad
            * (alpha - cfg.alpha0_rad)
            / cfg.wing_loading_npm2
            * G
        )
        ax = G * math.sin(th) + q * w + 0.3 * (v0 - v)
        return q, ax, az

    def deriv(t: float, s: np.ndarray) -> np.ndarray:
        u, w, th, _, h = s
        q, ax, az = controls(t, s)
        # ground velocity needs the wind, the wind rate needs h_dot: W at (t, h) first
        wx, wz, _, _ = wind(t, h, 0.0)
        vx = math.cos(th) * u + math.sin(th) * w + wx
        vd = -math.sin(th) * u + math.cos(th) * w + wz
        _, _, wxd, wzd = wind(t, h, -vd)
        du = ax - G * math.sin(th) - q * w - (wxd * math.cos(th) - wzd * math.sin(th))
        dw = az + G * math.cos(th) + q * u - (wxd * math.sin(th) + wzd * math.cos(th))
        return np.array([du, dw, q, vx, -vd])

    n_steps = int(round(cfg.duration_s / cfg.dt_imu_s))
    s = np.array([v0 * math.cos(alpha_trim), v0 * math.sin(alpha_trim), alpha_trim, 0.0, h0])
    frames: list[Frame] = []
    t_air, aoa_t, cas_t, wind_t, idx = [], [], [], [], []
    jam_aoa = np.full(3, np.nan)
    jam_cas = np.full(3, np.nan)
    for k in range(n_steps):
        t = k * cfg.dt_imu_s
        u, w, th, _, h = s
        q, ax, az = controls(t, s)
        wx, wz, _, _ = wind(t, h, 0.0)
        vx = math.cos(th) * u + math.sin(th) * w + wx
        vd = -math.sin(th) * u + math.cos(th) * w + wz
        t_us = int(round(t * 1e6))
        imu = ImuSample(
            t_us=t_us,
            instance=0,
            acc_frd_mps2=np.array([ax, 0.0, az]) + cfg.acc_sigma_mps2 * rng.standard_normal(3),
            omega_frd_radps=np.array([0.0, q, 0.0]) + cfg.gyro_sigma_radps * rng.standard_normal(3),
        )
        fr = Frame(
            t_us=t_us,
            imu=[imu],
            euler_rad=np.array([0.0, th + cfg.theta_sigma_rad * rng.standard_normal(), 0.0]),
            att_age_s=0.0,
            gps_vel_ned_mps=np.array([vx, 0.0, vd])
            + cfg.gps_vel_sigma_mps * rng.standard_normal(3),
            gps_age_s=0.0,
            gps_new=True,
            alt_msl_m=h,
        )
        if k % cfg.air_every == 0:
            alpha = math.atan2(w, u)
            cas = cas_from_tas(math.hypot(u, w), h)
            aoa_m = alpha + cfg.aoa_sigma_rad * rng.standard_normal(3)
            cas_m = cas + cfg.cas_sigma_mps * rng.standard_normal(3)
            for f in cfg.faults:
                if f.kind == "aoa":
                    if t >= f.t_start_s and np.isnan(jam_aoa[f.instance]):
                        jam_aoa[f.instance] = aoa_m[f.instance]
                    aoa_m[f.instance] += f.offset(t, alpha, jam_aoa[f.instance])
                else:
                    if t >= f.t_start_s and np.isnan(jam_cas[f.instance]):
                        jam_cas[f.instance] = cas_m[f.instance]
                    cas_m[f.instance] += f.offset(t, cas, jam_cas[f.instance])
            fr.aoa_rad, fr.cas_mps = aoa_m, cas_m
            fr.aoa_age_s, fr.cas_age_s = np.zeros(3), np.zeros(3)
            fr.air_new, fr.air_age_s = True, 0.0
            # as the telemetry assembler reports it: the measured period of the air stream
            fr.air_period_s = round(cfg.air_every * cfg.dt_imu_s * 1e6) / 1e6
            fr.baro_alt_m = h + cfg.baro_sigma_m * rng.standard_normal()
            fr.climb_mps = -vd
            t_air.append(t)
            aoa_t.append(alpha)
            cas_t.append(cas)
            wind_t.append((wx, wz))
            idx.append(k)
        frames.append(fr)
        # RK4
        dt = cfg.dt_imu_s
        k1 = deriv(t, s)
        k2 = deriv(t + dt / 2, s + dt / 2 * k1)
        k3 = deriv(t + dt / 2, s + dt / 2 * k2)
        k4 = deriv(t + dt, s + dt * k3)
        s = s + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return SynthRun(
        frames=frames,
        t_air_s=np.array(t_air),
        aoa_true_rad=np.array(aoa_t),
        cas_true_mps=np.array(cas_t),
        wind_true_mps=np.array(wind_t),
        air_frame_index=np.array(idx),
        meta={"alpha_trim_rad": alpha_trim},
    )
