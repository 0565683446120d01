"""ArduPilot DataFlash logs (.bin, text .log) -> contract MAVLink messages.

Read with pymavlink's ``DFReader`` (its compiled indexer finds each message type's records, so
only the types below are decoded). Old (``TimeMS``, ``IMU2``, ``ASP2``, ``Ch1``) and current
(``TimeUS``, instance field ``I``, ``C1``) names alike. Units and frames, converted here
(ArduPilot's body frame is FRD and its earth frame NED, so no axis changes):

* IMU / IMU2 / IMU3 (or IMU with ``I``): GyrX..Z rad/s, AccX..Z m/s² -> HIGHRES_IMU id = instance
  (block means above ``imu_rate_hz``)
* ATT: Roll, Pitch, Yaw deg; DesRoll, DesPitch, DesYaw deg -> ATTITUDE; ATTITUDE_TARGET
* GPS (instance 0): Lat, Lng deg, Alt m, Spd m/s, GCrs deg, VZ m/s down, Status ->
  GLOBAL_POSITION_INT (raw GPS velocity, NED), GPS_RAW_INT
* ARSP / ASP2 (or ARSP with ``I``): Airspeed m/s, DiffPress Pa, Temp °C -> AIRSPEED id = instance
* AOA: AOA, SSA deg -> AOA_SSA
* BARO (instance 0): Press Pa, Temp °C, CRt m/s up -> SCALED_PRESSURE; VFR_HUD (alt = ISA pressure
  altitude)
* RCOU: C1..C16 / Ch1..Ch12 PWM µs -> SERVO_OUTPUT_RAW
* CTUN, NTUN: NavRoll, NavPitch deg (plane; else ATT Des*), NavBrg, TBrg deg, Dist, AltE, XT m, AsE
  / AspdE m/s -> NAV_CONTROLLER_OUTPUT
* MSG / VER: firmware string -> HEARTBEAT (vehicle type), 1 Hz

Time: ``TimeUS`` (µs since boot), else ``TimeMS`` × 1000; the old GPS message's ``TimeMS`` is
GPS time of week, its boot time is ``T``. GPS velocity is the receiver's (speed over ground,
course, vertical speed), not the EKF's: the IMU family compares the IMU against an independent
measurement. Three corrections make it comparable, each measured from the log and noted in
``LogInfo.notes`` (:mod:`gcs_monitor.convert.alignment`):

* a GPS record whose GPS time (``GMS``/``GWk``, old ``TimeMS``/``Week``) does not advance is the
  previous solution logged again (erle_copter_loiter_rtl.bin: 111 of 992), no new measurement:
  dropped;
* a boot clock whose rate against GPS time is off by more than a crystal can be
  (:func:`~gcs_monitor.convert.alignment.clock_rate`; the same log: 0.923) is rescaled onto GPS
  time for every stream, so that IMU intervals are true intervals;
* the GPS velocity's lag behind the IMU (receiver latency, 0.19 s in erle_copter_16.BIN) is
  measured and the GPS records are stamped at their measurement instant.

VFR_HUD airspeed: CTUN's airspeed (ArduPlane's own estimate), else the first airspeed sensor,
else GPS ground speed (as ArduCopter fills it).
"""

from __future__ import annotations

import contextlib
import io
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from gcs_monitor.convert import encode as enc
from gcs_monitor.convert.alignment import clock_rate, clock_wrong, gnss_velocity_lag_s
from gcs_monitor.convert.logbase import LogError, LogInfo, Messages, block_means, log_error
from gcs_monitor.core.constants import (
    GRAVITY_STD_MPS2,
    ISA_LAPSE_KPM,
    ISA_P0_PA,
    ISA_R_JPKGK,
    ISA_T0_K,
)
from gcs_monitor.core.frames import quat_from_euler
from gcs_monitor.core.units import DEG2RAD
from gcs_monitor.link.mav import mavlink

DEFAULT_IMU_RATE_HZ = 100.0  # the contract's HIGHRES_IMU rate (docs/telemetry.md)
DEFAULT_SETPOINT_RATE_HZ = 10.0  # ATTITUDE_TARGET, SERVO_OUTPUT_RAW: a GCS stream rate
GPS_FIX_3D = 3
HEARTBEAT_PERIOD_US = 1_000_000
N_IMU = 3
N_ASPD = 3

