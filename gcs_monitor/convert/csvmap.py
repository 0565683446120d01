"""Any CSV described by a TOML column map, and a ``Flight`` as contract messages.

A column map says where the time is and, per column, which quantity it is, in which unit and
frame; the reader converts to SI / NED / FRD here and builds a :class:`Flight`, which is then
encoded like every other log. Shipped examples (``gcs_monitor/convert/maps/``):
``onspeed_gen2_efis.toml`` (the header-less OnSpeed Gen2 box layout) and ``zipline.toml``.

```toml
[csv]
header = true            # false: columns are numbered from 0
delimiter = ","
time = "seconds_since_launch"   # or a column number
time_unit = "s"          # s | ms | us

[columns]                # quantity = { column = NAME or NUMBER, unit = ..., frame = ... }
acc_x = { column = "accel_body_mps2[0]", unit = "m/s2", frame = "frd" }
```

Quantities: ``acc_x/y/z`` (specific force), ``gyro_x/y/z``, ``roll``, ``pitch``, ``yaw``,
``vel_n/e/d``, ``lat``, ``lon``, ``alt``, ``cas``, ``aoa``, ``baro_alt``, ``climb``,
``static_pressure``, ``oat``; a second IMU as ``imu1_acc_x`` ... Units: ``m/s2``, ``g``,
``rad/s``, ``deg/s``, ``rad``, ``deg``, ``m/s``, ``kt``, ``ft/min``, ``m``, ``ft``, ``Pa``, ``hPa``,
``degC``, ``K``. Frames: body axes ``frd`` or ``flu`` (y and z negated), earth axes ``ned`` or
``enu`` (north/east swapped, up negated); ``sign = -1`` flips one column (a sensor mounted
reversed). Accelerometers that read +1 g level (z up) are ``frame = "flu"`` on z alone.
"""

from __future__ import annotations

import csv
import math
import tomllib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from gcs_monitor.convert import encode as enc
from gcs_monitor.convert.formats import Flight
from gcs_monitor.convert.logbase import LogError, LogInfo, Messages, log_error
from gcs_monitor.core.atmosphere import isa_temperature_k
from gcs_monitor.core.units import DEG2RAD, FPM2MPS, FT2M, G2MPS2, HPA2PA, KT2MPS
from gcs_monitor.link.mav import mavlink

MAPS_DIR = Path(__file__).with_name("maps")
UNITS = {"m/s2": 1.0, "g": G2MPS2, "rad/s": 1.0, "deg/s": DEG2RAD, "rad": 1.0, "deg": DEG2RAD,
         "m/s": 1.0, "kt": KT2MPS, "ft/min": FPM2MPS, "m": 1.0, "ft": FT2M, "Pa": 1.0,
         "hPa": HPA2PA, "degC": 1.0, "K": 1.0, "1": 1.0}
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6}
AXES = ("x", "y", "z")
NED = ("n", "e", "d")
QUANTITIES = (
    [f"{p}acc_{a}" for p in ("", "imu1_") for a in AXES]
    + [f"{p}gyro_{a}" for p in ("", "imu1_") for a in AXES]
    + ["roll", "pitch", "yaw", "vel_n", "vel_e", "vel_d", "lat", "lon", "alt", "cas", "aoa",
       "baro_alt", "climb", "static_pressure", "oat"])
HEARTBEAT_PERIOD_S = 1.0


def load_map(path: Path) -> dict[str, Any]:
    """A column map, checked: unknown quantities, units or keys stop with the file named."""
    path = Path(path)
    try:
        cfg = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise LogError(f"{path}: not a readable TOML column map ({exc})") from None
    unknown = set(cfg) - {"csv", "columns", "notes"}
    if unknown:
        raise LogError(f"{path}: unknown section(s) {sorted(unknown)}; expected [csv], "
                       "[columns]")
    if "time" not in cfg.get("csv", {}):
        raise LogError(f"{path}: [csv] needs time = COLUMN")
    for q, spec in cfg.get("columns", {}).items():
        if q not in QUANTITIES:
            raise LogError(f"{path}: unknown quantity {q!r}; expected one of "
                           f"{', '.join(QUANTITIES)}")
        if not isinstance(spec, dict) or "column" not in spec:
            raise LogError(f"{path}: [columns] {q} needs {{ column = ..., unit = ... }}")
        if spec.get("unit", "1") not in UNITS:
            raise LogError(f"{path}: {q}: unknown unit {spec.get('unit')!r}; expected one of "
                           f"{', '.join(UNITS)}")
        if spec.get("frame", "frd") not in ("frd", "flu", "ned", "enu"):
            raise LogError(f"{path}: {q}: unknown frame {spec.get('frame')!r}")
    return cfg


