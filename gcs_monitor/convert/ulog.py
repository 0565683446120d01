"""PX4 ULog (.ulg) -> contract MAVLink messages, read with ``pyulog`` (BSD-3, PyPI).

PX4's body frame is FRD and its earth frame NED; quaternions are Hamilton, scalar first,
rotating body (FRD) vectors into NED, so no axis changes are needed. Old and current topic
names alike:

* vehicle_imu (every instance, when logged at >= 20 Hz): delta_velocity / delta_velocity_dt m/s²,
  delta_angle / delta_angle_dt rad/s -> HIGHRES_IMU id = instance
* sensor_combined (otherwise): accelerometer_m_s2, gyro_rad -> HIGHRES_IMU id 0
* vehicle_attitude: q (w, x, y, z) -> ATTITUDE (ZYX Euler)
* vehicle_gps_position or sensor_gps: lat, lon degE7 (or latitude_deg, longitude_deg), alt mm (or
  altitude_msl_m), vel_n/e/d_m_s, fix_type -> GLOBAL_POSITION_INT, GPS_RAW_INT, stamped at the
  measurement instant (the receiver's lag behind IMU 0 measured from the log, alignment.py)
* vehicle_local_position (only without a GPS topic): vx, vy, vz, x, y, z, ref_lat, ref_lon, ref_alt
  -> GLOBAL_POSITION_INT (EKF velocity: not independent of the IMU, said in the warnings)
* airspeed (per instance): indicated_airspeed_m_s, air_temperature_celsius -> AIRSPEED id =
  instance
* airspeed_validated: calibrated_airspeed_m_s -> VFR_HUD airspeed
* vehicle_air_data (or sensor_combined's baro): baro_pressure_pa, baro_alt_meter, baro_temp_celcius
  -> SCALED_PRESSURE, VFR_HUD alt
* actuator_outputs (per instance): output[0..15] -> SERVO_OUTPUT_RAW port = instance
* vehicle_attitude_setpoint: q_d, roll_body, pitch_body, thrust -> ATTITUDE_TARGET,
  NAV_CONTROLLER_OUTPUT
* vehicle_status: system_type (MAV_TYPE) or vehicle_type / is_rotary_wing -> HEARTBEAT, 1 Hz

Time: ``timestamp`` (µs since boot) of every topic.
"""

from __future__ import annotations

import contextlib
import io
import math
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from gcs_monitor.convert import encode as enc
from gcs_monitor.convert.alignment import LagEstimate, gnss_velocity_lag_s
from gcs_monitor.convert.dataflash import (
    DEFAULT_IMU_RATE_HZ,
    DEFAULT_SETPOINT_RATE_HZ,
    decimate,
)
from gcs_monitor.convert.logbase import LogError, LogInfo, Messages, block_means, log_error
from gcs_monitor.core.constants import EARTH_RADIUS_M
from gcs_monitor.core.frames import dcm_from_quat, euler_from_dcm
from gcs_monitor.core.units import DEG2RAD
from gcs_monitor.link.mav import mavlink

TOPICS = ["sensor_combined", "vehicle_imu", "vehicle_attitude", "vehicle_gps_position",
          "sensor_gps", "vehicle_local_position", "airspeed", "airspeed_validated",
          "vehicle_air_data", "actuator_outputs", "vehicle_attitude_setpoint", "vehicle_status"]
MIN_MULTI_IMU_HZ = 20.0
HEARTBEAT_PERIOD_US = 1_000_000
N_IMU = 3
N_ASPD = 3

# emit(row, t_us) -> messages; the merger calls it in time order
Emit = Callable[[int, int], Iterable[Any]]


def _rate_hz(t: np.ndarray) -> float:
    if len(t) < 3:
        return 0.0
    span = (float(t[-1]) - float(t[0])) * 1e-6
    return (len(t) - 1) / span if span > 0 else 0.0


def _f(d: dict[str, np.ndarray], *names: str) -> np.ndarray | None:
    for n in names:
        if n in d:
            return np.asarray(d[n], dtype=np.float64)
    return None


def _all(cols: list[np.ndarray | None]) -> list[np.ndarray] | None:
    """All the columns, or None when one of them is missing."""
    present = [c for c in cols if c is not None]
    return present if len(present) == len(cols) else None


