"""``sim-vehicle`` command line: argument parsing and the end-of-run summary only."""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from sim_vehicle.mavlink_out import load_signing_key, parse_hostport
from sim_vehicle.scenario import ScenarioError, list_presets, load_scenario, with_overrides

EXIT_BAD_INPUT = 2


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="sim-vehicle", description="Simulated aircraft with "
                                "sensor/actuator faults, streaming MAVLink 2.")
    sub = p.add_subparsers(dest="cmd", required=True)
    sub.add_parser("list", help="list presets with one-line descriptions")
    r = sub.add_parser("run", help="run a preset or scenario TOML file")
    r.add_argument("scenario", help="preset name (see `sim-vehicle list`) or path to a .toml")
    r.add_argument("--live", action="store_true", help="real time to UDP instead of a .tlog")
    r.add_argument("--udp", default="127.0.0.1:14550", help="HOST:PORT for --live (udpout)")
    r.add_argument("--out", default="runs", help="output directory (default: runs)")
    r.add_argument("--duration", type=float, default=None, help="override duration, s")
    r.add_argument("--seed", type=int, default=None, help="override seed")
    r.add_argument("--no-progress", action="store_true", help="no progress bar")
    r.add_argument("--signing-key", metavar="FILE",
                   help="MAVLink 2 sign every packet with this key (64 hex characters or 32 "
                        "raw bytes)")
    return p


def _summary(res: object) -> str:
    from sim_vehicle.run import RunResult

    assert isinstance(res, RunResult)
    sc = res.scenario
    lines = [
        f"scenario   {sc.name}  (airframe {sc.airframe}, seed {sc.seed})",
        f"duration   {res.vehicle_duration_s:.2f} s vehicle time in {res.wall_s:.2f} s wall "
        f"({res.realtime_factor:.1f}x real time)",
        "messages   " + ", ".join(f"{k} {v}" for k, v in sorted(res.counts.items())),
        f"           total {sum(res.counts.values())}",
        f"faults     {len(res.fault_events)} injected",
    ]
    for e in res.fault_events:
        end = "end" if e["t_end_s"] is None else f"{e['t_end_s']:g} s"
        lines.append(f"           {e['channel']:<14} {e['kind']:<12} {e['t_start_s']:g} s .. {end}")
    lines.append("files      " + (str(res.tlog_path) if res.tlog_path else "(live: no .tlog)"))
    lines.append(f"           {res.truth_path}")
    lines.append(f"           {res.scenario_path}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    if args.cmd == "list":
        presets = list_presets()
        width = max(len(n) for n, _ in presets)
        for name, desc in presets:
            print(f"{name:<{width}}  {desc}")
        return 0
    try:
        sc = with_overrides(load_scenario(args.scenario), duration_s=args.duration,
                            seed=args.seed)
        udp = parse_hostport(args.udp)
        key = load_signing_key(args.signing_key) if args.signing_key else None
    except (ScenarioError, ValueError, OSError) as e:
        print(f"sim-vehicle: error: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT
    from sim_vehicle.run import run_scenario

    if args.live:
        print(f"live: sending to udp {udp[0]}:{udp[1]} in real time for {sc.duration_s:g} s "
              "(Ctrl-C to stop)", file=sys.stderr)
    try:
        res = run_scenario(sc, Path(args.out), live=args.live, udp=udp,
                           progress=not args.no_progress, signing_key=key)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    print(_summary(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
