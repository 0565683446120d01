"""Synthetic MAVLink 2 telemetry following docs/telemetry.md, for link/telemetry tests.

A :class:`MavGen` produces the contract's message mix for one vehicle from smooth, known
"truth" functions of time (so tests can check conversions and interpolation against them):

* HIGHRES_IMU x ``n_imu`` and ATTITUDE at ``imu_rate_hz`` (100 Hz),
* GLOBAL_POSITION_INT + GPS_RAW_INT at ``gps_rate_hz`` (10 Hz); GPS velocity is LINEAR in time,
  so interpolation between two samples is exact up to the cm/s quantisation,
* AIRSPEED x3 + AOA_SSA + NAMED_VALUE_FLOAT AOA1/AOA2 + VFR_HUD at ``air_rate_hz`` (20 Hz),
* SCALED_PRESSURE, SERVO_OUTPUT_RAW, NAV_CONTROLLER_OUTPUT and ATTITUDE_TARGET at 10 Hz,
  DEBUG_FLOAT_ARRAY ``SURF`` at 50 Hz,
  HEARTBEAT at 1 Hz.

Corruption helpers (drop, duplicate, reorder, flip bits) and the tlog image are module
functions. Packets are ``(t_us, bytes)`` pairs in send order.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterable, Sequence

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink

Packet = tuple[int, bytes]
TLOG_EPOCH_US = 1_700_000_000_000_000
RAD2DEG = 180.0 / math.pi
RAD2DEGE7 = RAD2DEG * 1e7
G0 = 9.80665


class MavGen:
    """Contract telemetry of one synthetic vehicle.

    Parameters
    ----------
    sysid, compid : MAVLink source ids
    t0_us : vehicle time (since boot) of the first sample
    seq0 : first MAVLink sequence number (another sender with the same sysid uses another)
    mav_type : HEARTBEAT type (fixed wing by default)
    """

    def __init__(self, sysid: int = 1, compid: int = 1, *, t0_us: int = 5_000_000,
                 imu_rate_hz: int = 100, gps_rate_hz: int = 10, air_rate_hz: int = 20,
                 n_imu: int = 3, seq0: int = 0,
                 mav_type: int = mavlink.MAV_TYPE_FIXED_WING) -> None:
        self.mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.mav.seq = seq0 % 256
        self.t0_us = t0_us
        self.imu_rate_hz = imu_rate_hz
        self.gps_rate_hz = gps_rate_hz
        self.air_rate_hz = air_rate_hz
        self.n_imu = n_imu
        self.mav_type = mav_type

    # -- truth (SI, NED/FRD) as functions of vehicle time in seconds ---------------------------
    @staticmethod
    def acc_frd(t: float, inst: int = 0) -> tuple[float, float, float]:
        return (0.5 * math.sin(t) + 0.01 * inst, 0.2 * math.cos(0.5 * t),
                -G0 + 0.1 * math.sin(2 * t))

    @staticmethod
    def gyro_frd(t: float, inst: int = 0) -> tuple[float, float, float]:
        return (0.1 * math.sin(t), 0.05 * math.cos(t) + 0.001 * inst, 0.02)

    @staticmethod
    def euler(t: float) -> tuple[float, float, float]:
        return (0.1 * math.sin(0.3 * t), 0.05 + 0.02 * math.cos(0.3 * t), 1.0 + 0.02 * t)

    @staticmethod
    def gps_vel_ned(t: float) -> tuple[float, float, float]:
        """Linear in time: interpolation between GPS samples reproduces it exactly."""
        return (20.0 + 0.5 * t, -3.0 + 0.2 * t, 1.0 - 0.1 * t)

    @staticmethod
    def lat_lon_alt(t: float) -> tuple[float, float, float]:
        return (math.radians(47.0) + 1e-6 * t, math.radians(8.0) + 2e-6 * t, 500.0 + 0.5 * t)

    @staticmethod
    def cas(t: float, inst: int = 0) -> float:
        return 25.0 + 2.0 * math.sin(0.2 * t) + 0.1 * inst

    @staticmethod
    def aoa(t: float, inst: int = 0) -> float:
        return 0.05 + 0.02 * math.sin(0.7 * t) + 0.001 * inst

    @staticmethod
    def ssa(t: float) -> float:
        return 0.01 * math.sin(t)

    @staticmethod
    def baro(t: float) -> tuple[float, float]:
        return (480.0 + 0.5 * t, 0.5)

    @staticmethod
    def static(t: float) -> tuple[float, float]:
        return (95_000.0 - 5.0 * t, 283.15)

    @staticmethod
    def att_rates(t: float) -> tuple[float, float, float]:
        return (0.03 * math.cos(0.3 * t), -0.01 * math.sin(0.3 * t), 0.02)

    @staticmethod
    def servo_pwm(t: float) -> list[int]:
        """Channels 1-4 driven (aileron, elevator, rudder, throttle), the others unused (0)."""
        return [int(round(1500 + 200 * math.sin(t + k))) for k in range(3)] + [
            int(round(1600 + 100 * math.sin(0.5 * t)))] + [0] * 12

    @staticmethod
    def nav(t: float) -> tuple[float, ...]:
        """nav_roll, nav_pitch (rad), nav_bearing, target_bearing (rad), wp_dist (m),
        alt_error (m), aspd_error (m/s), xtrack_error (m)."""
        return (0.2 * math.sin(0.3 * t), 0.05, math.radians(30.0), math.radians(-45.0), 120.0,
                2.0 * math.sin(t), -0.5, 3.0)

    @staticmethod
    def target(t: float) -> tuple[tuple[float, float, float], tuple[float, float, float], float]:
        """ATTITUDE_TARGET truth: euler (rad), body-rate setpoints (rad/s), thrust."""
        return ((0.2 * math.sin(0.3 * t), 0.05, 1.0), (0.1, -0.05, 0.02), 0.6)

    @staticmethod
    def hud(t: float) -> tuple[float, float, float, float]:
        """airspeed, groundspeed (m/s), heading (rad), throttle (0..1)."""
        return (25.0, 20.0, math.radians(90.0), 0.5)

    @staticmethod
    def surf(t: float) -> list[float]:
        out = []
        for k in range(3):
            cmd = 0.05 * math.sin(t + k)
            out += [cmd, 0.9 * cmd, 0.01 * cmd]
        return out

    # -- single-message encoders (for injecting bad values) ------------------------------------
    def _pack(self, msg: object) -> bytes:
        packet = bytes(msg.pack(self.mav))  # type: ignore[attr-defined]
        self.mav.seq = (self.mav.seq + 1) % 256  # pack() does not advance it (send() does)
        return packet

    def heartbeat(self) -> bytes:
        M = mavlink
        return self._pack(M.MAVLink_heartbeat_message(
            self.mav_type, M.MAV_AUTOPILOT_ARDUPILOTMEGA, M.MAV_MODE_FLAG_SAFETY_ARMED, 0,
            M.MAV_STATE_ACTIVE, 3))

    def highres_imu(self, t_us: int, inst: int, acc: Sequence[float],
                    gyro: Sequence[float]) -> bytes:
        return self._pack(mavlink.MAVLink_highres_imu_message(
            t_us, acc[0], acc[1], acc[2], gyro[0], gyro[1], gyro[2], 0.0, 0.0, 0.0, 0.0, 0.0,
            0.0, 20.0, 0x3F, inst))

    def attitude(self, t_us: int, e: Sequence[float],
                 rates: Sequence[float] = (0.0, 0.0, 0.0)) -> bytes:
        return self._pack(mavlink.MAVLink_attitude_message(t_us // 1000, e[0], e[1], e[2],
                                                           rates[0], rates[1], rates[2]))

    def global_position(self, t_us: int, vel: Sequence[float],
                        lla: Sequence[float]) -> bytes:
        return self._pack(mavlink.MAVLink_global_position_int_message(
            t_us // 1000, int(round(lla[0] * RAD2DEGE7)), int(round(lla[1] * RAD2DEGE7)),
            int(round(lla[2] * 1000)), int(round(lla[2] * 1000)), int(round(vel[0] * 100)),
            int(round(vel[1] * 100)), int(round(vel[2] * 100)), 0))

    def gps_raw(self, t_us: int, fix: int = 3) -> bytes:
        return self._pack(mavlink.MAVLink_gps_raw_int_message(
            t_us, fix, 0, 0, 0, 100, 100, 0, 0, 12))

    def airspeed(self, inst: int, cas_mps: float, oat_k: float = 283.15) -> bytes:
        return self._pack(mavlink.MAVLink_airspeed_message(
            inst, cas_mps, int(round((oat_k - 273.15) * 100)), 3.8, 0))

    def aoa_ssa(self, t_us: int, aoa_rad: float, ssa_rad: float) -> bytes:
        return self._pack(mavlink.MAVLink_aoa_ssa_message(t_us, aoa_rad * RAD2DEG,
                                                          ssa_rad * RAD2DEG))

    def named_aoa(self, t_us: int, inst: int, aoa_rad: float) -> bytes:
        return self._pack(mavlink.MAVLink_named_value_float_message(
            t_us // 1000, f"AOA{inst}".encode(), aoa_rad * RAD2DEG))

    def vfr_hud(self, alt_m: float, climb_mps: float) -> bytes:
        return self._pack(mavlink.MAVLink_vfr_hud_message(25.0, 20.0, 90, 50, alt_m, climb_mps))

    def nav_controller(self, t: float) -> bytes:
        r, p, nb, tb, wp, ae, se, xe = self.nav(t)
        return self._pack(mavlink.MAVLink_nav_controller_output_message(
            r * RAD2DEG, p * RAD2DEG, int(round(nb * RAD2DEG)), int(round(tb * RAD2DEG)),
            int(wp), ae, se, xe))

    def attitude_target(self, t_us: int, t: float) -> bytes:
        (ph, th, ps), (p, q, r), thrust = self.target(t)
        cr, sr = math.cos(ph / 2), math.sin(ph / 2)
        cp, sp = math.cos(th / 2), math.sin(th / 2)
        cy, sy = math.cos(ps / 2), math.sin(ps / 2)
        quat = [cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy]
        return self._pack(mavlink.MAVLink_attitude_target_message(
            t_us // 1000, 0, quat, p, q, r, thrust))

    def scaled_pressure(self, t_us: int, p_pa: float, oat_k: float) -> bytes:
        return self._pack(mavlink.MAVLink_scaled_pressure_message(
            t_us // 1000, p_pa / 100.0, 3.8, int(round((oat_k - 273.15) * 100)), 0))

    def servo_output(self, t_us: int) -> bytes:
        pwm = self.servo_pwm(t_us * 1e-6)
        return self._pack(mavlink.MAVLink_servo_output_raw_message(
            t_us & 0xFFFFFFFF, 0, *pwm[:8], *pwm[8:]))

    def surf_array(self, t_us: int, data9: Sequence[float]) -> bytes:
        d = list(data9) + [0.0] * (58 - len(data9))
        return self._pack(mavlink.MAVLink_debug_float_array_message(t_us, b"SURF", 0, d))

    def unknown_message(self, msg_id: int = 60_000, payload: bytes = b"\x01\x02\x03") -> bytes:
        """A well-framed MAVLink 2 packet whose id is in no dialect (CRC extra 0)."""
        hdr = struct.pack("<BBBBBBBHB", 0xFD, len(payload), 0, 0, self.mav.seq,
                          self.mav.srcSystem, self.mav.srcComponent, msg_id & 0xFFFF,
                          msg_id >> 16)
        self.mav.seq = (self.mav.seq + 1) % 256
        crc = mavlink.x25crc(hdr[1:] + payload + b"\x00").crc
        return hdr + payload + struct.pack("<H", crc)

    # -- streams -----------------------------------------------------------------------------
    def packets(self, duration_s: float, *, start_us: int | None = None) -> list[Packet]:
        """The contract mix for ``duration_s`` of vehicle time, in send order."""
        t0 = self.t0_us if start_us is None else start_us
        dt_us = 1_000_000 // self.imu_rate_hz
        n = int(round(duration_s * self.imu_rate_hz))
        gps_every = self.imu_rate_hz // self.gps_rate_hz
        air_every = self.imu_rate_hz // self.air_rate_hz
        ten_hz = self.imu_rate_hz // 10
        fifty_hz = max(1, self.imu_rate_hz // 50)
        out: list[Packet] = []
        for k in range(n):
            t_us = t0 + k * dt_us
            t = t_us * 1e-6
            if k % self.imu_rate_hz == 0:
                out.append((t_us, self.heartbeat()))
            for i in range(self.n_imu):
                out.append((t_us, self.highres_imu(t_us, i, self.acc_frd(t, i),
                                                   self.gyro_frd(t, i))))
            out.append((t_us, self.attitude(t_us, self.euler(t), self.att_rates(t))))
            if k % gps_every == 0:
                out.append((t_us, self.global_position(t_us, self.gps_vel_ned(t),
                                                       self.lat_lon_alt(t))))
                out.append((t_us, self.gps_raw(t_us)))
            if k % air_every == 0:
                for i in range(3):
                    out.append((t_us, self.airspeed(i, self.cas(t, i))))
                out.append((t_us, self.aoa_ssa(t_us, self.aoa(t, 0), self.ssa(t))))
                for i in (1, 2):
                    out.append((t_us, self.named_aoa(t_us, i, self.aoa(t, i))))
                out.append((t_us, self.vfr_hud(*self.baro(t))))
            if k % ten_hz == 0:
                out.append((t_us, self.scaled_pressure(t_us, *self.static(t))))
                out.append((t_us, self.servo_output(t_us)))
                out.append((t_us, self.nav_controller(t)))
                out.append((t_us, self.attitude_target(t_us, t)))
            if k % fifty_hz == 0:
                out.append((t_us, self.surf_array(t_us, self.surf(t))))
        return out


# -- byte streams and corruption ------------------------------------------------------------------
def join(packets: Iterable[Packet]) -> bytes:
    return b"".join(p for _, p in packets)


def to_tlog(packets: Iterable[Packet], epoch_us: int = TLOG_EPOCH_US) -> bytes:
    """A .tlog image: 8-byte big-endian µs timestamp + packet per record."""
    return b"".join(struct.pack(">Q", epoch_us + t) + p for t, p in packets)


def drop(packets: Sequence[Packet], frac: float, rng: np.random.Generator) -> list[Packet]:
    keep = rng.random(len(packets)) >= frac
    return [p for p, k in zip(packets, keep, strict=True) if k]


def duplicate(packets: Sequence[Packet], frac: float, rng: np.random.Generator) -> list[Packet]:
    out: list[Packet] = []
    for p, d in zip(packets, rng.random(len(packets)) < frac, strict=True):
        out.append(p)
        if d:
            out.append(p)
    return out


def reorder(packets: Sequence[Packet], frac: float, rng: np.random.Generator) -> list[Packet]:
    """Swap a fraction of adjacent pairs (a late packet arriving after its successor)."""
    out = list(packets)
    i = 0
    swaps = rng.random(len(out)) < frac
    while i < len(out) - 1:
        if swaps[i]:
            out[i], out[i + 1] = out[i + 1], out[i]
            i += 2
        else:
            i += 1
    return out


def flip_bits(data: bytes, n_flips: int, rng: np.random.Generator) -> bytes:
    b = bytearray(data)
    for pos in rng.integers(0, len(b) * 8, n_flips):
        b[pos // 8] ^= 1 << (pos % 8)
    return bytes(b)