def _vec(d: dict[str, np.ndarray], base: str) -> np.ndarray | None:
    cols = _all([_f(d, f"{base}[{i}]") for i in range(3)])
    if cols is None:
        return None
    return np.column_stack(cols)


def _mav_type(status: dict[str, np.ndarray] | None) -> int:
    generic = int(mavlink.MAV_TYPE_GENERIC)
    quad, plane = int(mavlink.MAV_TYPE_QUADROTOR), int(mavlink.MAV_TYPE_FIXED_WING)
    if status is None:
        return generic
    st = _f(status, "system_type")
    if st is not None and len(st) and st[-1] > 0:
        return int(st[-1])
    vt = _f(status, "vehicle_type")  # 1 rotary wing, 2 fixed wing, 3 rover
    if vt is not None and len(vt):
        return {1: quad, 2: plane, 3: int(mavlink.MAV_TYPE_GROUND_ROVER)}.get(int(vt[-1]),
                                                                              generic)
    rw = _f(status, "is_rotary_wing")
    if rw is not None and len(rw):
        return quad if rw[-1] else plane
    return generic


def ulog_messages(path: Path, *, imu_rate_hz: float = DEFAULT_IMU_RATE_HZ,
                  setpoint_rate_hz: float = DEFAULT_SETPOINT_RATE_HZ,
                  ) -> tuple[Messages, LogInfo]:
    """The contract messages of a PX4 ULog (module docstring) and its info.

    Raises :class:`LogError` for a file pyulog cannot parse or one without IMU data.
    """
    from pyulog import ULog

    path = Path(path)
    sink = io.StringIO()
    try:
        with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
            u = ULog(str(path), message_name_filter_list=TOPICS)
    except Exception as exc:
        raise log_error(path, f"not a readable ULog ({type(exc).__name__}: {exc})") from None
    info = LogInfo(path=path, fmt="ulog")
    tail = ulog_tail_bytes(path)
    if tail:
        info.warnings.append(f"the file ends {tail} bytes into an incomplete record "
                             "(cut file?); read up to it")
    if u.file_corruption or "corrupt" in sink.getvalue().lower():
        info.warnings.append("pyulog found corrupt or cut data; read what it could")
    topics: dict[tuple[str, int], dict[str, np.ndarray]] = {}
    for d in u.data_list:
        if len(d.data.get("timestamp", ())):
            topics[(d.name, d.multi_id)] = d.data
            key = d.name if d.multi_id == 0 else f"{d.name}[{d.multi_id}]"
            info.records[key] = len(d.data["timestamp"])
    mi = u.msg_info_dict
    info.vehicle = " ".join(str(mi[k]) for k in ("sys_name", "ver_hw") if k in mi) or "PX4"
    if not topics:
        raise log_error(path, "a ULog header with no logged data (cut file?)")

    streams: list[tuple[np.ndarray, Emit]] = []
    state: dict[str, Any] = {"gyro0": (0.0, 0.0, 0.0), "yaw": 0.0, "gs": math.nan,
                             "climb": 0.0, "cas": math.nan, "thrust": 0.0}

    # IMU -----------------------------------------------------------------------------------
    multi = [(k[1], d) for k, d in sorted(topics.items()) if k[0] == "vehicle_imu"]
    if multi and all(_rate_hz(d["timestamp"]) >= MIN_MULTI_IMU_HZ for _, d in multi):
        for inst, d in multi[:N_IMU]:
            dv, da = _vec(d, "delta_velocity"), _vec(d, "delta_angle")
            dtv, dta = _f(d, "delta_velocity_dt"), _f(d, "delta_angle_dt")
            if dv is None or da is None or dtv is None or dta is None:
                continue
            with np.errstate(divide="ignore", invalid="ignore"):
                v = np.column_stack([dv / (dtv[:, None] * 1e-6), da / (dta[:, None] * 1e-6)])
            _add_imu(streams, state, inst, d["timestamp"], v, imu_rate_hz)
    elif ("sensor_combined", 0) in topics:
        d = topics[("sensor_combined", 0)]
        acc, gyr = _vec(d, "accelerometer_m_s2"), _vec(d, "gyro_rad")
        if acc is not None and gyr is not None:
            _add_imu(streams, state, 0, d["timestamp"], np.column_stack([acc, gyr]),
                     imu_rate_hz)
    if not streams:
        have = ", ".join(sorted({k[0] for k in topics}))
        raise LogError(f"{path}: PX4 ULog without IMU data (sensor_combined or vehicle_imu; "
                       f"has {have})")

    # attitude, GPS, air data, outputs, setpoints ------------------------------------------
    if ("vehicle_attitude", 0) in topics:
        _add_attitude(streams, state, topics[("vehicle_attitude", 0)])
    lpos = topics.get(("vehicle_local_position", 0))
    if lpos is not None and "vz" in lpos:
        t = lpos["timestamp"]
        vz = np.asarray(lpos["vz"], dtype=np.float64).tolist()

        def climb(i: int, t_us: int, vz: list[float] = vz) -> Iterable[Any]:
            if math.isfinite(vz[i]):
                state["climb"] = -vz[i]
            return ()

        streams.append((t, climb))
    gps = topics.get(("vehicle_gps_position", 0)) or topics.get(("sensor_gps", 0))
    if gps is not None:
        lag = _add_gps(streams, state, gps)
        if lag is not None:
            info.notes.append(lag.note("GNSS velocity"))
    elif lpos is not None:
        if _add_local_position(streams, state, lpos):
            info.warnings.append("no GPS topic logged: GPS velocity taken from "
                                 "vehicle_local_position (the EKF's estimate, not independent "
                                 "of the IMU)")
        else:
            info.warnings.append("no GPS velocity in the log (no GPS topic, and "
                                 "vehicle_local_position has no valid horizontal velocity)")
    for (name, inst), d in sorted(topics.items()):
        if name == "airspeed" and inst < N_ASPD:
            _add_airspeed(streams, inst, d)
        elif name == "actuator_outputs":
            _add_outputs(streams, inst, d, setpoint_rate_hz)
    if ("airspeed_validated", 0) in topics:
        d = topics[("airspeed_validated", 0)]
        cas = _f(d, "calibrated_airspeed_m_s", "indicated_airspeed_m_s")
        if cas is not None:
            cl = cas.tolist()

            def set_cas(i: int, t_us: int, cl: list[float] = cl) -> Iterable[Any]:
                state["cas"] = cl[i]
                return ()

            streams.append((d["timestamp"], set_cas))
    air = topics.get(("vehicle_air_data", 0))
    if air is not None:
        _add_baro(streams, state, air["timestamp"], _f(air, "baro_pressure_pa"),
                  _f(air, "baro_alt_meter"), _f(air, "baro_temp_celcius"))
    elif ("sensor_combined", 0) in topics and "baro_alt_meter" in topics[("sensor_combined", 0)]:
        d = topics[("sensor_combined", 0)]
        t = d["timestamp"]
        k = decimate(t, 20.0)
        _add_baro(streams, state, t[k], None, _f(d, "baro_alt_meter")[k],  # type: ignore[index]
                  _f(d, "baro_temp_celcius")[k])  # type: ignore[index]
    if ("vehicle_attitude_setpoint", 0) in topics:
        _add_setpoints(streams, state, topics[("vehicle_attitude_setpoint", 0)],
                       setpoint_rate_hz)

    mav_type = _mav_type(topics.get(("vehicle_status", 0)))
    t0 = min(int(s[0][0]) for s in streams if len(s[0]))
    t1 = max(int(s[0][-1]) for s in streams if len(s[0]))
    info.t0_us, info.t1_us = t0, t1
    return _merge(streams, mav_type), info