IMU_TYPES = {"IMU": 0, "IMU2": 1, "IMU3": 2}
ASPD_TYPES = {"ARSP": 0, "ASP2": 1}
WANTED = ["IMU", "IMU2", "IMU3", "ATT", "GPS", "ARSP", "ASP2", "AOA", "BARO", "RCOU", "CTUN",
          "NTUN", "MSG", "VER"]
_PA_EXP = -ISA_R_JPKGK * ISA_LAPSE_KPM / GRAVITY_STD_MPS2


def pressure_altitude_m(p_pa: float) -> float:
    """ISA pressure altitude (troposphere) of a static pressure."""
    return ISA_T0_K / -ISA_LAPSE_KPM * (1.0 - math.pow(p_pa / ISA_P0_PA, _PA_EXP))


def vehicle_type(text: str) -> tuple[int, str]:
    """MAV_TYPE and a short name from an ArduPilot firmware string."""
    t = text.lower()
    if "copter" in t or "heli" in t:
        return mavlink.MAV_TYPE_QUADROTOR, "ArduCopter"
    if "plane" in t:
        return mavlink.MAV_TYPE_FIXED_WING, "ArduPlane"
    if "rover" in t:
        return mavlink.MAV_TYPE_GROUND_ROVER, "ArduRover"
    if "sub" in t:
        return mavlink.MAV_TYPE_SUBMARINE, "ArduSub"
    return mavlink.MAV_TYPE_GENERIC, ""


def _open_reader(path: Path, text: bool) -> Any:
    from pymavlink import DFReader

    sink = io.StringIO()
    try:
        with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
            if text:
                return DFReader.DFReader_text(str(path))
            return DFReader.DFReader_binary(str(path))
    except Exception as exc:
        raise log_error(path, f"not a readable DataFlash log ({type(exc).__name__}: {exc})") \
            from None



# -- records -> column tables --------------------------------------------------------------------
# struct codes of DFReader's FORMAT_TO_STRUCT -> numpy (DataFlash is little-endian, packed)
_NP = {"b": "i1", "B": "u1", "e": "<f2", "h": "<i2", "H": "<u2", "i": "<i4", "I": "<u4",
       "f": "<f4", "d": "<f8", "q": "<i8", "Q": "<u8"}
Table = dict[str, np.ndarray]  # column name -> (n,) values (multipliers applied), plus "pos"


def _struct_codes(msg_struct: str) -> list[str]:
    out: list[str] = []
    num = ""
    for ch in msg_struct.lstrip("<"):
        if ch.isdigit():
            num += ch
        else:
            out.append(num + ch if ch == "s" else ch)
            num = ""
    return out


def _np_dtype(fmt: Any) -> np.dtype[Any] | None:
    fields = []
    for k, s in enumerate(_struct_codes(fmt.msg_struct)):
        if s.endswith("s"):
            fields.append((f"f{k}", f"S{s[:-1]}"))
        elif s in _NP:
            fields.append((f"f{k}", _NP[s]))
        else:
            return None
    return np.dtype(fields)


def _tables_binary(r: Any, names: list[str]) -> dict[str, Table]:
    """Every record of the wanted types as numpy columns, read straight from the file map with
    the reader's index (offsets per type), multipliers applied as DFReader applies them."""
    buf = np.frombuffer(r.data_map, dtype=np.uint8)
    out: dict[str, Table] = {}
    for name in names:
        i = r.name_to_id.get(name)
        if i is None or r.counts[i] <= 0:
            continue
        fmt = r.formats[i]
        dt = _np_dtype(fmt)
        if dt is None or dt.itemsize != fmt.len - 3:
            continue
        offs = np.asarray(r.offsets[i][:r.counts[i]], dtype=np.int64)
        offs = offs[offs + fmt.len <= len(buf)]
        if not len(offs):
            continue
        rec = buf[offs[:, None] + 3 + np.arange(fmt.len - 3)].view(dt).reshape(-1)
        tab: Table = {"pos": offs.astype(np.float64)}
        for k, col in enumerate(fmt.columns):
            if dt.names is None or k >= len(dt.names):
                break
            v = rec[f"f{k}"]
            if v.dtype.kind == "S":
                continue
            v = v.astype(np.float64)
            mult = fmt.msg_mults[k]
            if mult is not None:
                v = v / (1.0 / mult) if 0.0 < mult < 1.0 else v * mult
            tab[col] = v
        out[name] = tab
    return out


