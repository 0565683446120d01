"""Encode SI telemetry into MAVLink 2 packets per the telemetry contract (docs/telemetry.md).

The inverse of ``gcs_monitor.telemetry.contract``: SI/NED/FRD in, contract units out. Used by the
real-data converters; values are converted at this boundary only.
"""

from __future__ import annotations

import math
import os
import struct
from pathlib import Path
from types import TracebackType
from typing import BinaryIO

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from gcs_monitor.core.units import CM2M, RAD2DEG, RAD2DEGE7

TLOG_EPOCH_US = 1_700_000_000_000_000  # fixed wall epoch so converted tlogs are reproducible


class _Sink:
    """File-like that collects the bytes pymavlink writes."""

    def __init__(self) -> None:
        self.buf = b""

    def write(self, data: bytes) -> None:
        self.buf += data


class Packer:
    """Packs MAVLink 2 messages as one sender (sysid, compid), sequence numbers counted.

    The one place the converters and log readers turn message objects into bytes.
    """

    def __init__(self, *, sysid: int = 1, compid: int = 1) -> None:
        self._mav = mavlink.MAVLink(_Sink(), srcSystem=sysid, srcComponent=compid)
        self._mav.robust_parsing = True
        self.count: dict[str, int] = {}

    def pack(self, msg: mavlink.MAVLink_message) -> bytes:
        packet = bytes(msg.pack(self._mav))
        self._mav.seq = (self._mav.seq + 1) % 256
        name = msg.get_type()
        self.count[name] = self.count.get(name, 0) + 1
        return packet


# -- contract messages from SI values (the inverse of telemetry/contract.py) ---------------------
# Every function takes SI / NED / FRD values and returns one message in contract units; the
# log readers (dataflash.py, ulog.py) convert their log's units to SI and call these.

def _i16(x: float) -> int:
    return max(-32768, min(32767, int(round(x))))


def _u16(x: float) -> int:
    return max(0, min(65535, int(round(x))))


def heartbeat_msg(*, mav_type: int, autopilot: int, armed: bool = False) -> mavlink.MAVLink_message:
    base = mavlink.MAV_MODE_FLAG_SAFETY_ARMED if armed else 0
    return mavlink.MAVLink_heartbeat_message(mav_type, autopilot, base, 0,
                                             mavlink.MAV_STATE_ACTIVE, 3)


def highres_imu_msg(t_us: int, instance: int, acc_frd_mps2: tuple[float, float, float],
                    omega_frd_radps: tuple[float, float, float], *,
                    abs_pressure_pa: float = 0.0, temperature_k: float = 273.15,
                    ) -> mavlink.MAVLink_message:
    ax, ay, az = acc_frd_mps2
    p, q, r = omega_frd_radps
    return mavlink.MAVLink_highres_imu_message(
        t_us, ax, ay, az, p, q, r, 0.0, 0.0, 0.0, abs_pressure_pa / 100.0, 0.0, 0.0,
        temperature_k - 273.15, 0b111111, instance)