ULOG_HEADER_BYTES = 16


def ulog_tail_bytes(path: Path) -> int:
    """Bytes of a last, incomplete message (a cut file): ULog messages are ``uint16 size,
    uint8 type, size bytes``, one after the other from the 16-byte header on."""
    data = Path(path).read_bytes()
    n = len(data)
    p = ULOG_HEADER_BYTES
    while p + 3 <= n:
        size = data[p] | (data[p + 1] << 8)
        if p + 3 + size > n:
            return n - p
        p += 3 + size
    return n - p if p < n else 0


def _merge(streams: list[tuple[np.ndarray, Emit]], mav_type: int) -> Messages:
    """Every stream's messages in time order (stream order among equal times), with a
    HEARTBEAT each second of vehicle time."""
    t_all = np.concatenate([np.asarray(s[0], dtype=np.int64) for s in streams])
    sid = np.concatenate([np.full(len(s[0]), j) for j, s in enumerate(streams)])
    row = np.concatenate([np.arange(len(s[0])) for s in streams])
    order = np.lexsort((sid, t_all))
    emits = [s[1] for s in streams]
    ap = mavlink.MAV_AUTOPILOT_PX4

    def gen() -> Iterator[tuple[int, Any]]:
        next_hb = -1
        for t_us, j, i in zip(t_all[order].tolist(), sid[order].tolist(),
                              row[order].tolist(), strict=True):
            if t_us >= next_hb:
                yield t_us, enc.heartbeat_msg(mav_type=mav_type, autopilot=ap)
                next_hb = t_us + HEARTBEAT_PERIOD_US
            for m in emits[j](i, t_us):
                yield t_us, m

    return gen()