def _frame_sign(q: str, frame: str) -> float:
    axis = q.rsplit("_", 1)[-1]
    if frame == "flu" and axis in ("y", "z"):
        return -1.0
    if frame == "enu" and axis == "d":
        return -1.0
    return 1.0


def _enu_column(q: str, frame: str) -> str:
    """An ENU column feeds the other horizontal axis (east <-> north)."""
    if frame == "enu" and q in ("vel_n", "vel_e"):
        return "vel_e" if q == "vel_n" else "vel_n"
    return q


def read_mapped_csv(path: Path, column_map: Path) -> Flight:
    """A CSV through its column map as a :class:`Flight` (SI, NED, FRD)."""
    path = Path(path)
    cfg = load_map(column_map)
    c = cfg["csv"]
    header = bool(c.get("header", True))
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh, delimiter=c.get("delimiter", ",")))
    if not rows:
        raise log_error(path, "empty file")
    names = [h.strip() for h in rows[0]] if header else []
    body = rows[1:] if header else rows

    def index(col: Any) -> int:
        if isinstance(col, int):
            return col
        if col not in names:
            raise LogError(f"{path}: column {col!r} (from {column_map}) is not in the header "
                           f"({', '.join(names[:10])}...)")
        return names.index(col)

    def column(col: Any) -> np.ndarray:
        i = index(col)
        out = np.full(len(body), np.nan)
        for r, row in enumerate(body):
            if i < len(row):
                try:
                    out[r] = float(row[i])
                except ValueError:
                    pass
        return out

    t = column(c["time"]) * TIME_UNITS[c.get("time_unit", "s")]
    ok = np.isfinite(t)
    if np.count_nonzero(ok) < 2:
        raise log_error(path, f"fewer than two rows with a time in column {c['time']!r} of "
                              f"the map {column_map}")
    q: dict[str, np.ndarray] = {}
    for name, spec in cfg.get("columns", {}).items():
        frame = spec.get("frame", "frd")
        v = column(spec["column"])[ok] * UNITS[spec.get("unit", "1")]
        v = v * _frame_sign(name, frame) * float(spec.get("sign", 1.0))
        if spec.get("unit") == "degC":
            v = v + 273.15
        q[_enu_column(name, frame)] = v
    t = t[ok] - t[ok][0]
    n = len(t)
    nan = np.full(n, np.nan)

    def vec(prefix: str, kind: str) -> np.ndarray:
        return np.column_stack([q.get(f"{prefix}{kind}_{a}", nan) for a in AXES])

    acc = [vec("", "acc")]
    omg = [vec("", "gyro")]
    if any(f"imu1_acc_{a}" in q for a in AXES):
        acc.append(vec("imu1_", "acc"))
        omg.append(vec("imu1_", "gyro"))
    if not (np.any(np.isfinite(acc[0])) and np.any(np.isfinite(omg[0]))):
        raise LogError(f"{path}: the map {column_map} gives no IMU (acc_x/y/z and "
                       "gyro_x/y/z); the monitor's Frames follow the IMU")
    euler = np.column_stack([q.get(k, nan) for k in ("roll", "pitch", "yaw")])
    vel = np.column_stack([q.get(k, nan) for k in ("vel_n", "vel_e", "vel_d")])
    has_vel = np.all(np.isfinite(vel), axis=1)
    changed = has_vel.copy()  # GPS velocity held between updates: emit it when it changes
    changed[1:] &= np.any(np.diff(vel, axis=0) != 0.0, axis=1)
    return Flight(
        name=path.stem, fmt="csvmap", t_s=t, acc_frd_mps2=acc, omega_frd_radps=omg,
        euler_rad=euler, gps_t_s=t[changed], gps_vel_ned_mps=vel[changed],
        lat_rad=q.get("lat", nan)[changed], lon_rad=q.get("lon", nan)[changed],
        alt_m=q.get("alt", q.get("baro_alt", nan))[changed],
        air_t_s=t if ("cas" in q or "aoa" in q) else np.zeros(0),
        cas_mps=q.get("cas", nan), aoa_rad=q.get("aoa", nan),
        baro_alt_m=q.get("baro_alt", nan), climb_mps=q.get("climb", nan),
        static_pressure_pa=q.get("static_pressure", nan), oat_k=q.get("oat", nan),
        notes=[f"column map {Path(column_map).name}"])


