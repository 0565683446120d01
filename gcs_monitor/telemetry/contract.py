"""The telemetry contract: MAVLink message.field -> Frame field, scale, unit (docs/telemetry.md).

This module is the only place on the monitor side where non-SI MAVLink units (degE7, mm, cm/s,
hPa, cdegC, deg, mG, mrad/s) appear. The scale constants below are what the assembler multiplies
by (SI = raw * scale + offset); :data:`ROWS` uses the same constants and renders the
documentation table (:func:`contract_markdown`); a test checks that ``docs/telemetry.md`` carries
exactly that table, and a round-trip test checks every numeric row through the assembler.

Frames: body axes are FRD, navigation axes NED, Euler angles ZYX (NED -> FRD). ArduPilot's
SCALED_IMU/RAW_IMU are already FRD (ArduPilot body frame is X forward, Y right, Z down), so the
fallback IMU path only rescales.
"""

from __future__ import annotations

from dataclasses import dataclass

from gcs_monitor.core.constants import GRAVITY_STD_MPS2
from gcs_monitor.core.units import CM2M, DEG2RAD, DEGE7_2RAD, HPA2PA, MM2M, MS2US

# --- scale factors (SI = raw * scale + offset) -------------------------------------------------
US_SCALE = 1  # time_usec is already µs (int)
MS_TO_US = MS2US  # time_boot_ms -> µs (int)
DEGE7_TO_RAD = DEGE7_2RAD
MM_TO_M = MM2M
CMPS_TO_MPS = CM2M
DEG_TO_RAD = DEG2RAD
HPA_TO_PA = HPA2PA
CDEGC_TO_K = 0.01  # centi-degC -> K (scale), then + ZERO_C_K
ZERO_C_K = 273.15
MG_TO_MPS2 = GRAVITY_STD_MPS2 / 1000.0  # SCALED_IMU / ArduPilot RAW_IMU: milli-g
MRAD_TO_RAD = 1.0e-3  # SCALED_IMU / ArduPilot RAW_IMU: milli-rad/s
PCT_TO_FRAC = 0.01  # VFR_HUD throttle: percent -> 0..1
PWM_CENTER_US = 1500.0  # SERVO_OUTPUT_RAW: normalised output = (pwm - centre) / half range
PWM_HALF_RANGE_US = 500.0
PWM_UNUSED = (0, 65535)  # an output channel the autopilot does not drive

# --- plausibility limits: a value outside is counted as a bad value and dropped ------------------
# These are link-integrity limits (physically impossible for any airframe we monitor), not fault
# thresholds: a sensor fault inside these limits is the estimators' business, never dropped here.
MAX_ACC_MPS2 = 300.0  # ~30 g: beyond any airframe, inside a catapult stroke (Zipline ~7 g)
MAX_RATE_RADPS = 35.0  # ~2000 deg/s, the usual MEMS gyro full scale
MAX_SPEED_MPS = 400.0  # GPS velocity component, airspeed, climb rate
MAX_ANGLE_RAD = 7.0  # |Euler angle| (2 pi plus margin: yaw may be reported in [0, 2 pi))
MAX_AOA_RAD = 1.6  # |AoA| / |sideslip| (~90 deg)
MAX_ALT_M = 30_000.0
MIN_ALT_M = -1_000.0
MIN_PRESSURE_PA = 1_000.0
MAX_PRESSURE_PA = 120_000.0
MIN_OAT_K = 150.0
MAX_OAT_K = 350.0
MAX_SURF_RAD = 1.6
MAX_ROD_M = 1.0
MAX_PWM_US = 3000.0  # any servo pulse (RC servos: 800-2200 µs)
MAX_DIST_M = 1.0e6  # waypoint distance, cross-track error


@dataclass(frozen=True, slots=True)
class Row:
    """One line of the contract table.

    ``scale``/``offset`` are None for rows that carry no numeric conversion (flags, display).
    """

    message: str
    fields: str
    frame_field: str
    conversion: str
    rate: str = ""
    scale: float | None = None
    offset: float = 0.0


