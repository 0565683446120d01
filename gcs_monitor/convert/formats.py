"""Readers for the real flight-data formats in shared/data/real, to SI/NED/FRD arrays.

Every reader returns a :class:`Flight`: uniformly documented arrays, SI units, NED earth frame,
FRD body frame, time in seconds. Frame and unit fixes follow shared/data/real/README.md:

* Zipline launch CSVs (50 Hz): already NED/FRD SI. ``accel_body_mps2`` is specific force. The
  estimator reset at t = 7.94 s since launch (position/velocity jump) is masked (no GPS velocity
  is emitted over 7.4-8.9 s) for ``convert`` only; read as a log (``read_messages``) the velocity
  is as recorded, and the monitor's step gate attributes the jump to the reference. There is no
  lat/lon: the documented origin is the Muhanga distribution centre (-2.0767, 29.7376),
  altitude 1,700 m, which only sets the GS-KM's earth-rate and gravity terms.
* OnSpeed/VN-300 CSV (50 Hz): VN-300 specific force (z down) and rates as IMU 0; OnSpeed's
  internal IMU as IMU 1 (g -> m/s^2, deg/s -> rad/s, RollRate sign flipped: it is opposite to the
  VN-300, corr -0.97). Attitude from the VN-300 Euler angles. GPS velocity from the raw 5 Hz GNSS
  velocity, emitted only when it changes (it is held between updates in the file), stamped at its
  measurement instant: the receiver's latency behind the IMU is measured from the file
  (:mod:`gcs_monitor.convert.alignment`; 0.1-0.2 s). IAS (kt) is
  taken as CAS for AIRSPEED instance 0; AngleofAttack (deg) as vane 0.
* ALFA CSVs (20 Hz grid, ROS FLU/ENU): FLU -> FRD is (x, -y, -z) for both specific force and
  rates; ENU -> NED velocity is (y, x, -z); the orientation quaternion (x, y, z, w missing) is
  completed with w = +sqrt(1 - x^2 - y^2 - z^2) and converted from ENU-FLU to NED-FRD Euler
  angles; the sign of the missing w is chosen per row so that gravity agrees with the measured
  specific force. Rows whose IMU is empty are skipped. No lat/lon: a documented placeholder near
  Pittsburgh (40.44, -79.94), altitude 300 m. The autopilot's commanded attitude is the measured
  attitude plus ALFA's ``delta_roll`` / ``delta_pitch`` (commanded minus measured, deg: their
  signs agree with the body rates, corr(delta_roll, p) ~ 0.8), written as NAV_CONTROLLER_OUTPUT
  at every row where a delta changed (~12 Hz) with ``field.alt_error`` (m), ``field.aspd_error``
  (cm/s in ArduPlane's NAV_CONTROLLER_OUTPUT, converted to m/s) and ``field.xtrack_error`` (m);
  the IMU stays on the 20 Hz grid, forward-filled (its values change at ~2.5 Hz: the notes give
  the measured rate of every stream). The failure status (``field.data``) and the kind (from the
  file name) are ground truth, written beside the tlog, never on the link.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from datetime import UTC
from pathlib import Path

import numpy as np

from gcs_monitor.convert.alignment import gnss_velocity_lag_s
from gcs_monitor.core.frames import dcm_from_quat, euler_from_dcm
from gcs_monitor.core.types import Mat, Vec
from gcs_monitor.core.units import DEG2RAD, FPM2MPS, FT2M, G2MPS2, HPA2PA, KT2MPS

ZIPLINE_ORIGIN_DEG = (-2.0767, 29.7376)
ZIPLINE_ALT_M = 1700.0
ZIPLINE_RESET_MASK_S = (7.4, 8.9)
ALFA_ORIGIN_DEG = (40.44, -79.94)
ALFA_ALT_M = 300.0


class ConvertError(ValueError):
    """An input file does not have the format its reader expects."""


@dataclass(frozen=True)
class FailureTruth:
    """A real failure's ground truth (ALFA): the failed component, the kind as the file names
    it, the first instant of the failure (s, the flight's time axis; NaN without a failure) and
    the failure-status flag at each of its changes."""

    component: str  # "engine", "aileron", "elevator", "rudder", or "" (no failure)
    kind: str  # e.g. "engine_failure", "right_aileron_failure", "no_failure"
    t_failure_s: float
    status_t_s: Vec
    status: Vec


# ALFA file-name kinds -> the component the monitor should name (longest first)
ALFA_KINDS = (("both_ailerons_failure", "aileron"), ("right_aileron_failure", "aileron"),
              ("left_aileron_failure", "aileron"), ("rudder_left_failure", "rudder"),
              ("rudder_right_failure", "rudder"), ("elevator_failure", "elevator"),
              ("engine_failure", "engine"), ("no_failure", ""))


def alfa_kind(stem: str) -> tuple[str, str]:
    """(kind, component) of an ALFA flight from its file name (README: the flag's value
    differs between kinds, the name does not)."""
    for kind, component in ALFA_KINDS:
        if kind in stem:
            return kind, component
    return "unknown", ""


@dataclass
class Flight:
    """A flight in SI arrays. ``n`` samples at the IMU rate; GPS arrays on their own times."""

    name: str
    fmt: str
    t_s: Vec  # (n,)
    acc_frd_mps2: list[Mat]  # per IMU instance, (n, 3)
    omega_frd_radps: list[Mat]  # per IMU instance, (n, 3)
    euler_rad: Mat  # (n, 3)
    gps_t_s: Vec  # (m,)
    gps_vel_ned_mps: Mat  # (m, 3)
    lat_rad: Vec  # (m,)
    lon_rad: Vec  # (m,)
    alt_m: Vec  # (m,)
    air_t_s: Vec = field(default_factory=lambda: np.zeros(0))
    cas_mps: Vec = field(default_factory=lambda: np.zeros(0))
    aoa_rad: Vec = field(default_factory=lambda: np.zeros(0))
    baro_alt_m: Vec = field(default_factory=lambda: np.zeros(0))
    climb_mps: Vec = field(default_factory=lambda: np.zeros(0))
    static_pressure_pa: Vec = field(default_factory=lambda: np.zeros(0))
    oat_k: Vec = field(default_factory=lambda: np.zeros(0))
    # the autopilot's setpoints and tracking errors (NAV_CONTROLLER_OUTPUT), on their own times
    nav_t_s: Vec = field(default_factory=lambda: np.zeros(0))
    nav_roll_rad: Vec = field(default_factory=lambda: np.zeros(0))
    nav_pitch_rad: Vec = field(default_factory=lambda: np.zeros(0))
    alt_error_m: Vec = field(default_factory=lambda: np.zeros(0))
    aspd_error_mps: Vec = field(default_factory=lambda: np.zeros(0))
    xtrack_error_m: Vec = field(default_factory=lambda: np.zeros(0))
    # ground truth of a real failure (ALFA): never on the link, written beside the tlog
    truth: FailureTruth | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0]) if len(self.t_s) else 0.0


def _read_csv(path: Path) -> tuple[list[str], list[list[str]]]:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    if not rows:
        raise ConvertError(f"{path}: empty file")
    return [h.strip() for h in rows[0]], rows[1:]


def _columns(path: Path, header: list[str], rows: list[list[str]], names: list[str]) -> Mat:
    missing = [n for n in names if n not in header]
    if missing:
        raise ConvertError(f"{path}: missing columns {missing}")
    idx = [header.index(n) for n in names]
    out = np.full((len(rows), len(names)), np.nan)
    for r, row in enumerate(rows):
        for c, i in enumerate(idx):
            if i < len(row) and row[i].strip() != "":
                try:
                    out[r, c] = float(row[i])
                except ValueError:
                    pass
    return out


def read_zipline(path: Path, *, mask_reset: bool = True) -> Flight:
    """A Zipline launch CSV. ``mask_reset``: emit no velocity over the documented estimator
    reset (7.4-8.9 s after launch), as the Lu2016 open-loop reproduction wants it
    (``convert``); the log reader (replay, real_flights, calibrate) gives the velocity as
    recorded, and the monitor's step gate attributes the jump to the reference."""
    header, rows = _read_csv(path)
    cols = (["seconds_since_launch"]
            + [f"velocity_ned_mps[{i}]" for i in range(3)]
            + [f"accel_body_mps2[{i}]" for i in range(3)]
            + [f"orientation_rad[{i}]" for i in range(3)]
            + [f"angular_rate_body_radps[{i}]" for i in range(3)]
            + [f"position_ned_m[{i}]" for i in range(3)])
    a = _columns(path, header, rows, cols)
    a = a[np.all(np.isfinite(a), axis=1)]
    t = a[:, 0] - a[0, 0]
    keep_gps = ~((a[:, 0] >= ZIPLINE_RESET_MASK_S[0]) & (a[:, 0] <= ZIPLINE_RESET_MASK_S[1]))
    if not mask_reset:
        keep_gps[:] = True
    lat0, lon0 = (x * DEG2RAD for x in ZIPLINE_ORIGIN_DEG)
    from gcs_monitor.core.constants import EARTH_RADIUS_M

    north, east, down = a[:, 13], a[:, 14], a[:, 15]
    lat = lat0 + north / EARTH_RADIUS_M
    lon = lon0 + east / (EARTH_RADIUS_M * math.cos(lat0))
    alt = ZIPLINE_ALT_M - down
    return Flight(
        name=path.stem, fmt="zipline", t_s=t,
        acc_frd_mps2=[a[:, 4:7]], omega_frd_radps=[a[:, 10:13]], euler_rad=a[:, 7:10],
        gps_t_s=t[keep_gps], gps_vel_ned_mps=a[keep_gps, 1:4],
        lat_rad=lat[keep_gps], lon_rad=lon[keep_gps], alt_m=alt[keep_gps],
        notes=[f"t0 = {a[0, 0]:.3f} s since launch; " + (
            f"GPS velocity masked over {ZIPLINE_RESET_MASK_S} s since launch (estimator reset)"
            if mask_reset else "velocity as recorded (its estimator resets at 7.94 s since "
            "launch: a velocity and attitude jump)")],
    )


def read_onspeed(path: Path) -> Flight:
    header, rows = _read_csv(path)
    names = ["timeStamp", "vnAccelFwd", "vnAccelLat", "vnAccelVert",
             "vnAngularRateRoll", "vnAngularRatePitch", "vnAngularRateYaw",
             "ForwardG", "LateralG", "VerticalG", "RollRate", "PitchRate", "YawRate",
             "vnRoll", "vnPitch", "vnYaw", "vnGnssVelNedNorth", "vnGnssVelNedEast",
             "vnGnssVelNedDown", "vnGnssLat", "vnGnssLon", "IAS", "AngleofAttack", "Palt",
             "VSI", "PStatic", "OAT", "Altitude"]
    a = _columns(path, header, rows, names)
    a = a[np.isfinite(a[:, 0])]
    c = {n: a[:, i] for i, n in enumerate(names)}
    t = (c["timeStamp"] - c["timeStamp"][0]) / 1000.0
    acc0 = np.column_stack([c["vnAccelFwd"], c["vnAccelLat"], c["vnAccelVert"]])
    omg0 = np.column_stack([c["vnAngularRateRoll"], c["vnAngularRatePitch"],
                            c["vnAngularRateYaw"]])
    # OnSpeed IMU: +1 g level on VerticalG means specific force z (down) = -1 g.
    acc1 = G2MPS2 * np.column_stack([c["ForwardG"], c["LateralG"], -c["VerticalG"]])
    omg1 = DEG2RAD * np.column_stack([-c["RollRate"], c["PitchRate"], c["YawRate"]])
    euler = DEG2RAD * np.column_stack([c["vnRoll"], c["vnPitch"], c["vnYaw"]])
    gv = np.column_stack([c["vnGnssVelNedNorth"], c["vnGnssVelNedEast"], c["vnGnssVelNedDown"]])
    changed = np.ones(len(t), dtype=bool)
    changed[1:] = np.any(np.diff(gv, axis=0) != 0.0, axis=1)
    alt = c["Altitude"] * FT2M
    # raw GNSS velocity: the receiver's latency is measured against the VN-300 IMU and the
    # samples are stamped at their measurement instant (alignment.py)
    ok = np.all(np.isfinite(acc0), axis=1) & np.all(np.isfinite(euler), axis=1)
    eul_u = euler[ok].copy()
    eul_u[:, 2] = np.unwrap(eul_u[:, 2])
    gok = changed & np.all(np.isfinite(gv), axis=1)
    lag = gnss_velocity_lag_s(t[ok], acc0[ok], eul_u, t[gok], gv[gok])
    changed &= t - lag.lag_s >= t[0]  # a sample measured before the file starts is left out
    return Flight(
        name=path.stem, fmt="onspeed", t_s=t, acc_frd_mps2=[acc0, acc1],
        omega_frd_radps=[omg0, omg1], euler_rad=euler,
        gps_t_s=t[changed] - lag.lag_s, gps_vel_ned_mps=gv[changed],
        lat_rad=c["vnGnssLat"][changed] * DEG2RAD, lon_rad=c["vnGnssLon"][changed] * DEG2RAD,
        alt_m=alt[changed],
        air_t_s=t, cas_mps=c["IAS"] * KT2MPS, aoa_rad=c["AngleofAttack"] * DEG2RAD,
        baro_alt_m=c["Palt"] * FT2M, climb_mps=c["VSI"] * FPM2MPS,
        static_pressure_pa=c["PStatic"] * HPA2PA, oat_k=c["OAT"] + 273.15,
        notes=["IMU0 = VN-300 (rates quantised to 0.01 rad/s), IMU1 = OnSpeed internal "
               "(RollRate sign flipped)", "IAS taken as CAS",
               lag.note("VN-300 GNSS velocity")],
    )


def _parse_ros_time(s: str) -> float:
    from datetime import datetime

    return datetime.strptime(s.strip(), "%Y-%m-%d %H:%M:%S.%f").replace(
        tzinfo=UTC).timestamp()


def read_alfa(path: Path) -> Flight:
    header, rows = _read_csv(path)
    names = ["field.orientation.x", "field.orientation.y", "field.orientation.z",
             "field.angular_velocity.x", "field.angular_velocity.y", "field.angular_velocity.z",
             "field.linear_acceleration.x", "field.linear_acceleration.y",
             "field.linear_acceleration.z", "field.twist.linear.x", "field.twist.linear.y",
             "field.twist.linear.z"]
    if "%time" not in header:
        raise ConvertError(f"{path}: missing column %time")
    a = _columns(path, header, rows, names)
    ti = header.index("%time")
    t_abs = np.array([_parse_ros_time(r[ti]) for r in rows])
    ok = np.all(np.isfinite(a[:, 0:9]), axis=1) & np.all(np.isfinite(a[:, 9:12]), axis=1)
    a, t_abs = a[ok], t_abs[ok]
    if len(a) < 2:
        raise ConvertError(f"{path}: fewer than two complete rows")
    t = t_abs - t_abs[0]
    flu2frd = np.array([1.0, -1.0, -1.0])
    acc = a[:, 6:9] * flu2frd
    omg = a[:, 3:6] * flu2frd
    # ENU->NED and FLU->FRD: C_ned_frd = T @ C_enu_flu @ T' with T = [[0,1,0],[1,0,0],[0,0,-1]]
    # and T' = diag(1,-1,-1).
    T = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    Tb = np.diag(flu2frd)
    euler = np.zeros((len(a), 3))
    g_ned = np.array([0.0, 0.0, -9.81])  # specific force of an unaccelerated body, NED
    for k in range(len(a)):
        x, y, z = a[k, 0:3]
        w = math.sqrt(max(0.0, 1.0 - x * x - y * y - z * z))
        # The sign of w is not recoverable from (x, y, z): (w, v) and (-w, v) are different
        # rotations. Take the one whose gravity direction agrees with the accelerometer.
        best = None
        for ws in (w, -w):
            C = T @ dcm_from_quat(np.array([ws, x, y, z])) @ Tb
            err = float(np.sum((C.T @ g_ned - acc[k]) ** 2))
            if best is None or err < best[0]:
                best = (err, C)
        assert best is not None
        euler[k] = euler_from_dcm(best[1])
    vel = np.column_stack([a[:, 10], a[:, 9], -a[:, 11]])
    n = len(t)
    lat0, lon0 = (x * DEG2RAD for x in ALFA_ORIGIN_DEG)
    flight = Flight(
        name=path.stem, fmt="alfa", t_s=t, acc_frd_mps2=[acc], omega_frd_radps=[omg],
        euler_rad=euler, gps_t_s=t, gps_vel_ned_mps=vel, lat_rad=np.full(n, lat0),
        lon_rad=np.full(n, lon0), alt_m=np.full(n, ALFA_ALT_M),
        notes=["ALFA derived 20 Hz grid, forward-filled", "placeholder lat/lon/alt"],
    )
    _alfa_setpoints(path, header, rows, ok, t_abs[0], flight)
    _alfa_truth(path, header, rows, t_abs[0], flight)
    flight.notes.append("update rates (value changes per second): " + ", ".join(
        f"{k} {v:.1f} Hz" for k, v in (
            ("IMU", _change_rate(t, a[:, 3:9])), ("velocity", _change_rate(t, a[:, 9:12])),
            ("setpoints", len(flight.nav_t_s) / max(flight.duration_s, 1e-9)))))
    return flight


def _change_rate(t: Vec, cols: Mat) -> float:
    """Changes per second of a forward-filled stream (a row counts when any column changed)."""
    if len(t) < 2:
        return math.nan
    changed = np.any(np.diff(cols, axis=0) != 0.0, axis=1)
    return float(np.sum(changed)) / float(t[-1] - t[0])


def _alfa_setpoints(path: Path, header: list[str], rows: list[list[str]], ok: Vec,
                    t0_abs: float, flight: Flight) -> None:
    """NAV_CONTROLLER_OUTPUT samples: at every row (with an IMU) where a delta changed, the
    commanded bank and pitch = measured + delta, and the ArduPlane tracking errors."""
    names = ["delta_roll", "delta_pitch", "field.alt_error", "field.aspd_error",
             "field.xtrack_error"]
    if any(n not in header for n in names):
        flight.notes.append("no delta_roll/delta_pitch/nav errors: no setpoints")
        return
    d = _columns(path, header, rows, names)[ok]
    deltas = d[:, 0:2]
    good = np.all(np.isfinite(deltas), axis=1)
    changed = np.ones(len(d), dtype=bool)
    changed[1:] = np.any(np.diff(deltas, axis=0) != 0.0, axis=1)
    keep = good & changed
    e = flight.euler_rad[keep]
    flight.nav_t_s = flight.t_s[keep]
    flight.nav_roll_rad = e[:, 0] + d[keep, 0] * DEG2RAD
    flight.nav_pitch_rad = e[:, 1] + d[keep, 1] * DEG2RAD
    flight.alt_error_m = d[keep, 2]
    flight.aspd_error_mps = d[keep, 3] * 0.01  # ArduPlane sends cm/s
    flight.xtrack_error_m = d[keep, 4]


def _alfa_truth(path: Path, header: list[str], rows: list[list[str]], t0_abs: float,
                flight: Flight) -> None:
    """The failure status flag's changes and the first failed instant, on the flight's time
    axis (rows before the first complete IMU row included: the flag may change anywhere)."""
    kind, component = alfa_kind(path.stem)
    ti = header.index("%time")
    t = np.array([_parse_ros_time(r[ti]) for r in rows]) - t0_abs
    if "field.data" in header:
        flag = _columns(path, header, rows, ["field.data"])[:, 0]
        flag = np.where(np.isfinite(flag), flag, 0.0)
    else:
        flag = np.zeros(len(rows))
    changed = np.ones(len(flag), dtype=bool)
    changed[1:] = np.diff(flag) != 0.0
    on = np.flatnonzero(flag != 0.0)
    t_fail = float(t[on[0]]) if len(on) and component else math.nan
    flight.truth = FailureTruth(component, kind, t_fail, t[changed], flag[changed])


def csv_layout(first_line: str) -> str | None:
    """The known CSV layout (``zipline``, ``onspeed``, ``alfa``) its header line names, or None."""
    if "seconds_since_launch" in first_line:
        return "zipline"
    if "vnAccelFwd" in first_line:
        return "onspeed"
    if "field.linear_acceleration" in first_line:
        return "alfa"
    return None


def detect_format(path: Path) -> str:
    if not Path(path).exists():
        raise ConvertError(f"{path}: no such file")
    if path.suffix.lower() == ".tlog":
        return "tlog"
    with open(path, newline="") as fh:
        first = fh.readline()
    layout = csv_layout(first)
    if layout is not None:
        return layout
    raise ConvertError(f"{path}: unknown format (expected a Zipline, OnSpeed or ALFA CSV, or a "
                       ".tlog)")


READERS = {"zipline": read_zipline, "onspeed": read_onspeed, "alfa": read_alfa}
