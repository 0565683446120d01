"""Flight -> .tlog per the telemetry contract, with optional open-loop fault injection.

Open-loop validation (Lu2016 sec. 5): faults are added to the recorded IMU before encoding, so
the monitor sees them through the real MAVLink path; the injected values are returned as truth.
"""

from __future__ import annotations

import json
import math
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypedDict

import numpy as np

from gcs_monitor.convert.encode import TlogEncoder
from gcs_monitor.convert.formats import READERS, ConvertError, Flight, detect_format
from gcs_monitor.core.atmosphere import isa_temperature_k
from gcs_monitor.core.types import Mat, Vec

# (t_s (n,), flight) -> additive IMU fault (n, 6): [f_Ax, f_Ay, f_Az, f_p, f_q, f_r], SI.
ImuInjector = Callable[[Vec, Flight], Mat]


@dataclass
class ConvertResult:
    tlog: Path
    fmt: str
    duration_s: float
    messages: dict[str, int]
    injected_imu: Mat | None = None  # (n, 6) truth of the injected IMU faults
    t_s: Vec = field(default_factory=lambda: np.zeros(0))
    notes: list[str] = field(default_factory=list)
    truth_path: Path | None = None  # a real failure's ground truth beside the tlog (ALFA)


def write_flight(flight: Flight, out: Path, *, inject_imu: ImuInjector | None = None,
                 sysid: int = 1) -> ConvertResult:
    """Encode a flight; IMU at its own rate, GPS at its times, air data where present."""
    t = flight.t_s
    n = len(t)
    fault = inject_imu(t, flight) if inject_imu is not None else None
    gps_i = 0
    air_i = 0
    nav_i = 0
    next_hb = 0.0
    with TlogEncoder(out, sysid=sysid) as enc:
        for k in range(n):
            tk = float(t[k])
            t_us = int(round(tk * 1e6))
            if tk >= next_hb:
                enc.heartbeat(t_us)
                next_hb += 1.0
            while gps_i < len(flight.gps_t_s) and flight.gps_t_s[gps_i] <= tk + 1e-9:
                g_us = int(round(float(flight.gps_t_s[gps_i]) * 1e6))
                v = flight.gps_vel_ned_mps[gps_i]
                if np.all(np.isfinite(v)):
                    enc.gps(g_us, float(flight.lat_rad[gps_i]), float(flight.lon_rad[gps_i]),
                            float(flight.alt_m[gps_i]), (float(v[0]), float(v[1]), float(v[2])))
                gps_i += 1
            for inst in range(len(flight.acc_frd_mps2)):
                acc = flight.acc_frd_mps2[inst][k].copy()
                omg = flight.omega_frd_radps[inst][k].copy()
                if fault is not None and inst == 0:
                    acc += fault[k, 0:3]
                    omg += fault[k, 3:6]
                if np.all(np.isfinite(acc)) and np.all(np.isfinite(omg)):
                    enc.imu(t_us, inst, tuple(acc), tuple(omg))
            e = flight.euler_rad[k]
            if np.all(np.isfinite(e)):
                w = flight.omega_frd_radps[0][k]
                enc.attitude(t_us, (float(e[0]), float(e[1]), float(e[2])),
                             (float(w[0]), float(w[1]), float(w[2])) if np.all(np.isfinite(w))
                             else (0.0, 0.0, 0.0))
            while air_i < len(flight.air_t_s) and flight.air_t_s[air_i] <= tk + 1e-9:
                _write_air(enc, flight, air_i, t_us)
                air_i += 1
            while nav_i < len(flight.nav_t_s) and flight.nav_t_s[nav_i] <= tk + 1e-9:
                _write_nav(enc, flight, nav_i, t_us)
                nav_i += 1
        messages = dict(enc.count)
    truth = write_failure_truth(flight, out) if flight.truth is not None else None
    return ConvertResult(tlog=out, fmt=flight.fmt, duration_s=flight.duration_s,
                         messages=messages, injected_imu=fault, t_s=t, notes=flight.notes,
                         truth_path=truth)


def _write_nav(enc: TlogEncoder, f: Flight, i: int, t_us: int) -> None:
    enc.nav_controller(t_us, nav_roll_rad=float(f.nav_roll_rad[i]),
                       nav_pitch_rad=float(f.nav_pitch_rad[i]),
                       alt_error_m=float(f.alt_error_m[i]),
                       aspd_error_mps=float(f.aspd_error_mps[i]),
                       xtrack_error_m=float(f.xtrack_error_m[i]))


def truth_path_of(tlog: Path) -> Path:
    """Where a converted flight's ground truth sits: ``<name>.truth.npz`` beside the tlog."""
    return Path(tlog).with_suffix(".truth.npz")


# the status arrays' names hold a dot (no Python keyword): a typed mapping for np.savez
_StatusArrays = TypedDict("_StatusArrays", {"failure_status.t_s": Vec,
                                            "failure_status.value": Vec})


