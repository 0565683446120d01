"""Encode sensor samples as MAVLink 2 (ardupilotmega) per docs/telemetry.md, and send them.

One :class:`MavlinkEncoder` (one reused ``MAVLink`` object, messages packed directly, no mavutil)
turns :class:`~sim_vehicle.sensors.suite.SensorSample` objects and the true actuator state into
packets; :class:`TlogWriter` writes a .tlog (8-byte big-endian µs timestamp + packet, timestamp =
``TLOG_EPOCH_US`` + vehicle time, so a replay is byte-for-byte deterministic);
:class:`UdpSender` sends live on a monotonic-clock schedule (no drift).

Contract (docs/telemetry.md), sensor group -> messages:

* ``imu<i>`` -> HIGHRES_IMU (id = i; time_usec)
* ``attitude`` -> ATTITUDE (time_boot_ms; body rates from the latest imu0 sample)
* ``gps`` -> GLOBAL_POSITION_INT (lat/lon degE7, alt mm, v cm/s) and GPS_RAW_INT (fix 3D)
* ``airdata`` -> AIRSPEED id 0..2 (CAS, impact pressure hPa, OAT cdegC), AOA_SSA (vane 0, deg),
  NAMED_VALUE_FLOAT ``AOA1``/``AOA2`` (deg)
* ``baro`` -> VFR_HUD (alt = pressure altitude, climb positive up)
* ``static`` -> SCALED_PRESSURE (press_abs hPa, temperature cdegC)
* clocked: HEARTBEAT, SERVO_OUTPUT_RAW (outputs 1-3: PWM 1500 +- 500 = +- max deflection of
  the commanded aileron, elevator, rudder; output 4: throttle command, 1000-2000 µs),
  DEBUG_FLOAT_ARRAY ``SURF`` array 0 (cmd, pos, rod per surface), and the autopilot's
  setpoints: NAV_CONTROLLER_OUTPUT (commanded bank, pitch, heading; altitude and airspeed
  errors, commanded minus current) and ATTITUDE_TARGET (commanded attitude quaternion, body
  rates, throttle as thrust); VFR_HUD's throttle is the throttle command

:class:`MavlinkSigner` signs finished packets (MAVLink 2 signing: the signed flag, the CRC
again, link id, 48-bit timestamp in 10 µs since 2015-01-01, the first 6 bytes of
SHA-256(key + packet)); ``sim-vehicle run --signing-key FILE`` signs everything it sends.
"""

from __future__ import annotations

import hashlib
import math
import os
import socket
import string
import struct
import time
from collections.abc import Callable
from pathlib import Path
from types import TracebackType
from typing import BinaryIO, cast

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from gcs_monitor.core.atmosphere import impact_pressure_pa
from gcs_monitor.core.units import PA2HPA, RAD2DEG, RAD2DEGE7
from sim_vehicle.sensors.channels import N_AIRDATA
from sim_vehicle.sensors.suite import SensorSample
from sim_vehicle.state import TrueState

_mcrf4xx: Callable[[bytes, int], int] | None
try:  # the C CRC pymavlink itself uses when available
    from fastcrc.crc16 import mcrf4xx as _mcrf4xx
except ImportError:  # pragma: no cover - pure-Python fallback
    _mcrf4xx = None

TLOG_EPOCH_US = 1_700_000_000_000_000  # fixed wall epoch: tlog timestamps = epoch + vehicle time
KELVIN_0C = 273.15
PWM_CENTER_US = 1500
PWM_HALF_RANGE_US = 500
PWM_THROTTLE_MIN_US = 1000  # throttle output: 1000 µs idle .. 2000 µs full
DEBUG_ARRAY_LEN = 58  # DEBUG_FLOAT_ARRAY.data length
GPS_FIX_3D = 3
GPS_SATELLITES = 12
GPS_EPH_CM = 100  # HDOP*100 placeholder: 1.0
INT16_MAX = 32767


def _i16(x: float) -> int:
    return max(-INT16_MAX - 1, min(INT16_MAX, int(round(x))))


def _cdegc(temp_k: float) -> int:
    return _i16((temp_k - KELVIN_0C) * 100.0)


MAVLINK2_MAGIC = 0xFD
_MAGIC = bytes((MAVLINK2_MAGIC,))
_HDR_TAIL = struct.Struct("<BBHB")  # sysid, compid, message id (low 16 bits, high 8 bits)
_CRC = struct.Struct("<H")
_AOA_NAMES = tuple(f"AOA{i}".encode() for i in range(N_AIRDATA))


