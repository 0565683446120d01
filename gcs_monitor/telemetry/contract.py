"""The telemetry contract: MAVLink message.field -> Frame field, scale, unit (docs/telemetry.md).

This table is the only place non-SI MAVLink units appear on the monitor side. ``ROWS`` drives
the assembler's conversions and :func:`contract_markdown` renders the documentation table.
"""

from __future__ import annotations

from dataclasses import dataclass

from gcs_monitor.core.units import CM2M, DEG2RAD, DEGE7_2RAD, G2MPS2, HPA2PA, MM2M, MS2US


@dataclass(frozen=True, slots=True)
class Row:
    message: str
    fields: str
    frame_field: str
    scale: float  # multiply the MAVLink value by this to get SI
    offset: float  # then add this
    unit: str  # the MAVLink unit
    rate: str  # default rate sent by sim_vehicle


CDEGC_TO_K = 0.01
ZERO_C_K = 273.15
MG_TO_MPS2 = G2MPS2 / 1000.0  # SCALED_IMU: milli-g
MRAD_TO_RAD = 1.0e-3  # SCALED_IMU: milli-rad/s

ROWS: tuple[Row, ...] = (
    Row("HIGHRES_IMU (id = instance)", "time_usec", "imu[i].t_us", 1.0, 0.0, "µs", "100 Hz"),
    Row("HIGHRES_IMU (id = instance)", "xacc, yacc, zacc", "imu[i].acc_frd_mps2", 1.0, 0.0,
        "m/s² FRD specific force", "100 Hz"),
    Row("HIGHRES_IMU (id = instance)", "xgyro, ygyro, zgyro", "imu[i].omega_frd_radps", 1.0, 0.0,
        "rad/s FRD", "100 Hz"),
    Row("SCALED_IMU/2/3 (fallback, ArduPilot)", "xacc..zacc", "imu[i].acc_frd_mps2", MG_TO_MPS2,
        0.0, "mG", "autopilot"),
    Row("SCALED_IMU/2/3 (fallback, ArduPilot)", "xgyro..zgyro", "imu[i].omega_frd_radps",
        MRAD_TO_RAD, 0.0, "mrad/s", "autopilot"),
    Row("ATTITUDE", "time_boot_ms", "att_t_us", MS2US, 0.0, "ms", "100 Hz"),
    Row("ATTITUDE", "roll, pitch, yaw", "euler_rad", 1.0, 0.0, "rad (ZYX Euler)", "100 Hz"),
    Row("GLOBAL_POSITION_INT", "time_boot_ms", "gps_t_us", MS2US, 0.0, "ms", "GPS rate (10 Hz)"),
    Row("GLOBAL_POSITION_INT", "lat, lon", "lat_rad, lon_rad", DEGE7_2RAD, 0.0, "degE7",
        "GPS rate"),
    Row("GLOBAL_POSITION_INT", "alt", "alt_msl_m", MM2M, 0.0, "mm", "GPS rate"),
    Row("GLOBAL_POSITION_INT", "vx, vy, vz", "gps_vel_ned_mps (interpolated)", CM2M, 0.0,
        "cm/s NED", "GPS rate"),
    Row("AIRSPEED (id = instance)", "airspeed", "cas_mps[i]", 1.0, 0.0, "m/s CAS", "20 Hz"),
    Row("AIRSPEED (id = instance)", "temperature", "oat_k", CDEGC_TO_K, ZERO_C_K, "cdegC",
        "20 Hz"),
    Row("AOA_SSA", "AOA", "aoa_rad[0]", DEG2RAD, 0.0, "deg", "20 Hz"),
    Row("AOA_SSA", "SSA", "ssa_rad", DEG2RAD, 0.0, "deg", "20 Hz"),
    Row("NAMED_VALUE_FLOAT AOA1, AOA2 (convention)", "value", "aoa_rad[1], aoa_rad[2]", DEG2RAD,
        0.0, "deg", "20 Hz"),
    Row("VFR_HUD", "alt", "baro_alt_m", 1.0, 0.0, "m", "20 Hz"),
    Row("VFR_HUD", "climb", "climb_mps", 1.0, 0.0, "m/s up", "20 Hz"),
    Row("SCALED_PRESSURE", "press_abs", "static_pressure_pa", HPA2PA, 0.0, "hPa", "10 Hz"),
    Row("SCALED_PRESSURE", "temperature", "oat_k", CDEGC_TO_K, ZERO_C_K, "cdegC", "10 Hz"),
    Row("DEBUG_FLOAT_ARRAY SURF (convention)", "data[3k+0]", "surf_cmd_rad[k]", 1.0, 0.0,
        "rad", "50 Hz"),
    Row("DEBUG_FLOAT_ARRAY SURF (convention)", "data[3k+1]", "surf_pos_rad[k]", 1.0, 0.0,
        "rad", "50 Hz"),
    Row("DEBUG_FLOAT_ARRAY SURF (convention)", "data[3k+2]", "rod_pos_m[k]", 1.0, 0.0, "m",
        "50 Hz"),
)

# Physical-range limits: a value outside is counted as bad and dropped (never a fault alarm).
MAX_ACC_MPS2 = 300.0  # ~30 g: beyond any airframe, inside a catapult stroke (Zipline ~7 g)
MAX_RATE_RADPS = 35.0  # ~2000 deg/s, the usual MEMS gyro range
MAX_SPEED_MPS = 400.0
MAX_AOA_RAD = 1.6
MAX_ALT_M = 30_000.0
MIN_ALT_M = -1_000.0


def contract_markdown() -> str:
    """The contract as a Markdown table (kept in docs/telemetry.md)."""
    lines = ["| message | field(s) | Frame field | MAVLink unit | scale to SI | rate |",
             "|---|---|---|---|---|---|"]
    for r in ROWS:
        scale = f"× {r.scale:g}" + (f" + {r.offset:g}" if r.offset else "")
        lines.append(f"| {r.message} | {r.fields} | `{r.frame_field}` | {r.unit} | {scale} | "
                     f"{r.rate} |")
    return "\n".join(lines)