def _add_imu(streams: list[tuple[np.ndarray, Emit]], state: dict[str, Any], inst: int,
             t: np.ndarray, v: np.ndarray, rate_hz: float) -> None:
    t = np.asarray(t, dtype=np.int64)
    ok = np.all(np.isfinite(v), axis=1)
    tb, vb = block_means(t[ok], v[ok], rate_hz)
    rows = vb.tolist()
    if inst == 0:  # for the GNSS velocity's lag (alignment.py)
        state["imu0"] = (np.asarray(tb, dtype=np.float64) * 1e-6, np.asarray(vb)[:, :3])

    def emit(i: int, t_us: int) -> Iterable[Any]:
        a0, a1, a2, g0, g1, g2 = rows[i]
        if inst == 0:
            state["gyro0"] = (g0, g1, g2)
        return (enc.highres_imu_msg(t_us, inst, (a0, a1, a2), (g0, g1, g2)),)

    streams.append((np.asarray(tb, dtype=np.int64), emit))


def _add_attitude(streams: list[tuple[np.ndarray, Emit]], state: dict[str, Any],
                  d: dict[str, np.ndarray]) -> None:
    q = np.column_stack([_f(d, f"q[{i}]") for i in range(4)])  # type: ignore[misc]
    ok = np.all(np.isfinite(q), axis=1) & (np.linalg.norm(q, axis=1) > 0.5)
    euler = [euler_from_dcm(dcm_from_quat(x / np.linalg.norm(x))).tolist() for x in q[ok]]
    if euler:
        state["att"] = (np.asarray(d["timestamp"][ok], dtype=np.float64) * 1e-6,
                        np.asarray(euler))

    def emit(i: int, t_us: int) -> Iterable[Any]:
        e = euler[i]
        state["yaw"] = e[2]
        return (enc.attitude_msg(t_us, (e[0], e[1], e[2]), state["gyro0"]),)

    streams.append((d["timestamp"][ok], emit))


def _add_gps(streams: list[tuple[np.ndarray, Emit]], state: dict[str, Any],
             d: dict[str, np.ndarray]) -> LagEstimate | None:
    """The GNSS receiver's position and velocity, stamped at the measurement instant: its lag
    behind IMU 0 is measured from the log (alignment.py) and taken off the time stamps."""
    lat = _f(d, "latitude_deg")
    lon = _f(d, "longitude_deg")
    if lat is None or lon is None:
        lat, lon = _f(d, "lat"), _f(d, "lon")
        lat = None if lat is None else lat * 1e-7
        lon = None if lon is None else lon * 1e-7
    alt = _f(d, "altitude_msl_m")
    if alt is None:
        a = _f(d, "alt")
        alt = None if a is None else a * 1e-3
    vel = _all([_f(d, n) for n in ("vel_n_m_s", "vel_e_m_s", "vel_d_m_s")])
    fix = _f(d, "fix_type")
    sats = _f(d, "satellites_used")
    if lat is None or lon is None or alt is None or vel is None:
        return None
    cols = [lat * DEG2RAD, lon * DEG2RAD, alt, *vel,
            fix if fix is not None else np.full(len(lat), 3.0),
            sats if sats is not None else np.full(len(lat), 255.0)]
    ok = np.all(np.isfinite(np.column_stack(cols)), axis=1)
    rows = np.column_stack(cols)[ok].tolist()
    t = np.asarray(d["timestamp"], dtype=np.int64)[ok]
    lag = _gnss_lag(state, t, np.column_stack(vel)[ok], np.asarray(cols[6])[ok])
    if lag is not None and lag.determined:
        t = t - int(round(lag.lag_s * 1e6))

    def emit(i: int, t_us: int) -> Iterable[Any]:
        la, lo, al, vn, ve, vd, fx, ns = rows[i]
        state["gs"] = math.hypot(vn, ve)
        out = [enc.gps_raw_msg(t_us, int(fx), la, lo, al, (vn, ve, vd), int(ns))]
        if fx >= 3:
            out.append(enc.global_position_msg(t_us, la, lo, al, 0.0, (vn, ve, vd)))
        return out

    streams.append((t, emit))
    return lag