def _tables_text(r: Any, names: list[str]) -> tuple[dict[str, Table], dict[str, int]]:
    """The same columns from a text log, through DFReader's parser (line order as position)."""
    rows: dict[str, dict[str, list[float]]] = {}
    counts: dict[str, int] = {}
    pos = 0
    sink = io.StringIO()
    with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
        while True:
            m = r.recv_match(type=names)
            if m is None:
                break
            typ = m.get_type()
            counts[typ] = counts.get(typ, 0) + 1
            cols = rows.setdefault(typ, {"pos": []})
            cols["pos"].append(float(pos))
            pos += 1
            for c in m.fmt.columns:
                try:
                    v = float(getattr(m, c))
                except (TypeError, ValueError):
                    continue
                cols.setdefault(c, []).append(v)
    out: dict[str, Table] = {}
    for typ, cols in rows.items():
        n = len(cols["pos"])
        out[typ] = {c: np.asarray(v, dtype=np.float64) for c, v in cols.items() if len(v) == n}
    return out, counts


def _col(tab: Table, *names: str) -> np.ndarray:
    for n in names:
        if n in tab:
            return tab[n]
    return np.full(len(tab["pos"]), np.nan)


def _time_us(tab: Table, *, gps: bool = False) -> np.ndarray:
    if "TimeUS" in tab:
        return tab["TimeUS"].astype(np.int64)
    if gps and "T" in tab:  # old GPS: TimeMS is GPS time of week, T the boot time (ms)
        return (tab["T"] * 1000).astype(np.int64)
    if "TimeMS" in tab:
        return (tab["TimeMS"] * 1000).astype(np.int64)
    return np.full(len(tab["pos"]), -1, dtype=np.int64)


GPS_WEEK_S = 604_800.0
GPS_TIME_JUMP_S = 60.0  # a GPS time step beyond this (or back) starts a new run of records


def _gps_time_s(tab: Table) -> np.ndarray | None:
    """GPS time (s since the GPS epoch) of each GPS record, NaN where not valid (0); None when
    the log's GPS message has no GPS time."""
    if "GMS" in tab:
        ms, wk = tab["GMS"], _col(tab, "GWk")
    elif "T" in tab and "TimeMS" in tab:  # old names: TimeMS is GPS ms of week, T boot ms
        ms, wk = tab["TimeMS"], _col(tab, "Week")
    else:
        return None
    wk = np.nan_to_num(wk)
    out = ms * 1e-3 + wk * GPS_WEEK_S
    return np.where(ms > 0, out, np.nan)


def _longest_run(t_gnss: np.ndarray, t_boot: np.ndarray) -> np.ndarray:
    """Indices of the longest run of records whose GPS and boot times both advance (a GPS time
    reset or a reboot starts a new run)."""
    ok = np.isfinite(t_gnss)
    idx = np.flatnonzero(ok)
    if len(idx) < 2:
        return idx
    dg = np.diff(t_gnss[idx])
    db = np.diff(t_boot[idx])
    cut = np.flatnonzero((dg <= 0) | (dg > GPS_TIME_JUMP_S) | (db <= 0)) + 1
    runs = np.split(idx, cut)
    return max(runs, key=len)


def _instances(tab: Table, default: int) -> np.ndarray:
    if "I" in tab:
        return tab["I"].astype(np.int64)
    return np.full(len(tab["pos"]), default, dtype=np.int64)


def _firmware(r: Any) -> str:
    """The firmware string from VER / MSG."""
    sink = io.StringIO()
    out = ""
    with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
        r.rewind()
        for _ in range(60):
            m = r.recv_match(type=["MSG", "VER"])
            if m is None:
                break
            if m.get_type() == "VER" and getattr(m, "FWS", ""):
                out = str(m.FWS)
                break
            txt = str(getattr(m, "Message", ""))
            if txt.startswith(("Ardu", "APM:", "Rover", "Sub", "Blimp")) or "Copter" in txt \
                    or "Plane" in txt:
                out = txt
                break
    return out


def _tail_bytes(r: Any) -> int:
    """Bytes after the last complete record (a cut file leaves part of one; the reader's index
    may list that partial record)."""
    try:
        last, length = -1, 0
        for i in range(256):
            if i in r.formats and r.counts[i] > 0:
                ofs = int(r.offsets[i][r.counts[i] - 1])
                if ofs > last:
                    last, length = ofs, int(r.formats[i].len)
        if last < 0:
            return 0
        end = last + length
        return int(r.data_len) - (end if end <= int(r.data_len) else last)
    except (AttributeError, IndexError, KeyError, TypeError):
        return 0


