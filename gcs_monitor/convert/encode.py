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