def write_failure_truth(flight: Flight, tlog: Path) -> Path:
    """A real failure's ground truth beside the tlog (never on the link), in the simulator's
    truth layout: ``fault_events_json`` (JSON list: the failed component as an ``actuator.<name>``
    channel, kind, start) and the status flag at its changes (``failure_status.t_s``,
    ``failure_status.value``)."""
    tr = flight.truth
    assert tr is not None
    events = [] if not tr.component or not math.isfinite(tr.t_failure_s) else [
        {"type": "actuator", "channel": f"actuator.{tr.component}", "kind": tr.kind,
         "t_start_s": tr.t_failure_s, "t_end_s": None, "params": {"source": flight.name}}]
    status: _StatusArrays = {"failure_status.t_s": tr.status_t_s,
                             "failure_status.value": tr.status}
    path = truth_path_of(tlog)
    tmp = path.with_name(path.name + ".part")
    with open(tmp, "wb") as fh:
        np.savez(fh, fault_events_json=np.array(json.dumps(events)),
                 failure_kind=np.array(tr.kind), failure_component=np.array(tr.component),
                 **status)
    tmp.replace(path)
    return path


def load_failure_truth(path: Path) -> dict[str, object]:
    """A truth file of :func:`write_failure_truth`: events decoded, arrays as saved."""
    with np.load(path, allow_pickle=False) as z:
        out: dict[str, object] = {k: z[k] for k in z.files}
    out["fault_events"] = json.loads(str(out.pop("fault_events_json")))
    return out


def _write_air(enc: TlogEncoder, f: Flight, i: int, t_us: int) -> None:
    cas = float(f.cas_mps[i])
    aoa = float(f.aoa_rad[i])
    oat = float(f.oat_k[i]) if len(f.oat_k) else isa_temperature_k(float(f.baro_alt_m[i]))
    if math.isfinite(cas):
        enc.airspeed(t_us, 0, cas, oat)
    if math.isfinite(aoa):
        enc.aoa(t_us, [aoa], 0.0)
    if len(f.baro_alt_m) and math.isfinite(float(f.baro_alt_m[i])):
        enc.vfr_hud(t_us, cas_mps=cas if math.isfinite(cas) else 0.0, groundspeed_mps=0.0,
                    heading_rad=0.0, baro_alt_m=float(f.baro_alt_m[i]),
                    climb_mps=float(f.climb_mps[i]) if len(f.climb_mps) else 0.0)
    if len(f.static_pressure_pa) and math.isfinite(float(f.static_pressure_pa[i])):
        enc.scaled_pressure(t_us, float(f.static_pressure_pa[i]), oat)


def read_flight(path: Path, fmt: str | None = None) -> Flight:
    path = Path(path)
    if not path.exists():
        raise ConvertError(f"{path}: no such file")
    fmt = fmt or detect_format(path)
    if fmt == "tlog":
        raise ConvertError(f"{path}: a .tlog needs no conversion")
    if fmt not in READERS:
        raise ConvertError(f"unknown format {fmt!r}; expected one of {sorted(READERS)}")
    return READERS[fmt](path)


def convert_file(path: Path, out: Path, *, fmt: str | None = None,
                 inject_imu: ImuInjector | None = None) -> ConvertResult:
    """Convert one real flight file to a contract .tlog (tlogs are copied as they are)."""
    path = Path(path)
    if (fmt or detect_format(path)) == "tlog":
        shutil.copyfile(path, out)
        return ConvertResult(tlog=out, fmt="tlog", duration_s=float("nan"), messages={})
    return write_flight(read_flight(path, fmt), out, inject_imu=inject_imu)


def lu2016_table2_injector(t_start_frac: float = 1.0 / 3.0,
                           t_end_frac: float = 1.0) -> ImuInjector:
    """Lu2016 Table 2 faults scaled to the flight's length.

    The paper's 10-30 s window of a 40 s run becomes [t0 + a*T, t0 + b*T_fault] where the
    fault window starts at ``t_start_frac`` of the flight and lasts 20 s or until the last 5 s.
    The shapes keep their absolute definitions (bias 3 m/s^2, drift 0.1 m/s^3 from fault start,
    4 sin(0.5 pi t), 1.5 deg/s, pi/180 sin(0.5 pi (t - ts)), 3 deg/s) with t measured so that
    the fault start plays the role of the paper's t = 10 s.
    """

    def inject(t: Vec, flight: Flight) -> Mat:
        t0, t1 = float(t[0]), float(t[-1])
        ts = t0 + t_start_frac * (t1 - t0)
        te = min(ts + 20.0, t1 - 0.0 if t_end_frac >= 1.0 else t0 + t_end_frac * (t1 - t0))
        te = min(te, t1 - 2.0) if t1 - ts > 4.0 else t1
        out = np.zeros((len(t), 6))
        on = (t > ts) & (t < te)
        tp = t[on] - ts + 10.0  # paper time
        d2r = math.pi / 180.0
        out[on, 0] = 3.0
        out[on, 1] = 0.1 * (tp - 10.0)
        out[on, 2] = 4.0 * np.sin(0.5 * math.pi * tp)
        out[on, 3] = 1.5 * d2r
        out[on, 4] = d2r * np.sin(0.5 * math.pi * (tp - 10.0))
        out[on, 5] = 3.0 * d2r
        return out

    return inject