def dataflash_messages(path: Path, *, text: bool = False,
                       imu_rate_hz: float = DEFAULT_IMU_RATE_HZ,
                       setpoint_rate_hz: float = DEFAULT_SETPOINT_RATE_HZ,
                       ) -> tuple[Messages, LogInfo]:
    """The contract messages of an ArduPilot DataFlash log (module docstring) and its info.

    Raises :class:`LogError` when the file is no DataFlash log or holds no IMU records.
    """
    path = Path(path)
    r = _open_reader(path, text)
    info = LogInfo(path=path, fmt="dataflash-text" if text else "dataflash")
    if text:
        tables, counts = _tables_text(r, WANTED)
        if not counts:
            raise log_error(path, "a DataFlash text log with no data records")
    else:
        counts = {r.formats[i].name: int(r.counts[i]) for i in range(256)
                  if i in r.formats and r.counts[i] > 0}
        if not counts or set(counts) <= {"FMT", "FMTU", "UNIT", "MULT"}:
            raise log_error(path, "a DataFlash header with no data records (cut file?)")
        tail = _tail_bytes(r)
        if tail:
            info.warnings.append(f"the file ends {tail} bytes into an incomplete record "
                                 "(cut file?); read up to it")
        tables = _tables_binary(r, WANTED)
    info.records = dict(counts)
    if not any(t in tables for t in IMU_TYPES):
        have = ", ".join(sorted(counts)[:14]) or "nothing"
        raise LogError(f"{path}: ArduPilot DataFlash log without IMU records (has {have}); "
                       "the monitor needs IMU, ATT and GPS")
    fw = _firmware(r)
    r.close()
    mav_type, _ = vehicle_type(fw)
    info.vehicle = fw or "ArduPilot (firmware string not logged)"
    return _emit(tables, info, mav_type, imu_rate_hz, setpoint_rate_hz), info


def decimate(t_us: np.ndarray, rate_hz: float) -> np.ndarray:
    """Indices keeping at most one sample per 1 / rate_hz (the first of each slot, 10 % jitter
    allowed)."""
    if not len(t_us) or not rate_hz > 0:
        return np.arange(len(t_us))
    period = 0.9e6 / rate_hz
    keep = []
    last = -math.inf
    for k, t in enumerate(t_us.tolist()):
        if t - last >= period:
            keep.append(k)
            last = t
    return np.asarray(keep, dtype=np.int64)


# stream kinds of the merged event list
_K_IMU, _K_ATT, _K_ATT_SP, _K_GPS, _K_ASPD, _K_AOA, _K_BARO, _K_RCOU, _K_CTUN, _K_NTUN = range(10)
Stream = tuple[int, np.ndarray, np.ndarray, list[list[float]]]


def _gps_records(tables: dict[str, Table], info: LogInfo) -> tuple[np.ndarray, np.ndarray,
                                                                  Any]:
    """GPS instance 0: (row mask of new solutions, boot time µs, boot-clock fix). Records
    whose GPS time does not advance are dropped; the boot clock's rate against GPS time is
    measured and, when no crystal could be that far off, a fix ``t_us -> t_us`` onto GPS time
    is returned for every stream (module docstring)."""
    tab = tables["GPS"]
    first = _instances(tab, 0) == 0
    t = _time_us(tab, gps=True)
    tg = _gps_time_s(tab)
    keep = first.copy()
    fix = None
    if tg is not None:
        tg = np.where(first, tg, np.nan)
        # the same solution logged again: its GPS time did not advance
        prev = -np.inf
        rep = 0
        for i in np.flatnonzero(first & np.isfinite(tg)).tolist():
            if tg[i] <= prev:
                keep[i] = False
                rep += 1
            else:
                prev = tg[i]
        if rep:
            info.notes.append(f"GPS: {rep} records repeat the previous solution (GPS time "
                              "not advancing): dropped")
        run = _longest_run(np.where(keep & (_col(tab, "Status") >= GPS_FIX_3D), tg, np.nan),
                           t.astype(np.float64))
        rate = clock_rate(t[run] * 1e-6, tg[run]) if len(run) else math.nan
        if clock_wrong(rate):
            t_ref = int(t[run[0]])

            def fix(x: np.ndarray, t_ref: int = t_ref, rate: float = rate) -> np.ndarray:
                return (t_ref + np.round((x - t_ref) / rate)).astype(np.int64)

            info.warnings.append(f"the log's boot clock runs at {rate:.4f} of GPS time (no "
                                 "crystal is off by more than 1e-4): every time stamp "
                                 "rescaled onto GPS time")
    return keep, t, fix