def _gnss_lag(state: dict[str, Any], t_us: np.ndarray, vel_ned: np.ndarray,
              fix: np.ndarray) -> LagEstimate | None:
    """The GNSS velocity's lag behind IMU 0 (alignment.gnss_velocity_lag_s); None without
    IMU 0 or attitude."""
    imu, att = state.get("imu0"), state.get("att")
    sel = fix >= 3
    if imu is None or att is None or np.count_nonzero(sel) < 3:
        return None
    ti, acc = imu
    ta, eul = att
    ta, first = np.unique(ta, return_index=True)
    eul = eul[first]
    eul_i = np.column_stack([np.interp(ti, ta, np.unwrap(eul[:, k]) if k == 2 else eul[:, k])
                             for k in range(3)])
    return gnss_velocity_lag_s(ti, acc, eul_i, t_us[sel] * 1e-6, vel_ned[sel])


def _add_local_position(streams: list[tuple[np.ndarray, Emit]], state: dict[str, Any],
                        d: dict[str, np.ndarray]) -> bool:
    need = ("vx", "vy", "vz", "x", "y", "z", "ref_lat", "ref_lon")
    if not all(n in d for n in need):
        return False
    c = {n: np.asarray(d[n], dtype=np.float64) for n in need}
    ref_alt = _f(d, "ref_alt")
    c["ref_alt"] = ref_alt if ref_alt is not None else np.zeros(len(c["x"]))
    valid = np.ones(len(c["x"]), dtype=bool)
    for flag in ("v_xy_valid", "v_z_valid"):
        if flag in d:
            valid &= np.asarray(d[flag]) > 0
    lat0 = c["ref_lat"] * DEG2RAD
    lat = lat0 + c["x"] / EARTH_RADIUS_M
    lon = c["ref_lon"] * DEG2RAD + c["y"] / (EARTH_RADIUS_M * np.cos(lat0))
    alt = c["ref_alt"] - c["z"]
    cols = np.column_stack([lat, lon, alt, -c["z"], c["vx"], c["vy"], c["vz"]])
    ok = valid & np.all(np.isfinite(cols), axis=1)
    rows = cols[ok].tolist()

    def emit(i: int, t_us: int) -> Iterable[Any]:
        la, lo, al, rel, vn, ve, vd = rows[i]
        state["gs"] = math.hypot(vn, ve)
        return (enc.gps_raw_msg(t_us, 3, la, lo, al, (vn, ve, vd)),
                enc.global_position_msg(t_us, la, lo, al, rel, (vn, ve, vd)))

    streams.append((d["timestamp"][ok], emit))
    return bool(np.any(ok))


def _add_airspeed(streams: list[tuple[np.ndarray, Emit]], inst: int,
                  d: dict[str, np.ndarray]) -> None:
    ias = _f(d, "indicated_airspeed_m_s")
    if ias is None:
        return
    temp = _f(d, "air_temperature_celsius")
    oat = (temp + 273.15) if temp is not None else np.full(len(ias), math.nan)
    ok = np.isfinite(ias)
    rows = np.column_stack([ias, oat])[ok].tolist()

    def emit(i: int, t_us: int) -> Iterable[Any]:
        return (enc.airspeed_msg(inst, rows[i][0], oat_k=rows[i][1]),)

    streams.append((d["timestamp"][ok], emit))