def csvmap_messages(path: Path, column_map: Path) -> tuple[Messages, LogInfo]:
    return flight_messages(read_mapped_csv(path, column_map), path)


def flight_messages(flight: Flight, path: Path) -> tuple[Messages, LogInfo]:
    """A :class:`Flight` (any CSV reader's output) as contract messages, in time order: the
    IMU instances at their rate, GPS at its times, air data where present (as ``write_flight``
    encodes it into a .tlog)."""
    info = LogInfo(path=Path(path), fmt=flight.fmt, vehicle=f"{flight.fmt} CSV",
                   records={"rows": len(flight.t_s)}, notes=list(flight.notes))
    if len(flight.t_s) == 0:
        raise log_error(Path(path), "no rows")
    info.t0_us = 0
    info.t1_us = int(round(float(flight.t_s[-1] - flight.t_s[0]) * 1e6))
    return _flight_gen(flight), info


def _finite(*xs: float) -> bool:
    return all(math.isfinite(x) for x in xs)


def _flight_gen(f: Flight) -> Iterator[tuple[int, Any]]:
    t = (f.t_s - f.t_s[0]).tolist()
    gps_t = (f.gps_t_s - f.t_s[0]).tolist()
    air_t = (f.air_t_s - f.t_s[0]).tolist() if len(f.air_t_s) else []
    gi = ai = 0
    next_hb = 0.0
    accs = [a.tolist() for a in f.acc_frd_mps2]
    omgs = [w.tolist() for w in f.omega_frd_radps]
    euler = f.euler_rad.tolist()
    for k, tk in enumerate(t):
        t_us = int(round(tk * 1e6))
        if tk >= next_hb:
            yield t_us, enc.heartbeat_msg(mav_type=mavlink.MAV_TYPE_FIXED_WING,
                                          autopilot=mavlink.MAV_AUTOPILOT_GENERIC)
            next_hb += HEARTBEAT_PERIOD_S
        while gi < len(gps_t) and gps_t[gi] <= tk + 1e-9:
            g_us = int(round(gps_t[gi] * 1e6))
            v = f.gps_vel_ned_mps[gi]
            la, lo, al = float(f.lat_rad[gi]), float(f.lon_rad[gi]), float(f.alt_m[gi])
            if _finite(*v):
                la, lo = (la, lo) if _finite(la, lo) else (0.0, 0.0)
                al = al if math.isfinite(al) else 0.0
                vel = (float(v[0]), float(v[1]), float(v[2]))
                yield g_us, enc.gps_raw_msg(g_us, 3, la, lo, al, vel)
                yield g_us, enc.global_position_msg(g_us, la, lo, al, 0.0, vel)
            gi += 1
        for inst in range(len(accs)):
            a, w = accs[inst][k], omgs[inst][k]
            if _finite(*a, *w):
                yield t_us, enc.highres_imu_msg(t_us, inst, (a[0], a[1], a[2]),
                                                (w[0], w[1], w[2]))
        e = euler[k]
        if _finite(*e):
            yield t_us, enc.attitude_msg(t_us, (e[0], e[1], e[2]))
        while ai < len(air_t) and air_t[ai] <= tk + 1e-9:
            yield from _air(f, ai, t_us)
            ai += 1


def _air(f: Flight, i: int, t_us: int) -> Iterator[tuple[int, Any]]:
    def at(a: np.ndarray) -> float:
        return float(a[i]) if len(a) > i else math.nan

    cas, aoa, alt = at(f.cas_mps), at(f.aoa_rad), at(f.baro_alt_m)
    oat = at(f.oat_k)
    if not math.isfinite(oat):
        oat = isa_temperature_k(alt if math.isfinite(alt) else 0.0)
    if math.isfinite(cas):
        yield t_us, enc.airspeed_msg(0, cas, oat_k=oat)
    if math.isfinite(aoa):
        yield t_us, enc.aoa_ssa_msg(t_us, aoa, 0.0)
    if math.isfinite(alt):
        climb = at(f.climb_mps)
        yield t_us, enc.vfr_hud_msg(cas_mps=cas if math.isfinite(cas) else 0.0,
                                    groundspeed_mps=0.0, heading_rad=0.0, baro_alt_m=alt,
                                    climb_mps=climb if math.isfinite(climb) else 0.0)
    p = at(f.static_pressure_pa)
    if math.isfinite(p):
        yield t_us, enc.scaled_pressure_msg(t_us, p, oat)