def _emit(tables: dict[str, Table], info: LogInfo, mav_type: int, imu_rate_hz: float,
          setpoint_rate_hz: float) -> Messages:
    streams: list[Stream] = []
    skipped = 0
    gps_keep, gps_t, clock_fix = (_gps_records(tables, info) if "GPS" in tables
                                  else (None, None, None))

    def tus(tab: Table, *, gps: bool = False) -> np.ndarray:
        t = _time_us(tab, gps=gps)
        if clock_fix is None or not len(t):
            return t
        return np.where(t >= 0, clock_fix(t), t)  # -1: no time stamp, skipped by add()

    def add(kind: int, t: np.ndarray, pos: np.ndarray, cols: list[np.ndarray],
            required: int | None = None) -> None:
        """A stream; rows with a bad time or a non-finite value in the first ``required``
        columns (all by default) are skipped and counted."""
        nonlocal skipped
        ok = t >= 0
        for c in cols[:required]:
            ok &= np.isfinite(c)
        skipped += int(np.count_nonzero(~ok))
        if np.any(ok):
            streams.append((kind, t[ok], pos[ok], [c[ok].tolist() for c in cols]))

    for name, default in IMU_TYPES.items():  # per instance, block means above imu_rate_hz
        tab = tables.get(name)
        if tab is None:
            continue
        t = tus(tab)
        inst = _instances(tab, default)
        v = np.column_stack([_col(tab, c) for c in ("AccX", "AccY", "AccZ", "GyrX", "GyrY",
                                                     "GyrZ")])
        good = (t >= 0) & np.all(np.isfinite(v), axis=1)
        skipped += int(np.count_nonzero(~good))
        for i in np.unique(inst).tolist():
            sel = good & (inst == i)
            if not 0 <= i < N_IMU or not np.any(sel):
                continue
            ti, vi = block_means(t[sel], v[sel], imu_rate_hz)
            pi = np.interp(ti, t[sel], tab["pos"][sel])
            add(_K_IMU, ti, pi, [np.full(len(ti), float(i))] + [vi[:, k] for k in range(6)])
    if "ATT" in tables:
        tab = tables["ATT"]
        t = tus(tab)
        add(_K_ATT, t, tab["pos"], [_col(tab, "Roll") * DEG2RAD, _col(tab, "Pitch") * DEG2RAD,
                                    _col(tab, "Yaw") * DEG2RAD])
        k = decimate(t, setpoint_rate_hz)
        if "DesRoll" in tab:
            add(_K_ATT_SP, t[k], tab["pos"][k], [_col(tab, "DesRoll")[k] * DEG2RAD,
                                                 _col(tab, "DesPitch")[k] * DEG2RAD,
                                                 _col(tab, "DesYaw")[k] * DEG2RAD])
    if "GPS" in tables:
        tab = tables["GPS"]
        first = gps_keep
        assert first is not None
        t = tus(tab, gps=True)[first]
        spd, crs = _col(tab, "Spd")[first], _col(tab, "GCrs")[first] * DEG2RAD
        vz = np.nan_to_num(_col(tab, "VZ")[first])
        lag = _gps_lag(streams, t, np.column_stack([spd * np.cos(crs), spd * np.sin(crs), vz]),
                       _col(tab, "Status")[first])
        if lag is not None:
            info.notes.append(lag.note("GPS velocity"))
            t = t - int(round(lag.lag_s * 1e6))
        add(_K_GPS, t, tab["pos"][first],
            [_col(tab, "Status")[first], _col(tab, "Lat")[first] * DEG2RAD,
             _col(tab, "Lng")[first] * DEG2RAD, _col(tab, "Alt")[first], spd, crs, vz,
             np.nan_to_num(_col(tab, "RelAlt")[first]),
             np.nan_to_num(_col(tab, "NSats")[first], nan=255.0)])
    for name, default in ASPD_TYPES.items():
        tab = tables.get(name)
        if tab is not None:
            add(_K_ASPD, tus(tab), tab["pos"],
                [_instances(tab, default).astype(np.float64), _col(tab, "Airspeed"),
                 _col(tab, "Temp") + 273.15, _col(tab, "DiffPress")], required=2)
    if "AOA" in tables:
        tab = tables["AOA"]
        add(_K_AOA, tus(tab), tab["pos"], [_col(tab, "AOA") * DEG2RAD,
                                                _col(tab, "SSA") * DEG2RAD])
    if "BARO" in tables:
        tab = tables["BARO"]
        first = _instances(tab, 0) == 0
        add(_K_BARO, tus(tab)[first], tab["pos"][first],
            [_col(tab, "Press")[first],
             np.nan_to_num(_col(tab, "Temp")[first] + 273.15, nan=ISA_T0_K),
             np.nan_to_num(_col(tab, "CRt")[first])])
    if "RCOU" in tables:
        tab = tables["RCOU"]
        t = tus(tab)
        k = decimate(t, setpoint_rate_hz)
        chans = [_col(tab, f"C{i}", f"Ch{i}")[k] for i in range(1, 17)]
        add(_K_RCOU, t[k], tab["pos"][k],
            [np.where((ch >= 800.0) & (ch <= 2500.0), ch, 0.0) for ch in chans])
    if "CTUN" in tables:  # throttle always; NavRoll, NavPitch, airspeed only in ArduPlane
        tab = tables["CTUN"]
        add(_K_CTUN, tus(tab), tab["pos"],
            [np.nan_to_num(_col(tab, "ThrOut", "ThO")), _col(tab, "NavRoll") * DEG2RAD,
             _col(tab, "NavPitch") * DEG2RAD, _col(tab, "Aspd", "As")], required=1)
    if "NTUN" in tables:
        tab = tables["NTUN"]
        add(_K_NTUN, tus(tab), tab["pos"],
            [np.nan_to_num(_col(tab, *n)) for n in (("NavBrg",), ("TBrg",), ("Dist", "WpDist"),
                                                     ("AltE", "AltErr"), ("XT",),
                                                     ("AsE", "AspdE", "AsErr"))])
    if skipped:
        info.warnings.append(f"{skipped} records without a time stamp or with non-finite "
                             "values skipped")
    if not streams:
        return iter(())
    kinds = np.concatenate([np.full(len(s[1]), s[0]) for s in streams])
    sidx = np.concatenate([np.full(len(s[1]), j) for j, s in enumerate(streams)])
    rows = np.concatenate([np.arange(len(s[1])) for s in streams])
    t_all = np.concatenate([s[1] for s in streams])
    pos = np.concatenate([s[2] for s in streams])
    order = np.lexsort((pos, t_all))  # time order, file order among equal times
    info.t0_us = int(t_all[order[0]])
    info.t1_us = int(t_all[order[-1]])
    return _messages(order, kinds, sidx, rows, t_all, streams, mav_type)