class _FastPacker:
    """Packs one message type straight from arguments in declaration (``*_encode``) order.

    Same bytes as ``MAVLink_<msg>_message(...).pack(mav)`` (tested), without building the
    message object: a generated wire-order ``struct.pack`` call, header and C CRC.
    """

    def __init__(self, cls: type) -> None:
        self.msg_id: int = cls.id  # type: ignore[attr-defined]
        self.crc_extra = bytes([cls.crc_extra])  # type: ignore[attr-defined]
        names = cls.fieldnames  # type: ignore[attr-defined]
        args = []
        for f, n in zip(cls.ordered_fieldnames, cls.lengths, strict=True):  # type: ignore[attr-defined]
            i = names.index(f)
            is_array = n > 1 and cls.fieldtypes[i] != "char"  # type: ignore[attr-defined]
            args.append(f"*a[{i}]" if is_array else f"a[{i}]")
        self.payload = eval(  # noqa: S307 - generated from pymavlink's own field tables
            f"lambda a: st({', '.join(args)})", {"st": cls.unpacker.pack})  # type: ignore[attr-defined]

    def pack(self, mav: mavlink.MAVLink, *a: object) -> bytes:
        return self.bind(mav)(*a)

    def bind(self, mav: mavlink.MAVLink) -> Callable[..., bytes]:
        """``pack(*args) -> bytes`` for one ``MAVLink`` object (its sysid/compid fixed now)."""
        payload_of = self.payload
        crc_extra = self.crc_extra
        mid = self.msg_id
        # header after (len, incompat, compat, seq): sysid, compid, 24-bit message id
        tail = _HDR_TAIL.pack(mav.srcSystem, mav.srcComponent, mid & 0xFFFF, mid >> 16)
        crc16 = cast(Callable[[bytes, int], int], _mcrf4xx)  # _packer binds with fastcrc only
        crc_pack = _CRC.pack

        def pack(*a: object) -> bytes:
            payload = payload_of(a).rstrip(b"\0") or b"\0"  # MAVLink 2 trailing-zero truncation
            seq = mav.seq
            body = bytes((len(payload), 0, 0, seq)) + tail + payload
            mav.seq = (seq + 1) % 256
            return _MAGIC + body + crc_pack(crc16(body + crc_extra, 0xFFFF))

        return pack


_PACKERS: dict[type, _FastPacker] = {}