def attitude_msg(t_us: int, euler_rad: tuple[float, float, float],
                 omega_frd_radps: tuple[float, float, float] = (0.0, 0.0, 0.0),
                 ) -> mavlink.MAVLink_message:
    phi, theta, psi = euler_rad
    p, q, r = omega_frd_radps
    return mavlink.MAVLink_attitude_message(t_us // 1000, phi, theta, psi, p, q, r)


def global_position_msg(t_us: int, lat_rad: float, lon_rad: float, alt_msl_m: float,
                        alt_rel_m: float, vel_ned_mps: tuple[float, float, float],
                        ) -> mavlink.MAVLink_message:
    vn, ve, vd = vel_ned_mps
    hdg = int(round((math.degrees(math.atan2(ve, vn)) % 360.0) * 100)) % 36000
    return mavlink.MAVLink_global_position_int_message(
        t_us // 1000, int(round(lat_rad * RAD2DEGE7)), int(round(lon_rad * RAD2DEGE7)),
        int(round(alt_msl_m * 1000)), int(round(alt_rel_m * 1000)), _cms(vn), _cms(ve),
        _cms(vd), hdg)


def gps_raw_msg(t_us: int, fix_type: int, lat_rad: float, lon_rad: float, alt_msl_m: float,
                vel_ned_mps: tuple[float, float, float], satellites: int = 255,
                ) -> mavlink.MAVLink_message:
    vn, ve, _ = vel_ned_mps
    cog = int(round((math.degrees(math.atan2(ve, vn)) % 360.0) * 100)) % 36000
    return mavlink.MAVLink_gps_raw_int_message(
        t_us, fix_type, int(round(lat_rad * RAD2DEGE7)), int(round(lon_rad * RAD2DEGE7)),
        int(round(alt_msl_m * 1000)), 65535, 65535, _u16(math.hypot(vn, ve) / CM2M), cog,
        min(255, max(0, satellites)))


def airspeed_msg(instance: int, cas_mps: float, *, oat_k: float = math.nan,
                 impact_pressure_pa: float = math.nan) -> mavlink.MAVLink_message:
    temp = _i16((oat_k - 273.15) * 100) if math.isfinite(oat_k) else 0
    raw = impact_pressure_pa / 100.0 if math.isfinite(impact_pressure_pa) else 0.0
    return mavlink.MAVLink_airspeed_message(instance, cas_mps, temp, raw, 0)


def aoa_ssa_msg(t_us: int, aoa_rad: float, ssa_rad: float) -> mavlink.MAVLink_message:
    return mavlink.MAVLink_aoa_ssa_message(t_us, aoa_rad * RAD2DEG, ssa_rad * RAD2DEG)


def vfr_hud_msg(*, cas_mps: float, groundspeed_mps: float, heading_rad: float,
                baro_alt_m: float, climb_mps: float, throttle: float = 0.0,
                ) -> mavlink.MAVLink_message:
    return mavlink.MAVLink_vfr_hud_message(
        cas_mps, groundspeed_mps, int(round(math.degrees(heading_rad) % 360.0)) % 360,
        _u16(throttle * 100), baro_alt_m, climb_mps)


def scaled_pressure_msg(t_us: int, static_pressure_pa: float, oat_k: float,
                        ) -> mavlink.MAVLink_message:
    return mavlink.MAVLink_scaled_pressure_message(
        t_us // 1000, static_pressure_pa / 100.0, 0.0, _i16((oat_k - 273.15) * 100))


def servo_output_msg(t_us: int, pwm_us: list[float], *, port: int = 0,
                     ) -> mavlink.MAVLink_message:
    """SERVO_OUTPUT_RAW: up to 16 outputs in PWM µs (0 where absent)."""
    v = [_u16(x) if math.isfinite(x) else 0 for x in pwm_us[:16]]
    v += [0] * (16 - len(v))
    return mavlink.MAVLink_servo_output_raw_message(t_us & 0xFFFFFFFF, port, *v)


def nav_controller_msg(*, nav_roll_rad: float, nav_pitch_rad: float, nav_bearing_rad: float = 0.0,
                       target_bearing_rad: float = 0.0, wp_dist_m: float = 0.0,
                       alt_error_m: float = 0.0, aspd_error_mps: float = 0.0,
                       xtrack_error_m: float = 0.0) -> mavlink.MAVLink_message:
    """NAV_CONTROLLER_OUTPUT (deg, deg, cdeg-free integer degrees, m, m, m/s, m)."""

    def f(x: float) -> float:
        return x if math.isfinite(x) else 0.0

    return mavlink.MAVLink_nav_controller_output_message(
        f(nav_roll_rad) * RAD2DEG, f(nav_pitch_rad) * RAD2DEG,
        _i16(f(nav_bearing_rad) * RAD2DEG), _i16(f(target_bearing_rad) * RAD2DEG),
        _u16(f(wp_dist_m)), f(alt_error_m), f(aspd_error_mps), f(xtrack_error_m))


def attitude_target_msg(t_us: int, q_ned_frd: tuple[float, float, float, float], *,
                        thrust: float = 0.0) -> mavlink.MAVLink_message:
    """ATTITUDE_TARGET: attitude setpoint quaternion (scalar first), body rates ignored."""
    ignore_rates = 0b0000_0111
    return mavlink.MAVLink_attitude_target_message(
        t_us // 1000, ignore_rates, list(q_ned_frd), 0.0, 0.0, 0.0,
        thrust if math.isfinite(thrust) else 0.0)


class TlogEncoder:
    """Writes contract messages as a .tlog (8-byte big-endian µs timestamp + packet).

    Parameters
    ----------
    path : output .tlog; written to ``path.tmp`` and renamed on close, so nothing is written half
    sysid : MAVLink system id of the vehicle
    """

    def __init__(self, path: Path, *, sysid: int = 1, compid: int = 1) -> None:
        self.path = Path(path)
        self._tmp = self.path.with_suffix(self.path.suffix + ".tmp")
        self._fh: BinaryIO = open(self._tmp, "wb")  # noqa: SIM115 - closed in close()
        self._mav = mavlink.MAVLink(_Sink(), srcSystem=sysid, srcComponent=compid)
        self._mav.robust_parsing = True
        self.count: dict[str, int] = {}

    def _emit(self, t_us: int, msg: mavlink.MAVLink_message) -> None:
        packet = msg.pack(self._mav)
        self._mav.seq = (self._mav.seq + 1) % 256
        self._fh.write(struct.pack(">Q", TLOG_EPOCH_US + t_us) + packet)
        name = msg.get_type()
        self.count[name] = self.count.get(name, 0) + 1

    def heartbeat(self, t_us: int) -> None:
        self._emit(
            t_us,
            mavlink.MAVLink_heartbeat_message(
                mavlink.MAV_TYPE_FIXED_WING, mavlink.MAV_AUTOPILOT_GENERIC, 0, 0, 4, 3
            ),
        )

    def imu(self, t_us: int, instance: int, acc_frd_mps2: tuple[float, ...],
            omega_frd_radps: tuple[float, ...]) -> None:
        ax, ay, az = acc_frd_mps2
        p, q, r = omega_frd_radps
        self._emit(
            t_us,
            mavlink.MAVLink_highres_imu_message(
                t_us, ax, ay, az, p, q, r, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0b111111, instance
            ),
        )

    def attitude(self, t_us: int, euler_rad: tuple[float, ...]) -> None:
        phi, theta, psi = euler_rad
        self._emit(
            t_us,
            mavlink.MAVLink_attitude_message(t_us // 1000, phi, theta, psi, 0.0, 0.0, 0.0),
        )

    def gps(self, t_us: int, lat_rad: float, lon_rad: float, alt_msl_m: float,
            vel_ned_mps: tuple[float, ...]) -> None:
        vn, ve, vd = vel_ned_mps
        lat = int(round(lat_rad * RAD2DEGE7))
        lon = int(round(lon_rad * RAD2DEGE7))
        hdg = int(round((math.degrees(math.atan2(ve, vn)) % 360.0) * 100)) % 36000
        self._emit(
            t_us,
            mavlink.MAVLink_global_position_int_message(
                t_us // 1000, lat, lon, int(round(alt_msl_m * 1000)), int(round(alt_msl_m * 1000)),
                _cms(vn), _cms(ve), _cms(vd), hdg,
            ),
        )
        speed = math.hypot(vn, ve)
        self._emit(
            t_us,
            mavlink.MAVLink_gps_raw_int_message(
                t_us, 3, lat, lon, int(round(alt_msl_m * 1000)), 100, 100,
                int(round(speed / CM2M)), hdg, 12,
            ),
        )

    def airspeed(self, t_us: int, instance: int, cas_mps: float, oat_k: float = 288.15) -> None:
        self._emit(
            t_us,
            mavlink.MAVLink_airspeed_message(instance, cas_mps, int(round((oat_k - 273.15) * 100)),
                                             0.0, 0),
        )

    def aoa(self, t_us: int, aoa_rad: list[float], ssa_rad: float) -> None:
        """Vane 0 and sideslip in AOA_SSA; vanes 1, 2 in NAMED_VALUE_FLOAT AOA1/AOA2 (contract)."""
        self._emit(t_us, mavlink.MAVLink_aoa_ssa_message(t_us, aoa_rad[0] * RAD2DEG,
                                                          ssa_rad * RAD2DEG))
        for i in range(1, len(aoa_rad)):
            self._emit(t_us, mavlink.MAVLink_named_value_float_message(
                t_us // 1000, f"AOA{i}".encode(), aoa_rad[i] * RAD2DEG))

    def vfr_hud(self, t_us: int, *, cas_mps: float, groundspeed_mps: float, heading_rad: float,
                baro_alt_m: float, climb_mps: float, throttle: float = 0.0) -> None:
        self._emit(
            t_us,
            mavlink.MAVLink_vfr_hud_message(
                cas_mps, groundspeed_mps, int(round(math.degrees(heading_rad) % 360.0)) % 360,
                int(round(throttle * 100)), baro_alt_m, climb_mps,
            ),
        )

    def scaled_pressure(self, t_us: int, static_pressure_pa: float, oat_k: float) -> None:
        self._emit(
            t_us,
            mavlink.MAVLink_scaled_pressure_message(
                t_us // 1000, static_pressure_pa / 100.0, 0.0, int(round((oat_k - 273.15) * 100))
            ),
        )

    def close(self) -> None:
        self._fh.close()
        os.replace(self._tmp, self.path)

    def abort(self) -> None:
        self._fh.close()
        self._tmp.unlink(missing_ok=True)

    def __enter__(self) -> TlogEncoder:
        return self

    def __exit__(self, et: type[BaseException] | None, e: BaseException | None,
                 tb: TracebackType | None) -> None:
        if et is None:
            self.close()
        else:
            self.abort()


def _cms(v_mps: float) -> int:
    return max(-32768, min(32767, int(round(v_mps / CM2M))))