def _gps_lag(streams: list[Stream], t_gps: np.ndarray, vel_ned: np.ndarray,
             status: np.ndarray) -> Any:
    """The GPS velocity's lag behind IMU 0 (alignment.gnss_velocity_lag_s) from the IMU and
    ATT streams built so far; None without them."""
    imu = next((s for s in streams if s[0] == _K_IMU and s[3][0] and s[3][0][0] == 0.0), None)
    att = next((s for s in streams if s[0] == _K_ATT), None)
    ok = status >= GPS_FIX_3D
    if imu is None or att is None or np.count_nonzero(ok) < 3:
        return None
    ti = imu[1] * 1e-6
    ta = att[1] * 1e-6
    ta, first = np.unique(ta, return_index=True)
    eul = np.column_stack([np.unwrap(np.asarray(c, dtype=np.float64)[first]) if k == 2 else
                           np.asarray(c, dtype=np.float64)[first]
                           for k, c in enumerate(att[3])])
    eul_i = np.column_stack([np.interp(ti, ta, eul[:, k]) for k in range(3)])
    acc = np.column_stack([np.asarray(imu[3][k], dtype=np.float64) for k in (1, 2, 3)])
    return gnss_velocity_lag_s(ti, acc, eul_i, t_gps[ok] * 1e-6, vel_ned[ok])


