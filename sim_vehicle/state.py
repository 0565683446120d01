"""The true state the physics publishes each output step; sensors, faults and truth read it.

This is the interface between ``sim_vehicle.dynamics``/``autopilot``/``actuators`` (which
produce it) and ``sim_vehicle.sensors``/``faults``/``truth``/``mavlink_out`` (which consume it).
All SI, NED earth frame, FRD body frame.
"""

from __future__ import annotations

from dataclasses import dataclass

from gcs_monitor.core.types import Vec, Vec3


@dataclass(frozen=True, slots=True)
class TrueState:
    t_s: float  # simulation time since boot, s
    lat_rad: float
    lon_rad: float
    alt_m: float  # geometric altitude above the sphere (= MSL here), m
    vel_ned_mps: Vec3  # (3,) ground velocity NED
    euler_rad: Vec3  # (3,) [phi, theta, psi]
    omega_frd_radps: Vec3  # (3,) body rates
    acc_frd_mps2: Vec3  # (3,) specific force (what a perfect accelerometer reads), body FRD
    wind_ned_mps: Vec3  # (3,) total wind (mean + shear + turbulence) at the aircraft
    tas_mps: float
    aoa_rad: float
    ssa_rad: float
    pressure_alt_m: float  # ISA pressure altitude (what a perfect baro reads)
    static_pressure_pa: float
    oat_k: float
    cas_mps: float  # true calibrated airspeed (Wan2018 eq. 16 from tas and pressure altitude)
    surf_cmd_rad: Vec  # (3,) commanded aileron, elevator, rudder deflection
    surf_pos_rad: Vec  # (3,) actual deflection (after the Lu2017 servo, incl. actuator faults)
    rod_pos_m: Vec  # (3,) servo rod position (Lu2017)
    throttle: float  # 0..1, the engine's state (lags the command)
    # the autopilot's commands (published as NAV_CONTROLLER_OUTPUT / ATTITUDE_TARGET / VFR_HUD)
    throttle_cmd: float = 0.0  # 0..1
    att_cmd_rad: Vec3 | None = None  # (3,) commanded [phi, theta, psi]
    rate_cmd_radps: Vec3 | None = None  # (3,) commanded body rates [p, q, r]
    alt_cmd_m: float = 0.0
    tas_cmd_mps: float = 0.0
    # actuator health (truth): share of the nominal effect of the aileron, elevator, rudder
    # and engine (1 healthy, 0 none; a stuck surface is in surf_pos_rad, not here)
    effectiveness: Vec | None = None  # (4,)
