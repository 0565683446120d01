"""Sensor noise (1-sigma, white Gaussian) and sample rates of the named sensor sets.

Two sets: ``lu2016`` (default, Lu2016 Table 1) and ``atmaca2025`` (Atmaca2025 Table 1). Values
the tables do not give (GPS position, baro altitude, vertical speed, static pressure, OAT, and
Lu2016's rates) are marked *assumed* and chosen as typical of the class of sensor.
"""

from __future__ import annotations

from dataclasses import dataclass

from gcs_monitor.core.units import DEG2RAD


@dataclass(frozen=True, slots=True)
class SensorNoise:
    """1-sigma measurement noise of every channel family (SI)."""

    acc_mps2: float
    gyro_radps: float
    euler_rad: tuple[float, float, float]  # phi, theta, psi
    gps_vel_mps: float
    gps_pos_m: float  # horizontal, per axis
    gps_alt_m: float
    baro_alt_m: float
    vs_mps: float
    aoa_rad: float
    ssa_rad: float
    cas_mps: float
    static_pa: float
    oat_k: float


@dataclass(frozen=True, slots=True)
class SensorRates:
    """Sample rate of each sensor group, Hz."""

    imu_hz: float = 100.0
    attitude_hz: float = 100.0
    gps_hz: float = 10.0
    airdata_hz: float = 20.0
    baro_hz: float = 20.0
    static_hz: float = 10.0


# Assumed values shared by both sets (not in either table).
_GPS_POS_M = 1.5  # assumed: SBAS-class horizontal position noise
_GPS_ALT_M = 2.5  # assumed: vertical ~1.7x horizontal
_BARO_ALT_M = 0.5  # assumed: air-data computer pressure altitude resolution/noise
_STATIC_PA = 5.0  # assumed: consistent with 0.5 m pressure altitude at low level (~12 Pa/m)
_OAT_K = 0.25  # assumed: total-air-temperature probe noise


@dataclass(frozen=True, slots=True)
class SensorSet:
    name: str
    noise: SensorNoise
    rates: SensorRates
    source: str


LU2016 = SensorSet(
    name="lu2016",
    noise=SensorNoise(
        acc_mps2=0.01,  # Lu2016 Table 1 sigma_Ax,Ay,Az
        gyro_radps=0.01 * DEG2RAD,  # Lu2016 Table 1 sigma_p,q,r = 0.01 pi/180
        euler_rad=(0.01 * DEG2RAD,) * 3,  # Lu2016 Table 1 sigma_phi,theta,psi
        gps_vel_mps=0.01,  # Lu2016 Table 1 sigma_UN,UE,UD
        gps_pos_m=_GPS_POS_M,
        gps_alt_m=_GPS_ALT_M,
        baro_alt_m=_BARO_ALT_M,
        vs_mps=0.01,  # assumed equal to Lu2016 Table 1 sigma_UD
        aoa_rad=0.1 * DEG2RAD,  # Lu2016 Table 1 sigma_alpha
        ssa_rad=0.1 * DEG2RAD,  # Lu2016 Table 1 sigma_beta
        cas_mps=0.1,  # Lu2016 Table 1 sigma_V (applied to CAS)
        static_pa=_STATIC_PA,
        oat_k=_OAT_K,
    ),
    # Lu2016 gives no sample rates for its simulation; defaults are the telemetry contract's.
    rates=SensorRates(),
    source="Lu2016 Table 1",
)

ATMACA2025 = SensorSet(
    name="atmaca2025",
    noise=SensorNoise(
        acc_mps2=6.9e-4,  # Atmaca2025 Table 1 A_xm,A_ym,A_zm
        gyro_radps=4.1e-6,  # Atmaca2025 Table 1 p_m,q_m,r_m
        euler_rad=(8.7e-5, 8.7e-5, 1.7e-4),  # Atmaca2025 Table 1 phi_m,theta_m / psi_m
        # Table 1 gives 0.030 m/s for the body-axis ground-speed components; applied per NED axis
        gps_vel_mps=0.030,
        gps_pos_m=_GPS_POS_M,
        gps_alt_m=_GPS_ALT_M,
        baro_alt_m=_BARO_ALT_M,
        vs_mps=0.030,  # assumed equal to the GPS velocity noise
        aoa_rad=2.7e-4,  # Atmaca2025 Table 1 alpha_m, beta_m
        ssa_rad=2.7e-4,
        cas_mps=0.005,  # Atmaca2025 Table 1 V_m
        static_pa=_STATIC_PA,
        oat_k=_OAT_K,
    ),
    # Atmaca2025 Table 1: GPS 10 Hz, everything else 100 Hz.
    rates=SensorRates(imu_hz=100.0, attitude_hz=100.0, gps_hz=10.0, airdata_hz=100.0),
    source="Atmaca2025 Table 1",
)

SENSOR_SETS: dict[str, SensorSet] = {s.name: s for s in (LU2016, ATMACA2025)}