_HR = "HIGHRES_IMU (`id` = instance 0..2)"
_GPI = "GLOBAL_POSITION_INT"
_ASPD = "AIRSPEED (`id` = instance 0..2)"
_SIMU = "SCALED_IMU / SCALED_IMU2 / SCALED_IMU3 **(fallback)**"
_RIMU = "RAW_IMU **(fallback, ArduPilot only)**"
_SURF = "DEBUG_FLOAT_ARRAY `SURF` array_id 0 **(convention)**"

ROWS: tuple[Row, ...] = (
    Row("HEARTBEAT", "type, autopilot, base_mode", "vehicle type, armed", "-", "1 Hz"),
    Row(_HR, "time_usec", "`imu[i].t_us`", "µs", "100 Hz per instance", US_SCALE),
    Row("", "xacc, yacc, zacc", "`imu[i].acc_frd_mps2`", "m/s², body FRD specific force", "",
        1.0),
    Row("", "xgyro, ygyro, zgyro", "`imu[i].omega_frd_radps`", "rad/s, body FRD", "", 1.0),
    Row(_SIMU, "time_boot_ms", "`imu[i].t_us` (i = 0, 1, 2)", "ms → µs", "autopilot rate",
        MS_TO_US),
    Row("", "xacc, yacc, zacc", "`imu[i].acc_frd_mps2`", "mG → m/s², FRD", "", MG_TO_MPS2),
    Row("", "xgyro, ygyro, zgyro", "`imu[i].omega_frd_radps`", "mrad/s → rad/s, FRD", "",
        MRAD_TO_RAD),
    Row(_RIMU, "time_usec", "`imu[0].t_us`", "µs", "autopilot rate", US_SCALE),
    Row("", "xacc, yacc, zacc", "`imu[0].acc_frd_mps2`", "mG → m/s², FRD", "", MG_TO_MPS2),
    Row("", "xgyro, ygyro, zgyro", "`imu[0].omega_frd_radps`", "mrad/s → rad/s, FRD", "",
        MRAD_TO_RAD),
    Row("ATTITUDE", "time_boot_ms", "`att_t_us`", "ms → µs", "100 Hz", MS_TO_US),
    Row("", "roll, pitch, yaw", "`euler_rad` = [φ, θ, ψ]", "rad, ZYX Euler NED→FRD", "", 1.0),
    Row("", "rollspeed, pitchspeed, yawspeed", "`att_rate_frd_radps` = [p, q, r]",
        "rad/s, body FRD (the autopilot's estimate)", "", 1.0),
    Row(_GPI, "time_boot_ms", "`gps_t_us`", "ms → µs", "GPS rate (10 Hz; 1-10 Hz)", MS_TO_US),
    Row("", "lat, lon", "`lat_rad`, `lon_rad`", "degE7 → rad", "", DEGE7_TO_RAD),
    Row("", "alt", "`alt_msl_m`", "mm → m", "", MM_TO_M),
    Row("", "vx, vy, vz", "`gps_vel_ned_mps`",
        "cm/s → m/s, NED (interpolated to the IMU rate by the monitor)", "", CMPS_TO_MPS),
    Row("GPS_RAW_INT", "fix_type, satellites_visible", "`gps_fix`", "-", "GPS rate"),
    Row(_ASPD, "airspeed", "`cas_mps[i]`", "m/s, calibrated airspeed", "20 Hz per instance",
        1.0),
    Row("", "raw_press", "(diagnostic) impact pressure", "hPa → Pa", "", HPA_TO_PA),
    Row("", "temperature", "`oat_k`", "cdegC → K", "", CDEGC_TO_K, ZERO_C_K),
    Row("AOA_SSA", "time_usec", "`air_t_us`", "µs", "20 Hz", US_SCALE),
    Row("", "AOA", "`aoa_rad[0]` (vane 0)", "deg → rad", "", DEG_TO_RAD),
    Row("", "SSA", "`ssa_rad` (sideslip vane)", "deg → rad", "", DEG_TO_RAD),
    Row("NAMED_VALUE_FLOAT `AOA1`, `AOA2` **(convention)**", "value",
        "`aoa_rad[1]`, `aoa_rad[2]` (vanes 1, 2)", "deg → rad", "20 Hz", DEG_TO_RAD),
    Row("VFR_HUD", "alt", "`baro_alt_m`", "m, barometric (pressure) altitude", "20 Hz", 1.0),
    Row("", "climb", "`climb_mps`", "m/s, positive up (= −v_D)", "", 1.0),
    Row("", "airspeed, groundspeed", "`hud.airspeed_mps`, `hud.groundspeed_mps`",
        "m/s (airspeed as the autopilot shows it)", "", 1.0),
    Row("", "heading", "`hud.heading_rad`", "deg → rad", "", DEG_TO_RAD),
    Row("", "throttle", "`hud.throttle`", "% → 0..1", "", PCT_TO_FRAC),
    Row("SCALED_PRESSURE", "press_abs, temperature", "`static_pressure_pa`, `oat_k`",
        "hPa → Pa, cdegC → K", "10 Hz", HPA_TO_PA),
    Row("SERVO_OUTPUT_RAW (`port` 0)", "servo1_raw .. servo16_raw",
        "`servo.pwm_us[k]` (k = channel − 1)",
        "PWM µs; 0 and 65535 (unused) → NaN", "10 Hz", 1.0),
    Row("", "servo1_raw .. servo16_raw", "`servo.norm[k]`",
        "(PWM − 1500 µs) / 500 µs, dimensionless", ""),
    Row("NAV_CONTROLLER_OUTPUT", "nav_roll, nav_pitch", "`nav.nav_roll_rad`, `nav.nav_pitch_rad`",
        "deg → rad, commanded bank and pitch", "10 Hz", DEG_TO_RAD),
    Row("", "nav_bearing, target_bearing", "`nav.nav_bearing_rad`, `nav.target_bearing_rad`",
        "deg → rad", "", DEG_TO_RAD),
    Row("", "wp_dist, alt_error, xtrack_error", "`nav.wp_dist_m`, `nav.alt_error_m`, "
        "`nav.xtrack_error_m`", "m", "", 1.0),
    Row("", "aspd_error", "`nav.aspd_error_mps`", "m/s (MAVLink; ArduPlane logs cm/s: the "
        "log readers convert)", "", 1.0),
    Row("ATTITUDE_TARGET", "time_boot_ms", "`att_target.t_us`", "ms → µs", "10 Hz", MS_TO_US),
    Row("", "q (type_mask bit 7 clear)", "`att_target.euler_rad`",
        "quaternion NED→FRD → ZYX Euler, rad", "", 1.0),
    Row("", "body_roll_rate, body_pitch_rate, body_yaw_rate (bits 0-2 clear)",
        "`att_target.rate_frd_radps`", "rad/s, body FRD", "", 1.0),
    Row("", "thrust (bit 6 clear)", "`att_target.thrust`", "0..1", "", 1.0),
    Row(_SURF, "data[3k+0]", "`surf_cmd_rad[k]`", "rad, commanded surface deflection", "50 Hz",
        1.0),
    Row("", "data[3k+1]", "`surf_pos_rad[k]`", "rad, measured surface deflection", "", 1.0),
    Row("", "data[3k+2]", "`rod_pos_m[k]`", "m, measured servo rod position (Lu2017)", "", 1.0),
)

TABLE_HEADER = ("| message | field | Frame field | conversion | scale to SI | default rate |\n"
                "|---|---|---|---|---|---|")


def _fmt_scale(r: Row) -> str:
    if r.scale is None:
        return "-"
    s = f"× {r.scale:.10g}"
    return s + (f" + {r.offset:g}" if r.offset else "")


def contract_markdown() -> str:
    """The contract as the Markdown table kept in docs/telemetry.md (no trailing newline)."""
    lines = [TABLE_HEADER]
    for r in ROWS:
        lines.append(f"| {r.message} | {r.fields} | {r.frame_field} | {r.conversion} | "
                     f"{_fmt_scale(r)} | {r.rate} |")
    return "\n".join(lines)
