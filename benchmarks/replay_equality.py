"""Replay equality: record everything a replay produces, and compare two records.

Used to check that a speed change changes no result: record the same .tlog with the old and the
new code (``PYTHONPATH`` of each tree), then compare (events must be identical, Estimates,
set and channel statuses equal to ``--atol``; NaN equals NaN).

    PYTHONPATH=OLD .venv/bin/python benchmarks/replay_equality.py record FLIGHT.tlog imu2 old.pkl
    PYTHONPATH=NEW .venv/bin/python benchmarks/replay_equality.py record FLIGHT.tlog imu2 new.pkl
    .venv/bin/python benchmarks/replay_equality.py compare old.pkl new.pkl

Configurations: ``fdi`` (estimators off), ``default`` (imu_ts + cmhe), ``imu2`` (imu_ts +
imu_hosm, air data off). ``record ... --events-only`` runs without the on_step callback (the
path without per-channel statuses) and records events and health only.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import pickle
import sys
from pathlib import Path
from typing import Any

import numpy as np

from gcs_monitor.config import MonitorConfig, load_config
from gcs_monitor.link.transports import TlogSource
from gcs_monitor.monitor import Monitor


def _config(name: str) -> MonitorConfig:
    """``fdi``: consensus FDI only (no estimator); ``default``; ``imu2``: both IMU estimators,
    air data on consensus."""
    cfg = MonitorConfig()
    if name == "default":
        return cfg
    imu = cfg.family("imu")
    on = name == "imu2"
    imu = dataclasses.replace(imu, enabled=on, ts=dataclasses.replace(imu.ts, enabled=on),
                              hosm=dataclasses.replace(imu.hosm, enabled=on))
    return cfg.with_family("imu", imu).with_family("airdata", estimator="none")


CONFIGS = ("fdi", "default", "imu2")


def _event(e: Any) -> tuple[Any, ...]:
    return (e.t_us, str(e.channel), e.state.value, e.kind.value, e.fault_type.value, e.magnitude,
            e.residual_rms, e.threshold, e.estimator, e.message, e.vehicle)


def record(tlog: str, cfg: MonitorConfig, with_step: bool = True) -> dict[str, Any]:
    """Events, per-frame Estimates, set and channel statuses and health of one replay."""
    rec: dict[str, Any] = {"est": {}, "sets": [], "chan": {}, "frames": []}

    def on_step(sysid: int, frame: Any, step: Any) -> None:
        rec["frames"].append((frame.t_us, frame.air_new, frame.gps_new,
                              None if frame.gps_vel_ned_mps is None
                              else tuple(frame.gps_vel_ned_mps)))
        for e in step.estimates:
            rec["est"].setdefault(e.name, []).append(
                (e.t_us, e.available, e.reason, e.numerics_ok, tuple(e.faults.values()),
                 tuple(e.residuals.values()), tuple(e.virtual.values()),
                 {k: np.array(v, dtype=float) for k, v in e.states.items()}))
        for s in step.sets:
            rec["sets"].append((s.name, s.t_us, s.measured, s.reference, s.fused, s.weights,
                                s.rms, s.faulty, s.configuration))
        for c in step.channels:
            rec["chan"].setdefault((c.estimator, str(c.channel)), []).append(
                (c.t_us, c.value, c.rms, c.faulty))

    mon = Monitor(cfg, on_step=on_step if with_step else None)
    with TlogSource(tlog) as src:
        for chunk, wall_s in src:
            mon.feed(chunk, wall_s)
    mon.finish()
    rec["events"] = [_event(e) for e in mon.events]
    rec["health"] = mon.health()
    return rec


def _eq(x: Any, y: Any) -> bool:
    if isinstance(x, float) and isinstance(y, float):
        return x == y or (x != x and y != y)
    if isinstance(x, (tuple, list)) and isinstance(y, (tuple, list)):
        return len(x) == len(y) and all(_eq(p, q) for p, q in zip(x, y, strict=False))
    if isinstance(x, dict) and isinstance(y, dict):
        return x.keys() == y.keys() and all(_eq(x[k], y[k]) for k in x)
    return bool(x == y)


def _diff(x: Any, y: Any) -> float:
    a = np.atleast_1d(np.asarray(x, dtype=float))
    b = np.atleast_1d(np.asarray(y, dtype=float))
    if a.shape != b.shape:
        return math.inf
    d = np.abs(a - b)
    d[(np.isnan(a) & np.isnan(b)) | (a == b)] = 0.0
    return float(np.nanmax(d)) if d.size else 0.0


def _health_core(h: dict[str, Any]) -> dict[str, Any]:
    vehicles = {k: {f: x for f, x in v.items() if f not in ("estimators", "families")}
                for k, v in h["vehicles"].items()}
    return {**h, "vehicles": vehicles}


def compare(a: dict[str, Any], b: dict[str, Any], atol: float) -> bool:
    """Print the differences of two records; True when they agree."""
    ok = _eq(a["events"], b["events"])
    print(f"events identical: {ok} ({len(a['events'])} vs {len(b['events'])})")
    same = _eq(a["frames"], b["frames"])
    print(f"frames identical: {same} ({len(a['frames'])})")
    ok &= same
    for name in sorted(set(a["est"]) | set(b["est"])):
        ea, eb = a["est"].get(name, []), b["est"].get(name, [])
        if len(ea) != len(eb):
            print(f"{name}: {len(ea)} vs {len(eb)} estimates")
            ok = False
            continue
        meta = all(_eq(x[:4], y[:4]) for x, y in zip(ea, eb, strict=False))
        md = {"faults": 0.0, "residuals": 0.0, "virtual": 0.0, "states": 0.0}
        for x, y in zip(ea, eb, strict=False):
            for i, k in ((4, "faults"), (5, "residuals"), (6, "virtual")):
                md[k] = max(md[k], _diff(x[i], y[i]))
            if set(x[7]) != set(y[7]):
                md["states"] = math.inf
            else:
                for k in x[7]:
                    md["states"] = max(md["states"], _diff(x[7][k], y[7][k]))
        print(f"{name}: {len(ea)} estimates, availability/numerics identical: {meta}, max |diff| "
              + " ".join(f"{k}={v:.3g}" for k, v in md.items()))
        ok &= meta and all(v <= atol for v in md.values())
    same = _eq(a["sets"], b["sets"])
    print(f"set statuses identical: {same} ({len(a['sets'])})")
    if not same and len(a["sets"]) == len(b["sets"]):
        flags = all(x[0] == y[0] and x[1] == y[1] and x[7] == y[7] and x[8] == y[8]
                    for x, y in zip(a["sets"], b["sets"], strict=False))
        m = max(max(_diff(x[i], y[i]) for i in (2, 3, 4, 5, 6))
                for x, y in zip(a["sets"], b["sets"], strict=False))
        print(f"  decisions identical: {flags}, values max |diff| {m:.3g}")
        ok &= flags and m <= atol
    elif not same:
        ok = False
    for k in sorted(set(a["chan"]) | set(b["chan"])):
        ca, cb = a["chan"].get(k, []), b["chan"].get(k, [])
        if not _eq(ca, cb):
            if len(ca) != len(cb):
                print(f"channel {k}: {len(ca)} vs {len(cb)} statuses")
                ok = False
                continue
            m = max(_diff(x[1:3], y[1:3]) for x, y in zip(ca, cb, strict=False))
            flags = all(x[0] == y[0] and x[3] == y[3] for x, y in zip(ca, cb, strict=False))
            print(f"channel {k}: values max |diff| {m:.3g}, decisions identical: {flags}")
            ok &= flags and m <= atol
    # the per-family availability summary is a report, not a result (its shape changed with
    # the families); everything else of the health must agree
    same = _eq(_health_core(a["health"]), _health_core(b["health"]))
    print(f"health identical (availability summary aside): {same}")
    ok &= same
    print("RESULT:", "SAME" if ok else "DIFFERENT")
    return ok


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("record")
    r.add_argument("tlog")
    r.add_argument("config", choices=CONFIGS)
    r.add_argument("out")
    r.add_argument("--events-only", action="store_true")
    r.add_argument("--config-file", type=Path, help="a monitor TOML applied over the configuration")
    c = sub.add_parser("compare")
    c.add_argument("a")
    c.add_argument("b")
    c.add_argument("--atol", type=float, default=1e-12)
    args = ap.parse_args()
    if args.cmd == "record":
        cfg = _config(args.config)
        cfg = load_config(args.config_file, base=cfg)
        rec = record(args.tlog, cfg, with_step=not args.events_only)
        with open(args.out, "wb") as f:
            pickle.dump(rec, f)
        print(f"{args.config}: {len(rec['events'])} events, {len(rec['frames'])} frames")
        return
    with open(args.a, "rb") as fa, open(args.b, "rb") as fb:
        a, b = pickle.load(fa), pickle.load(fb)
    sys.exit(0 if compare(a, b, args.atol) else 1)


if __name__ == "__main__":
    main()