def _messages(order: np.ndarray, kinds: np.ndarray, sidx: np.ndarray, rows: np.ndarray,
              t_all: np.ndarray, streams: list[Stream], mav_type: int,
              ) -> Iterator[tuple[int, Any]]:
    ap = mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
    plane = mav_type == mavlink.MAV_TYPE_FIXED_WING
    next_hb = -1
    gyro0 = (0.0, 0.0, 0.0)
    yaw = 0.0
    gs = math.nan
    ctun_aspd = aspd0 = math.nan
    throttle = 0.0
    nav_roll = nav_pitch = math.nan
    cols = [s[3] for s in streams]
    for kind, j, row, t_us in zip(kinds[order].tolist(), sidx[order].tolist(),
                                  rows[order].tolist(), t_all[order].tolist(), strict=True):
        c = cols[j]
        if t_us >= next_hb:
            yield t_us, enc.heartbeat_msg(mav_type=mav_type, autopilot=ap)
            next_hb = t_us + HEARTBEAT_PERIOD_US
        if kind == _K_IMU:
            inst = int(c[0][row])
            omg = (c[4][row], c[5][row], c[6][row])
            if inst == 0:
                gyro0 = omg
            yield t_us, enc.highres_imu_msg(t_us, inst, (c[1][row], c[2][row], c[3][row]), omg)
        elif kind == _K_ATT:
            yaw = c[2][row]
            yield t_us, enc.attitude_msg(t_us, (c[0][row], c[1][row], yaw), gyro0)
        elif kind == _K_ATT_SP:
            d = (c[0][row], c[1][row], c[2][row])
            q = quat_from_euler(*d)
            yield t_us, enc.attitude_target_msg(
                t_us, (float(q[0]), float(q[1]), float(q[2]), float(q[3])), thrust=throttle)
            if not plane:
                nav_roll, nav_pitch = d[0], d[1]
        elif kind == _K_GPS:
            fix, lat, lon, alt, spd, crs, vz, rel, sats = (x[row] for x in c)
            vel = (spd * math.cos(crs), spd * math.sin(crs), vz)
            gs = spd
            yield t_us, enc.gps_raw_msg(t_us, int(fix), lat, lon, alt, vel, int(sats))
            if fix >= GPS_FIX_3D:
                yield t_us, enc.global_position_msg(t_us, lat, lon, alt, rel, vel)
        elif kind == _K_ASPD:
            inst = int(c[0][row])
            if 0 <= inst < N_ASPD:
                if inst == 0:
                    aspd0 = c[1][row]
                yield t_us, enc.airspeed_msg(inst, c[1][row], oat_k=c[2][row],
                                             impact_pressure_pa=c[3][row])
        elif kind == _K_AOA:
            yield t_us, enc.aoa_ssa_msg(t_us, c[0][row], c[1][row])
        elif kind == _K_BARO:
            p = c[0][row]
            if p > 0:
                yield t_us, enc.scaled_pressure_msg(t_us, p, c[1][row])
                cas = ctun_aspd if math.isfinite(ctun_aspd) else (
                    aspd0 if math.isfinite(aspd0) else (gs if math.isfinite(gs) else 0.0))
                yield t_us, enc.vfr_hud_msg(
                    cas_mps=cas, groundspeed_mps=gs if math.isfinite(gs) else 0.0,
                    heading_rad=yaw, baro_alt_m=pressure_altitude_m(p), climb_mps=c[2][row],
                    throttle=throttle)
        elif kind == _K_RCOU:
            yield t_us, enc.servo_output_msg(t_us, [x[row] for x in c])
        elif kind == _K_CTUN:
            thr = c[0][row]
            throttle = thr / 1000.0 if thr > 1.5 else thr  # copter logs ThrOut in 0..1000
            if plane:
                nav_roll, nav_pitch, ctun_aspd = c[1][row], c[2][row], c[3][row]
        elif kind == _K_NTUN and math.isfinite(nav_roll) and math.isfinite(nav_pitch):
            nbrg, tbrg, dist, alte, xt, ase = (x[row] for x in c)
            yield t_us, enc.nav_controller_msg(
                nav_roll_rad=nav_roll, nav_pitch_rad=nav_pitch, nav_bearing_rad=nbrg * DEG2RAD,
                target_bearing_rad=tbrg * DEG2RAD, wp_dist_m=dist, alt_error_m=alte,
                aspd_error_mps=ase, xtrack_error_m=xt)