class MavlinkEncoder:
    """Contract encoder for one vehicle.

    Parameters
    ----------
    sysid, compid : MAVLink source (docs/telemetry.md: compid 1 = autopilot)
    servo_max_deflection_rad : (3,) deflection that maps to PWM 1500 +- 500 per surface
    home_alt_m : altitude for GLOBAL_POSITION_INT.relative_alt
    """

    def __init__(
        self,
        *,
        sysid: int = 1,
        compid: int = 1,
        servo_max_deflection_rad: tuple[float, float, float] = (0.35, 0.35, 0.4),
        home_alt_m: float = 0.0,
    ) -> None:
        self.mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.servo_max = servo_max_deflection_rad
        self.home_alt_m = home_alt_m
        self._gyro0 = (0.0, 0.0, 0.0)
        self._oat_k = KELVIN_0C + 15.0
        self._gs_mps = 0.0
        self._hdg_deg = 0
        self._cas0 = 0.0
        self._throttle = 0
        self._surf = [0.0] * DEBUG_ARRAY_LEN
        self._bound: dict[type, Callable[..., bytes]] = {}
        M = mavlink
        self._imu = self._packer(M.MAVLink_highres_imu_message)
        self._att = self._packer(M.MAVLink_attitude_message)
        self._gpi = self._packer(M.MAVLink_global_position_int_message)
        self._gps_raw = self._packer(M.MAVLink_gps_raw_int_message)
        self._aspd = self._packer(M.MAVLink_airspeed_message)
        self._aoa = self._packer(M.MAVLink_aoa_ssa_message)
        self._nvf = self._packer(M.MAVLink_named_value_float_message)
        self._hud = self._packer(M.MAVLink_vfr_hud_message)
        self._press = self._packer(M.MAVLink_scaled_pressure_message)
        self._by_group = {"attitude": self._enc_attitude, "gps": self._enc_gps,
                          "airdata": self._enc_airdata, "baro": self._enc_baro,
                          "static": self._enc_static}

    def _packer(self, cls: type) -> Callable[..., bytes]:
        """``pack(*encode_args) -> bytes`` of one message type (sequence numbers shared)."""
        f = self._bound.get(cls)
        if f is None:
            if _mcrf4xx is None:  # pragma: no cover

                def f(*args: object) -> bytes:
                    buf: bytes = cls(*args).pack(self.mav)
                    self.mav.seq = (self.mav.seq + 1) % 256
                    return buf

            else:
                p = _PACKERS.get(cls)
                if p is None:
                    p = _PACKERS[cls] = _FastPacker(cls)
                f = p.bind(self.mav)
            self._bound[cls] = f
        return f

    def _pack(self, cls: type, *args: object) -> bytes:
        """Encode one message given ``cls`` and its ``*_encode`` arguments."""
        return self._packer(cls)(*args)

    # -- sensor-driven -------------------------------------------------------------------------

    def encode_sample(self, s: SensorSample) -> list[tuple[str, bytes]]:
        """Packets carrying one sensor sample, as (message type, bytes)."""
        g = s.group
        v = s.values.tolist() if isinstance(s.values, np.ndarray) else [float(x) for x in s.values]
        if g[:3] == "imu":
            inst = int(g[3:])
            if inst == 0:
                self._gyro0 = (v[3], v[4], v[5])
            return [("HIGHRES_IMU", self._imu(
                s.t_us, v[0], v[1], v[2], v[3], v[4], v[5], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                self._oat_k - KELVIN_0C, 0x3F, inst))]
        enc = self._by_group.get(g)
        if enc is None:
            raise KeyError(g)
        return enc(s.t_us, v)

    def _enc_attitude(self, t_us: int, v: list[float]) -> list[tuple[str, bytes]]:
        self._hdg_deg = int(round(math.degrees(v[2]))) % 360
        p, q, r = self._gyro0
        return [("ATTITUDE", self._att(t_us // 1000, v[0], v[1], v[2], p, q, r))]

    def _enc_gps(self, t_us: int, v: list[float]) -> list[tuple[str, bytes]]:
        vn, ve, vd, lat, lon, alt = v
        ms = t_us // 1000
        gs = math.hypot(vn, ve)
        self._gs_mps = gs
        cog = int(round(math.degrees(math.atan2(ve, vn)) * 100.0)) % 36000
        lat7, lon7 = int(round(lat * RAD2DEGE7)), int(round(lon * RAD2DEGE7))
        alt_mm = int(round(alt * 1000.0))
        return [
            ("GLOBAL_POSITION_INT", self._gpi(
                ms, lat7, lon7, alt_mm, int(round((alt - self.home_alt_m) * 1000.0)),
                _i16(vn * 100.0), _i16(ve * 100.0), _i16(vd * 100.0), cog)),
            ("GPS_RAW_INT", self._gps_raw(
                t_us, GPS_FIX_3D, lat7, lon7, alt_mm, GPS_EPH_CM, GPS_EPH_CM,
                min(int(round(gs * 100.0)), 65534), cog, GPS_SATELLITES,
                0, 0, 0, 0, 0, 0)),
        ]

    def _enc_airdata(self, t_us: int, v: list[float]) -> list[tuple[str, bytes]]:
        out = []
        temp = _cdegc(self._oat_k)
        self._cas0 = v[N_AIRDATA]
        for i in range(N_AIRDATA):
            cas = v[N_AIRDATA + i]
            qc_hpa = impact_pressure_pa(cas) * PA2HPA if cas > 0 else 0.0
            out.append(("AIRSPEED", self._aspd(i, cas, temp, qc_hpa, 0)))
        out.append(("AOA_SSA", self._aoa(t_us, v[0] * RAD2DEG, v[2 * N_AIRDATA] * RAD2DEG)))
        ms = t_us // 1000
        for i in range(1, N_AIRDATA):
            out.append(("NAMED_VALUE_FLOAT", self._nvf(ms, _AOA_NAMES[i], v[i] * RAD2DEG)))
        return out

    def _enc_baro(self, t_us: int, v: list[float]) -> list[tuple[str, bytes]]:
        return [("VFR_HUD", self._hud(
            self._cas0, self._gs_mps, self._hdg_deg, self._throttle, v[0], v[1]))]

    def _enc_static(self, t_us: int, v: list[float]) -> list[tuple[str, bytes]]:
        self._oat_k = v[1]
        qc_hpa = impact_pressure_pa(self._cas0) * PA2HPA if self._cas0 > 0 else 0.0
        return [("SCALED_PRESSURE", self._press(
            t_us // 1000, v[0] * PA2HPA, qc_hpa, _cdegc(v[1]), 0))]

    # -- clocked -------------------------------------------------------------------------------

    def heartbeat(self) -> tuple[str, bytes]:
        M = mavlink
        return ("HEARTBEAT", self._pack(M.MAVLink_heartbeat_message,
            M.MAV_TYPE_FIXED_WING, M.MAV_AUTOPILOT_ARDUPILOTMEGA,
            M.MAV_MODE_FLAG_SAFETY_ARMED | M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 0,
            M.MAV_STATE_ACTIVE, 3))

    def servo_output_raw(self, t_us: int, st: TrueState) -> tuple[str, bytes]:
        pwm = []
        cmd = st.surf_cmd_rad
        for k in range(3):
            frac = max(-1.0, min(1.0, float(cmd[k]) / self.servo_max[k]))
            pwm.append(int(round(PWM_CENTER_US + PWM_HALF_RANGE_US * frac)))
        thr = max(0.0, min(1.0, st.throttle_cmd))
        self._throttle = int(round(100.0 * thr))
        pwm.append(int(round(PWM_THROTTLE_MIN_US + 2 * PWM_HALF_RANGE_US * thr)))
        return ("SERVO_OUTPUT_RAW", self._pack(mavlink.MAVLink_servo_output_raw_message,
            t_us & 0xFFFFFFFF, 0, pwm[0], pwm[1], pwm[2], pwm[3], 0, 0, 0, 0,
            0, 0, 0, 0, 0, 0, 0, 0))

    def setpoints(self, t_us: int, st: TrueState) -> list[tuple[str, bytes]]:
        """The autopilot's setpoints: NAV_CONTROLLER_OUTPUT and ATTITUDE_TARGET."""
        att = st.att_cmd_rad if st.att_cmd_rad is not None else st.euler_rad
        rates = st.rate_cmd_radps if st.rate_cmd_radps is not None else st.omega_frd_radps
        phi, theta, psi = float(att[0]), float(att[1]), float(att[2])
        hdg = int(round(math.degrees(psi))) % 360
        nav = self._pack(mavlink.MAVLink_nav_controller_output_message,
            phi * RAD2DEG, theta * RAD2DEG, hdg, hdg, 0, st.alt_cmd_m - st.alt_m,
            st.tas_cmd_mps - st.tas_mps, 0.0)
        cr, sr = math.cos(0.5 * phi), math.sin(0.5 * phi)
        cp, sp = math.cos(0.5 * theta), math.sin(0.5 * theta)
        cy, sy = math.cos(0.5 * psi), math.sin(0.5 * psi)
        q = [cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
             cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy]
        target = self._pack(mavlink.MAVLink_attitude_target_message,
            t_us // 1000, 0, q, float(rates[0]), float(rates[1]), float(rates[2]),
            max(0.0, min(1.0, st.throttle_cmd)))
        return [("NAV_CONTROLLER_OUTPUT", nav), ("ATTITUDE_TARGET", target)]

    def surf(self, t_us: int, st: TrueState) -> tuple[str, bytes]:
        d = self._surf
        cmd, pos, rod = st.surf_cmd_rad, st.surf_pos_rad, st.rod_pos_m
        for k in range(3):
            d[3 * k] = float(cmd[k])
            d[3 * k + 1] = float(pos[k])
            d[3 * k + 2] = float(rod[k])
        return ("DEBUG_FLOAT_ARRAY", self._pack(mavlink.MAVLink_debug_float_array_message,
            t_us, b"SURF", 0, d))


# ---------------------------------------------------------------------------------------------
# signing
# ---------------------------------------------------------------------------------------------

SIGNING_EPOCH_US = 1_420_070_400_000_000  # 2015-01-01T00:00:00Z
MAV2_IFLAG_SIGNED = 0x01
_CRC_EXTRA = {mid: cls.crc_extra for mid, cls in mavlink.mavlink_map.items()}


def load_signing_key(path: Path | str) -> bytes:
    """A 32-byte key from a file: 64 hexadecimal characters, or 32 raw bytes."""
    raw = Path(path).read_bytes()
    text = raw.decode("ascii", errors="replace").strip()
    if len(text) == 64 and all(c in string.hexdigits for c in text):
        return bytes.fromhex(text)
    if len(raw) == 32:
        return raw
    raise ValueError(f"signing key {path}: expected 64 hexadecimal characters or 32 raw bytes")


class MavlinkSigner:
    """Signs MAVLink 2 packets with one key (one link id).

    Timestamps strictly increase: ``wall_clock`` uses the time of day (a live link, as an
    autopilot with a clock); otherwise the timestamp follows the packets' vehicle time from the
    tlog epoch, so a signed .tlog is byte-for-byte deterministic.
    """

    def __init__(self, key: bytes, *, link_id: int = 0, wall_clock: bool = True) -> None:
        if len(key) != 32:
            raise ValueError("a MAVLink signing key has 32 bytes")
        self.key = key
        self.link_id = link_id
        self.wall_clock = wall_clock
        self._last = 0

    def sign(self, packet: bytes, t_us: int = 0) -> bytes:
        b = bytearray(packet)
        b[2] |= MAV2_IFLAG_SIGNED
        n = b[1]
        mid = b[7] | b[8] << 8 | b[9] << 16
        body = bytes(b[1:10 + n]) + bytes((_CRC_EXTRA[mid],))
        crc = _mcrf4xx(body, 0xFFFF) if _mcrf4xx is not None else mavlink.x25crc(
            bytearray(body)).crc
        struct.pack_into("<H", b, 10 + n, crc)
        now_us = time.time() * 1e6 if self.wall_clock else TLOG_EPOCH_US + t_us
        ts = max(self._last + 1, int((now_us - SIGNING_EPOCH_US) // 10))
        self._last = ts
        block = bytes((self.link_id,)) + struct.pack("<Q", ts)[:6]
        sig = hashlib.sha256(self.key + bytes(b[:12 + n]) + block).digest()[:6]
        return bytes(b) + block + sig


# ---------------------------------------------------------------------------------------------
# sinks
# ---------------------------------------------------------------------------------------------


class TlogWriter:
    """.tlog writer: ``>Q`` (epoch + vehicle µs) + packet; temp file renamed on close."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._tmp = self.path.with_name(self.path.name + ".part")
        self._fh: BinaryIO = open(self._tmp, "wb")  # noqa: SIM115 - closed in close()
        self._ts = struct.Struct(">Q")

    def write(self, t_us: int, packet: bytes) -> None:
        self._fh.write(self._ts.pack(TLOG_EPOCH_US + t_us) + packet)

    def close(self, *, commit: bool = True) -> None:
        if self._fh.closed:
            return
        self._fh.close()
        if commit:
            os.replace(self._tmp, self.path)
        else:
            self._tmp.unlink(missing_ok=True)

    def __enter__(self) -> TlogWriter:
        return self

    def __exit__(self, et: type[BaseException] | None, e: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close(commit=et is None)


def parse_hostport(text: str, default_port: int = 14550) -> tuple[str, int]:
    """``"HOST:PORT"`` -> (host, port); raises ValueError with a readable message."""
    host, sep, port = text.rpartition(":")
    if not sep:
        host, port = text, str(default_port)
    if not host:
        raise ValueError(f"--udp {text!r}: expected HOST:PORT")
    try:
        p = int(port)
    except ValueError:
        raise ValueError(f"--udp {text!r}: port {port!r} is not an integer") from None
    if not 0 < p < 65536:
        raise ValueError(f"--udp {text!r}: port must be 1..65535")
    return host, p


class UdpSender:
    """udpout to HOST:PORT, paced so that vehicle time tracks a monotonic clock.

    Packets for vehicle time ``t_us`` are sent at ``t0 + t_us`` on ``time.monotonic``; the
    schedule is absolute, so sleep jitter never accumulates into drift.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 14550) -> None:
        self.addr = (host, port)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._t0: float | None = None

    def pace(self, t_us: int) -> None:
        now = time.monotonic()
        if self._t0 is None:
            self._t0 = now - t_us * 1e-6
        delay = self._t0 + t_us * 1e-6 - now
        if delay > 0:
            time.sleep(delay)

    def write(self, t_us: int, packet: bytes) -> None:
        try:
            self.sock.sendto(packet, self.addr)
        except OSError:  # nobody listening (ICMP port unreachable) is not an error for udpout
            pass

    def close(self) -> None:
        self.sock.close()