def _add_baro(streams: list[tuple[np.ndarray, Emit]], state: dict[str, Any], t: np.ndarray,
              p: np.ndarray | None, alt: np.ndarray | None, temp_c: np.ndarray | None) -> None:
    if alt is None:
        return
    n = len(alt)
    cols = np.column_stack([alt, p if p is not None else np.full(n, math.nan),
                            (temp_c + 273.15) if temp_c is not None else np.full(n, 288.15)])
    ok = np.isfinite(alt)
    rows = cols[ok].tolist()

    def emit(i: int, t_us: int) -> Iterable[Any]:
        a, pa, tk = rows[i]
        out = []
        if math.isfinite(pa) and pa > 0:
            out.append(enc.scaled_pressure_msg(t_us, pa, tk if math.isfinite(tk) else 288.15))
        gs = state["gs"] if math.isfinite(state["gs"]) else 0.0
        cas = state["cas"] if math.isfinite(state["cas"]) else gs
        out.append(enc.vfr_hud_msg(cas_mps=cas, groundspeed_mps=gs, heading_rad=state["yaw"],
                                   baro_alt_m=a, climb_mps=state["climb"],
                                   throttle=state["thrust"]))
        return out

    streams.append((np.asarray(t)[ok], emit))


def _add_outputs(streams: list[tuple[np.ndarray, Emit]], port: int, d: dict[str, np.ndarray],
                 rate_hz: float) -> None:
    outs = [_f(d, f"output[{i}]") for i in range(16)]
    if outs[0] is None:
        return
    n = len(outs[0])
    noutputs = _f(d, "noutputs")
    cols = np.column_stack([o if o is not None else np.zeros(n) for o in outs])
    if noutputs is not None:
        cols = np.where(np.arange(16)[None, :] < noutputs[:, None], cols, 0.0)
    cols = np.where(np.isfinite(cols) & (cols >= 0.0) & (cols <= 65535.0), cols, 0.0)
    t = np.asarray(d["timestamp"], dtype=np.int64)
    k = decimate(t, rate_hz)
    rows = cols[k].tolist()

    def emit(i: int, t_us: int) -> Iterable[Any]:
        return (enc.servo_output_msg(t_us, rows[i], port=port),)

    streams.append((t[k], emit))


def _add_setpoints(streams: list[tuple[np.ndarray, Emit]], state: dict[str, Any],
                   d: dict[str, np.ndarray], rate_hz: float) -> None:
    t = np.asarray(d["timestamp"], dtype=np.int64)
    k = decimate(t, rate_hz)
    q = [_f(d, f"q_d[{i}]") for i in range(4)]
    roll, pitch = _f(d, "roll_body"), _f(d, "pitch_body")
    thrust = _f(d, "thrust")
    if thrust is None:
        tb = _vec(d, "thrust_body")
        thrust = np.linalg.norm(tb, axis=1) if tb is not None else np.zeros(len(t))
    n = len(t)
    cols = np.column_stack([x if x is not None else np.full(n, math.nan) for x in q]
                           + [roll if roll is not None else np.full(n, math.nan),
                              pitch if pitch is not None else np.full(n, math.nan), thrust])
    rows = cols[k].tolist()

    def emit(i: int, t_us: int) -> Iterable[Any]:
        w, x, y, z, r, p, th = rows[i]
        state["thrust"] = th if math.isfinite(th) else 0.0
        out = []
        if all(math.isfinite(v) for v in (w, x, y, z)) and abs(w) + abs(x) + abs(y) + abs(z) > 0:
            out.append(enc.attitude_target_msg(t_us, (w, x, y, z), thrust=state["thrust"]))
            if not (math.isfinite(r) and math.isfinite(p)):
                e = euler_from_dcm(dcm_from_quat(np.array([w, x, y, z])))
                r, p = float(e[0]), float(e[1])
        if math.isfinite(r) and math.isfinite(p):
            out.append(enc.nav_controller_msg(nav_roll_rad=r, nav_pitch_rad=p))
        return out

    streams.append((t[k], emit))
