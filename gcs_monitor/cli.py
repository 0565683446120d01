"""gcs-monitor: live monitoring, tlog replay, alarm subscription, demo, evaluation, conversion.

Argument parsing and printing only; the work is done by the library modules.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import math
import os
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from gcs_monitor.config import ConfigError, MonitorConfig, load_config
from gcs_monitor.console import family_line, format_event, summarise_alarms
from gcs_monitor.demo import run_demo
from gcs_monitor.sinks import SharedSink

log = logging.getLogger("gcs_monitor")
DEFAULT_ZENOH = "tcp/127.0.0.1:7447"


# -- sinks -------------------------------------------------------------------------------------
class _Outputs:
    """The sinks of a run: one Zenoh session, one web viewer and one journal shared by every
    vehicle, opened before any data is read (a port in use stops the command with one line
    instead of a monitor that runs on without its outputs); closed by :meth:`close`."""

    def __init__(self, args: argparse.Namespace, cfg: MonitorConfig) -> None:
        self.args, self.cfg = args, cfg
        self.bus: Any = None
        self.viewer: Any = None
        self.journal: Any = None
        try:
            self._open()
        except BaseException:
            self.close()
            raise

    def _open(self) -> None:
        args, cfg = self.args, self.cfg
        if getattr(args, "journal", None):
            from gcs_monitor.sinks.journal import AlarmJournal

            self.journal = AlarmJournal(Path(args.journal))
            if self.journal.repair.repaired:
                print(f"gcs-monitor: journal {args.journal}: {self.journal.repair.describe()}",
                      file=sys.stderr, flush=True)
        if getattr(args, "web", False):
            from gcs_monitor.sinks.rerun_sink import WebViewer

            self.viewer = WebViewer(bind=args.web_bind, web_port=args.web_port,
                                    grpc_port=args.web_grpc_port)
            print(f"Rerun web viewer at {self.viewer.viewer_url}", flush=True)
        if getattr(args, "zenoh", False) or cfg.sinks.zenoh:
            from gcs_monitor.link.zenoh_bus import RoleDefaults, open_bus

            listen = tuple(args.zenoh_listen or cfg.sinks.zenoh_listen)
            connect = tuple(args.zenoh_connect or cfg.sinks.zenoh_connect)
            self.bus = open_bus(_zenoh_options(args), what="zenoh",
                                defaults=RoleDefaults(listen=listen, connect=connect))

    def blueprint(self, sysid: int) -> Any:
        from dashboards.blueprints import default_blueprint, family_views

        return default_blueprint(sysid, family_views(self.cfg))

    def __call__(self, sysid: int) -> list[Any]:
        args, cfg = self.args, self.cfg
        sinks: list[Any] = []
        rrd = None
        if getattr(args, "rrd", None):
            rrd = Path(args.rrd)
            if sysid != 1:
                rrd = rrd.with_name(f"{rrd.stem}_v{sysid}{rrd.suffix}")
        if rrd is not None or self.viewer is not None:
            from gcs_monitor.sinks.rerun_sink import RerunSink

            sinks.append(RerunSink(
                sysid, rrd_path=rrd, plot_rate_hz=cfg.sinks.rerun_rate_hz,
                connect_grpc=self.viewer.grpc_url if self.viewer is not None else None,
                blueprint=self.blueprint(sysid)))
        if self.bus is not None:
            from gcs_monitor.sinks.zenoh_sink import ZenohSink

            sinks.append(ZenohSink(sysid, bus=self.bus,
                                   estimate_rate_hz=cfg.sinks.estimate_rate_hz))
        if getattr(args, "mavlink_alarms", None):
            from gcs_monitor.sinks.mavlink_sink import COMPID_DEFAULT, MavlinkAlarmSink

            sinks.append(MavlinkAlarmSink(
                args.mavlink_alarms, vehicle=sysid, sysid=args.mavlink_alarms_sysid,
                compid=args.mavlink_alarms_compid or COMPID_DEFAULT,
                named_values=args.mavlink_named_values, queue_size=cfg.sinks.queue_size))
        if self.journal is not None:
            sinks.append(SharedSink(self.journal))
        return sinks

    def close(self) -> None:
        if self.journal is not None:
            self.journal.close()
        if self.bus is not None:
            self.bus.close()
        if self.viewer is not None:
            self.viewer.close()



def _add_zenoh_args(p: argparse.ArgumentParser, *, listen_default: str,
                    connect_default: str, mode_default: str = "peer") -> None:
    g = p.add_argument_group("Zenoh")
    g.add_argument("--zenoh-listen", action="append", metavar="ENDPOINT",
                   help=f"endpoint to listen on, tcp/HOST:PORT or tls/HOST:PORT ({listen_default})")
    g.add_argument("--zenoh-connect", action="append", metavar="ENDPOINT",
                   help=f"router or peer to connect to ({connect_default})")
    g.add_argument("--zenoh-mode", choices=["peer", "client", "router"], default=None,
                   help=f"Zenoh mode (default {mode_default}, or the config file's)")
    g.add_argument("--zenoh-config", type=Path, metavar="FILE",
                   help="Zenoh JSON5 configuration: TLS (transport/link/tls), access control "
                        "(access_control), ...; the options above override it")
    g.add_argument("--zenoh-ca", type=Path, metavar="PEM",
                   help="TLS: the CA certificate that verifies the other side")
    g.add_argument("--zenoh-cert", type=Path, metavar="PEM",
                   help="TLS: this side's certificate (mutual TLS: listeners then require one)")
    g.add_argument("--zenoh-key", type=Path, metavar="PEM", help="TLS: this side's private key")
    g.add_argument("--zenoh-lease-s", type=float, metavar="S",
                   help="a peer that goes silent is dropped after this long (Zenoh: 10 s)")


def _zenoh_options(args: argparse.Namespace, *, connect_timeout_s: float | None = None,
                   listen: Sequence[str] | None = None,
                   connect: Sequence[str] | None = None) -> Any:
    from gcs_monitor.link.zenoh_bus import ZenohOptions

    listen = listen if listen is not None else getattr(args, "zenoh_listen", None)
    connect = connect if connect is not None else getattr(args, "zenoh_connect", None)
    return ZenohOptions(
        mode=getattr(args, "zenoh_mode", None),
        listen=tuple(listen) if listen else None,
        connect=tuple(connect) if connect else None,
        config_file=getattr(args, "zenoh_config", None),
        tls_ca=getattr(args, "zenoh_ca", None), tls_cert=getattr(args, "zenoh_cert", None),
        tls_key=getattr(args, "zenoh_key", None),
        connect_timeout_s=connect_timeout_s, lease_s=getattr(args, "zenoh_lease_s", None))


def _add_signing_args(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("MAVLink 2 signing")
    g.add_argument("--signing-key", type=Path, metavar="FILE",
                   help="signing key (64 hex characters or 32 raw bytes): badly signed and "
                        "replayed packets are rejected, counted and alarmed (LINK/signature)")
    g.add_argument("--require-signing", action="store_true",
                   help="also reject unsigned packets (needs --signing-key)")


def _decoder(args: argparse.Namespace) -> Any:
    """The link decoder of a command: with the signing key and policy of its options."""
    from gcs_monitor.link.decode import Decoder

    key_file = getattr(args, "signing_key", None)
    if getattr(args, "require_signing", False) and key_file is None:
        raise ValueError("--require-signing needs --signing-key FILE")
    if key_file is None:
        return Decoder()
    from gcs_monitor.link.signing import load_signing_key

    return Decoder(signing_key=load_signing_key(key_file),
                   require_signing=bool(args.require_signing))


def _add_sink_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", type=Path, help="monitor TOML (defaults suit the simulator)")
    p.add_argument("--rrd", type=Path, help="write a Rerun recording (.rrd) per vehicle")
    p.add_argument("--web", action="store_true",
                   help="serve the Rerun web viewer (with --rrd: both)")
    p.add_argument("--web-bind", default="127.0.0.1", metavar="ADDR",
                   help="address the web viewer listens on (default 127.0.0.1: this host only)")
    p.add_argument("--web-port", type=int, default=9090, help="web viewer port (9090)")
    p.add_argument("--web-grpc-port", type=int, default=9876,
                   help="the viewer's gRPC port (9876)")
    p.add_argument("--zenoh", action="store_true", help="publish alarms/estimates/health on Zenoh")
    p.add_argument("--journal", type=Path, help="append alarms as JSON lines to this file")
    p.add_argument("--record-tlog", type=Path, help="record the raw input to a .tlog")
    p.add_argument("--mavlink-alarms", metavar="URL",
                   help="send every alarm raise and clear as STATUSTEXT to a ground station "
                        "(udpout:HOST:PORT or tcp:HOST:PORT)")
    p.add_argument("--mavlink-alarms-sysid", type=int, default=None,
                   help="source system id of the alarms (default: the vehicle's, so ground "
                        "stations show them with its messages; 255 = a GCS)")
    p.add_argument("--mavlink-alarms-compid", type=int, default=None,
                   help="source component id of the alarms (default 191, "
                        "MAV_COMP_ID_ONBOARD_COMPUTER)")
    p.add_argument("--mavlink-named-values", action="store_true",
                   help="also send each set's fused value as NAMED_VALUE_FLOAT")
    p.add_argument("--quiet", action="store_true", help="print only the summary")
    _add_zenoh_args(p, listen_default=DEFAULT_ZENOH, connect_default="none")


def _add_log_args(p: argparse.ArgumentParser) -> None:
    from gcs_monitor.convert.logs import FORMATS

    p.add_argument("--format", choices=sorted(FORMATS),
                   help="force the log format (default: detected from the content)")
    p.add_argument("--map", type=Path, metavar="COLUMNS.toml",
                   help="column map of a generic CSV (gcs_monitor/convert/maps/ has examples)")
    p.add_argument("--imu-rate-hz", type=float, default=None,
                   help="highest IMU rate given to the monitor from a .bin/.ulg (block means "
                        "above it; default 100 Hz, the contract's HIGHRES_IMU rate)")


def _source_counters(src: Any) -> dict[str, Any]:
    return {"dropped_chunks": src.dropped_chunks, "dropped_bytes": src.dropped_bytes,
            "resync_bytes": src.resync_bytes, "kernel_drops": getattr(src, "kernel_drops", None),
            "truncated_bytes": getattr(src, "truncated_bytes", 0)}


def _run_source(src: Any, args: argparse.Namespace, *, duration_s: float | None = None,
                progress: Any = None, sinks_for: Callable[[int], list[Any]] | None = None,
                on_wall: Callable[[Any, float], None] | None = None,
                raw: Callable[[Any], None] | None = None,
                summary: bool = True, inherit: bool = False, banner: str = "") -> Any:
    """Run a byte source through a Monitor; return the Monitor (its health and events).

    ``inherit``: alarms the journal says are active are inherited (a restarted live monitor:
    no duplicate raise); a replay starts afresh."""
    from gcs_monitor.monitor import Monitor

    cfg = load_config(args.config)
    outputs = None
    try:
        decoder = _decoder(args)
        if sinks_for is None:
            outputs = _Outputs(args, cfg)
            sinks_for = outputs
    except BaseException:
        src.close()
        raise
    tlog_out = None
    if args.record_tlog:
        from gcs_monitor.sinks.tlog_writer import TlogWriter

        tlog_out = TlogWriter(args.record_tlog)
    raws = [f for f in (tlog_out.write_message if tlog_out else None, raw) if f is not None]

    def raw_sink(msg: Any) -> None:
        for f in raws:
            f(msg)

    if banner:
        print(banner, flush=True)
    active = outputs.journal.active_alarms() if inherit and outputs is not None and \
        outputs.journal is not None else None
    monitor: Any = Monitor(cfg, sinks_for=sinks_for, decoder=decoder,
                      raw_sink=raw_sink if raws else None, inherit=active)
    t0 = time.monotonic()
    next_health = t0
    rejected = 0
    next_reject_note = t0
    try:
        for data, wall in src:
            for ev in monitor.feed(data, wall):
                if not args.quiet:
                    print(format_event(ev), flush=True)
            now = time.monotonic()
            if on_wall is not None:
                on_wall(monitor, now)
            c = monitor.decoder.counters
            if c.bad_signature > rejected and now >= next_reject_note:
                # said at once, then at most every 5 s while it goes on
                print(f"gcs-monitor: {c.bad_signature - rejected} packets rejected by "
                      f"signing (unsigned {c.unsigned_rejected}, wrong key {c.wrong_key}, "
                      f"replayed {c.replayed} so far)", file=sys.stderr, flush=True)
                rejected = c.bad_signature
                next_reject_note = now + 5.0
            if now >= next_health:
                monitor.source_counters = _source_counters(src)
                monitor.publish_health()
                next_health = now + 1.0
            if duration_s is not None and now - t0 >= duration_s:
                break
        for ev in monitor.finish():
            if not args.quiet:
                print(format_event(ev), flush=True)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
    finally:
        src.close()
        monitor.source_counters = _source_counters(src)
        monitor.close()
        if tlog_out is not None:
            tlog_out.close()
        if progress is not None:
            progress.close()
        if outputs is not None:
            outputs.close()
    monitor.wall_s = time.monotonic() - t0
    if summary:
        _print_summary(monitor, monitor.wall_s)
    return monitor


def usable(monitor: Any) -> bool:
    """Whether a replay gave the monitor any vehicle Frame to judge."""
    return any(v.assembler.frames_out > 0 for v in monitor.vehicles.values())


def _print_summary(monitor: Any, wall_s: float) -> None:
    h = monitor.health()
    print(f"\n== summary ({wall_s:.1f} s wall) ==")
    link = h["link"]
    kd = link.get("kernel_drops")
    print(f"link: {link['bytes_in']} bytes, {link['parse_errors']} CRC/parse errors, "
          f"{link['bad_signature']} rejected by signing (unsigned {link['unsigned_rejected']}, "
          f"wrong key {link['wrong_key']}, replayed {link['replayed']}), "
          f"{link.get('dropped_chunks', 0)} dropped chunks, "
          f"{'n/a' if kd is None else kd} kernel drops")
    if not h["vehicles"]:
        print("no vehicle seen")
    for sysid, v in h["vehicles"].items():
        lk = v["link"]
        if not lk["per_type"]:
            continue
        print(f"vehicle {sysid}: {lk['messages']} msgs, lost {lk['lost']} "
              f"({lk['loss_pct']:.2f} %), reboots {lk['reboots']}, "
              f"bad values {sum(lk['bad_values'].values())}, "
              f"vehicle time {v['vehicle_time_s']:.1f} s")
        if lk["signature_failures"]:
            print(f"  signing: {lk['signature_failures']} rejected (unsigned "
                  f"{lk['unsigned_rejected']}, wrong key {lk['wrong_key']}, replayed "
                  f"{lk['replayed']}), {lk['signed_packets']} signed accepted")
        for note in v["notes"]:
            print(f"  warning: {note}")
        for name, fam in v["families"].items():
            print("  " + family_line(name, fam))
    for sysid, st in sorted(monitor.decoder.stats.items()):
        if str(sysid) not in h["vehicles"] and st.signature_failures:
            print(f"sender {sysid}: {st.signature_failures} packets rejected by signing "
                  f"(unsigned {st.unsigned_rejected}, wrong key {st.wrong_key}, replayed "
                  f"{st.replayed}), none accepted")
    rows = summarise_alarms(monitor.events)
    if rows:
        print("\nalarms (per vehicle and channel: first raise | final state):")
        for r in rows:
            print("  " + r)
    else:
        print("\nno alarms")


# -- commands ----------------------------------------------------------------------------------
def cmd_live(args: argparse.Namespace) -> int:
    from gcs_monitor.link.transports import open_source

    src = open_source(args.url, idle_timeout_s=args.idle_timeout,
                      zenoh_options=_zenoh_options(args) if args.url.startswith("zenoh:")
                      else None)
    banner = f"listening on {args.url} (Ctrl-C to stop)"
    if not args.request_rates:
        _run_source(src, args, duration_s=args.duration, inherit=True, banner=banner)
        return 0
    from gcs_monitor.link.rates import RateRequester, rates_table

    req = RateRequester(src.write, measure_s=args.rates_report_after)

    def poll(monitor: Any, now: float) -> None:
        res = req.poll(now)
        if res is not None:
            print("\nmessage rates (requested with MAV_CMD_SET_MESSAGE_INTERVAL, "
                  "REQUEST_DATA_STREAM where not accepted):\n" + rates_table(res), flush=True)

    _run_source(src, args, duration_s=args.duration, raw=req.on_message, on_wall=poll,
                inherit=True, banner=banner)
    return 0


def cmd_bridge(args: argparse.Namespace) -> int:
    from gcs_monitor.fleet.bridge import Bridge
    from gcs_monitor.link.transports import open_source
    from gcs_monitor.link.zenoh_bus import RoleDefaults, open_bus

    decoder = _decoder(args)
    bus = open_bus(_zenoh_options(args), what="bridge",
                   defaults=RoleDefaults(mode="client", connect=(DEFAULT_ZENOH,)))
    try:
        src = open_source(args.url, idle_timeout_s=args.idle_timeout,
                          speed=args.speed if args.url.endswith(".tlog") else None)
    except BaseException:
        bus.close()
        raise
    print(f"bridge: {args.url} -> mavlink/<sysid>/rx on {', '.join(bus.connect + bus.listen)} "
          f"(Ctrl-C to stop)", flush=True)
    bridge = Bridge(src, bus, decoder=decoder, name=args.name, flush_s=args.flush_ms / 1000.0)
    try:
        st = bridge.run(duration_s=args.duration)
    finally:
        src.close()
        bus.close()
    c = decoder.counters
    kd = getattr(src, "kernel_drops", None)
    print(f"bridge: {st.frames} frames in {st.samples} samples from "
          f"{len(st.per_sysid)} vehicles; {c.parse_errors} CRC/parse errors, "
          f"{c.bad_signature} rejected by signing (unsigned {c.unsigned_rejected}, wrong key "
          f"{c.wrong_key}, replayed {c.replayed}), {src.dropped_chunks} dropped chunks, "
          f"{'n/a' if kd is None else kd} kernel drops")
    return 0


def cmd_worker(args: argparse.Namespace) -> int:
    import signal

    from gcs_monitor.fleet.ownership import parse_shard
    from gcs_monitor.fleet.worker import Worker, WorkerOptions, default_worker_id
    from gcs_monitor.link.signing import load_signing_key
    from gcs_monitor.link.zenoh_bus import RoleDefaults, open_bus

    cfg = load_config(args.config)
    if args.require_signing and args.signing_key is None:
        raise ValueError("--require-signing needs --signing-key FILE")
    opts = WorkerOptions(
        group=args.group, worker_id=args.name or default_worker_id(), scope=args.keyexpr,
        shard=parse_shard(args.shard) if args.shard else None, buffer_s=args.buffer_s,
        grace_s=args.grace_s,
        signing_key=load_signing_key(args.signing_key) if args.signing_key else None,
        require_signing=args.require_signing, journal=args.journal)
    bus = open_bus(_zenoh_options(args), what="worker",
                   defaults=RoleDefaults(mode="client", connect=(DEFAULT_ZENOH,)))
    try:
        worker = Worker(cfg, opts, bus, on_event=None if args.quiet else
                        (lambda ev: print(format_event(ev), flush=True)))
        if worker.journal is not None and worker.journal.repair.repaired:
            print(f"gcs-monitor: journal {args.journal}: {worker.journal.repair.describe()}",
                  file=sys.stderr, flush=True)
        signal.signal(signal.SIGTERM, lambda *_: worker.stop())
        print(f"worker {opts.worker_id} (group {opts.group}, scope {opts.scope}"
              + (f", shard {args.shard}" if args.shard else "") + ") on "
              + ", ".join(bus.connect + bus.listen) + " (Ctrl-C to stop)", flush=True)
        try:
            worker.run(duration_s=args.duration)
        except KeyboardInterrupt:
            print("interrupted", file=sys.stderr)
        finally:
            worker.close()
    finally:
        bus.close()
    print(f"worker {opts.worker_id}: owned {sorted(worker.owned) or '-'} at the end; "
          f"{len(worker.events)} alarm events; {len(worker.handovers)} vehicles taken")
    rows = summarise_alarms(worker.events)
    for r in rows:
        print("  " + r)
    return 0


def cmd_router(args: argparse.Namespace) -> int:
    from gcs_monitor.link.zenoh_bus import RoleDefaults, open_bus

    opts = _zenoh_options(args)
    if opts.mode is None:
        import dataclasses

        opts = dataclasses.replace(opts, mode="router")
    bus = open_bus(opts, what="router", defaults=RoleDefaults(mode="router",
                                                              listen=(DEFAULT_ZENOH,)))
    print(f"router {bus.zid} listening on {', '.join(bus.listen) or '-'}"
          + (f", connected to {', '.join(bus.connect)}" if bus.connect else "")
          + " (Ctrl-C to stop)", flush=True)
    try:
        t_end = None if args.duration is None else time.monotonic() + args.duration
        while t_end is None or time.monotonic() < t_end:
            time.sleep(0.2)
    except KeyboardInterrupt:
        pass
    finally:
        bus.close()
    return 0


EXIT_UNUSABLE = 2  # a file could not be used at all (missing, empty, unknown, no data)
EXIT_PARTIAL = 3  # every file was used, but some only in part (cut mid-record)


def _log_sinks(args: argparse.Namespace, path: Path, several: bool) -> argparse.Namespace:
    """Per-file output names when several logs are replayed in one command."""
    if not several or not getattr(args, "rrd", None):
        return args
    a = argparse.Namespace(**vars(args))
    a.rrd = args.rrd.with_name(f"{args.rrd.stem}_{path.stem}{args.rrd.suffix}")
    return a


def _open_log(path: Path, args: argparse.Namespace, progress: Any = None) -> Any:
    from gcs_monitor.link.logs import open_log

    return open_log(path, args.format, speed=getattr(args, "speed", None),
                    column_map=args.map, imu_rate_hz=args.imu_rate_hz, on_progress=progress)


def _batch_end(failures: list[tuple[Path, str]], partial: list[Path], n: int) -> int:
    if failures:
        print(f"\n{len(failures)} of {n} files could not be used:", file=sys.stderr)
        for path, why in failures:
            print(f"  {path}: {why}", file=sys.stderr)
    if partial:
        print(f"{len(partial)} of {n} files were read only in part: "
              + ", ".join(str(p) for p in partial), file=sys.stderr)
    return EXIT_UNUSABLE if failures else (EXIT_PARTIAL if partial else 0)


def _no_vehicle(path: Path, fmt: str) -> str:
    from gcs_monitor.convert.logbase import KNOWN_FORMATS

    return (f"{path}: no vehicle telemetry the monitor can use in this {fmt} (no vehicle "
            f"sent IMU messages); expected {KNOWN_FORMATS}")


def replay_one(path: Path, args: argparse.Namespace, *, several: bool = False,
               sinks_for: Callable[[int], list[Any]] | None = None,
               on_step: Any = None) -> tuple[Any, Any]:
    """Replay one log: (monitor, LogInfo). Raises LogError when the file cannot be used."""
    from tqdm import tqdm

    from gcs_monitor.convert.logbase import LogError

    bar = tqdm(total=100, unit="%", desc=path.name,
               disable=args.quiet or not sys.stderr.isatty())
    last = [0.0]

    def progress(done: int, total: int) -> None:
        pct = 100.0 * done / total if total else 0.0
        bar.update(pct - last[0])
        last[0] = pct

    opened = _open_log(path, args, progress)
    a = _log_sinks(args, path, several)
    monitor = _run_source(opened.source, a, progress=bar, sinks_for=sinks_for, summary=False)
    info = opened.info
    if info.fmt == "tlog":
        info.messages = _tlog_counts(monitor)
        if getattr(opened.source, "truncated_bytes", 0):
            info.warnings.append(f"the file ends {opened.source.truncated_bytes} bytes into "
                                 "an incomplete record (cut file?); read up to it")
    if not usable(monitor):
        raise LogError(_no_vehicle(path, info.fmt))
    return monitor, info


def _tlog_counts(monitor: Any) -> dict[str, int]:
    out: dict[str, int] = {}
    for st in monitor.decoder.stats.values():
        for k, n in st.per_type.items():
            out[k] = out.get(k, 0) + int(n)
    return out


def cmd_replay(args: argparse.Namespace) -> int:
    from gcs_monitor.convert.logbase import LogError

    failures: list[tuple[Path, str]] = []
    partial: list[Path] = []
    several = len(args.inputs) > 1
    for path in args.inputs:
        if several:
            print(f"\n== {path} ==", flush=True)
        try:
            monitor, info = replay_one(path, args, several=several)
        except LogError as exc:
            print(f"gcs-monitor: {exc}", file=sys.stderr)
            failures.append((path, str(exc).removeprefix(f"{path}: ")))
            continue
        print(f"{path.name}: {info.fmt}"
              + (f", {info.vehicle}" if info.vehicle else "")
              + (f", {info.duration_s:.1f} s" if info.duration_s else ""))
        for w in info.warnings:
            print(f"gcs-monitor: {path}: {w}", file=sys.stderr)
        if any("incomplete record" in w for w in info.warnings):
            partial.append(path)
        _print_summary(monitor, monitor.wall_s)
    return _batch_end(failures, partial, len(args.inputs))


def cmd_alarms(args: argparse.Namespace) -> int:
    from gcs_monitor.sinks.zenoh_sink import run_alarm_printer

    connect = args.connect or args.zenoh_connect or [DEFAULT_ZENOH]
    opts = _zenoh_options(args, connect=connect, connect_timeout_s=args.connect_timeout)
    run_alarm_printer(args.keyexpr, connect=connect, duration_s=args.duration,
                      max_alarms=args.max, json_lines=args.json, options=opts,
                      history=args.history)
    return 0


class _NoTruth:
    """An empty stand-in for a truth file that is not there (``with`` and ``files``)."""

    files: tuple[str, ...] = ()

    def __enter__(self) -> _NoTruth:
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def __getitem__(self, key: str) -> Any:
        raise KeyError(key)


def cmd_convert(args: argparse.Namespace) -> int:
    from gcs_monitor.convert.formats import ConvertError
    from gcs_monitor.convert.logbase import LogError
    from gcs_monitor.convert.logs import detect_log_format
    from gcs_monitor.convert.writer import convert_file, lu2016_table2_injector

    args.out.mkdir(parents=True, exist_ok=True)
    inject = lu2016_table2_injector() if args.inject == "lu2016" else None
    failures: list[tuple[Path, str]] = []
    partial: list[Path] = []
    for path in args.inputs:
        out = args.out / (path.stem + (".lu2016" if inject else "") + ".tlog")
        try:
            fmt = "csvmap" if args.map else (args.format or detect_log_format(path))
            if fmt in ("zipline", "onspeed", "alfa") or inject is not None:
                res = convert_file(path, out, fmt=fmt if fmt != "csvmap" else None,
                                   inject_imu=inject)
                n = sum(res.messages.values())
                print(f"{path.name}: {res.fmt}, {res.duration_s:.1f} s, {n} messages -> {out}")
                if res.truth_path is not None:
                    print(f"  ground truth (failure status, never on the link) -> "
                          f"{res.truth_path}")
                if inject is not None and res.injected_imu is not None:
                    import numpy as np

                    truth = out.with_suffix(".truth.npz")
                    with np.load(truth) if truth.exists() else _NoTruth() as old:
                        kept = {k: old[k] for k in old.files}  # a real failure's truth stays
                    np.savez(truth, t_s=res.t_s, imu_fault=res.injected_imu, **kept)
                continue
            info = _write_log_tlog(path, out, args, fmt)
        except (LogError, ConvertError) as exc:
            print(f"gcs-monitor: {exc}", file=sys.stderr)
            failures.append((path, str(exc).removeprefix(f"{path}: ")))
            continue
        n = sum(info.messages.values())
        print(f"{path.name}: {info.fmt}, {info.duration_s:.1f} s, {n} messages -> {out}")
        for w in info.warnings:
            print(f"gcs-monitor: {path}: {w}", file=sys.stderr)
        if any("incomplete record" in w for w in info.warnings):
            partial.append(path)
    return _batch_end(failures, partial, len(args.inputs))


def _write_log_tlog(path: Path, out: Path, args: argparse.Namespace, fmt: str) -> Any:
    """Any log the monitor reads, written as the contract .tlog it replays."""
    import shutil

    from gcs_monitor.link.logs import open_log

    if fmt == "tlog":
        shutil.copyfile(path, out)
        from gcs_monitor.convert.logbase import LogInfo

        return LogInfo(path=path, fmt="tlog")
    opened = open_log(path, fmt, column_map=args.map, imu_rate_hz=args.imu_rate_hz)
    from gcs_monitor.link.transports import TLOG_HEADER

    tmp = out.with_suffix(out.suffix + ".tmp")
    try:
        with open(tmp, "wb") as fh:
            _tlog_records(opened.source, fh, TLOG_HEADER)
        tmp.replace(out)
    finally:
        tmp.unlink(missing_ok=True)
    return opened.info


def _tlog_records(src: Any, fh: Any, header: Any) -> None:
    from gcs_monitor.link.decode import Decoder

    dec = Decoder(resync=False)
    for data, wall in src:
        for m in dec.feed(data, wall):
            fh.write(header.pack(int(round(wall * 1e6))) + bytes(m.get_msgbuf()))


def cmd_report(args: argparse.Namespace) -> int:
    from gcs_monitor.convert.logbase import LogError
    from gcs_monitor.report import write_report

    failures: list[tuple[Path, str]] = []
    partial: list[Path] = []
    cfg = load_config(args.config)
    for path in args.inputs:
        try:
            page = write_report(path, args.out, cfg=cfg, fmt=args.format, column_map=args.map,
                                imu_rate_hz=args.imu_rate_hz)
        except LogError as exc:
            print(f"gcs-monitor: {exc}", file=sys.stderr)
            failures.append((path, str(exc).removeprefix(f"{path}: ")))
            continue
        print(f"{path.name}: report -> {page}")
    return _batch_end(failures, partial, len(args.inputs))


def cmd_config(args: argparse.Namespace) -> int:
    from gcs_monitor.config import config_markdown, config_toml

    if args.markdown:
        print(config_markdown(), end="")
        return 0
    if args.file is None and not args.defaults:
        print("gcs-monitor config: give --defaults, --markdown or a FILE to check",
              file=sys.stderr)
        return 2
    cfg = load_config(args.file)  # the defaults without a file
    print(config_toml(cfg, comments=not args.no_comments), end="")
    return 0


def cmd_calibrate(args: argparse.Namespace) -> int:
    from gcs_monitor.calibrate import (
        calibrate,
        calibration_toml,
        margins_table,
        parse_flight,
        spike_warnings,
    )

    base = load_config(args.config)
    try:
        flights = [parse_flight(f) for f in args.flights]
    except ValueError as e:
        print(f"gcs-monitor calibrate: {e}", file=sys.stderr)
        return 2
    missing = [f.path for f in flights if not f.path.is_file()]
    if missing:
        print(f"gcs-monitor calibrate: no such file: {', '.join(map(str, missing))}",
              file=sys.stderr)
        return 2
    design = args.out.parent / f"{args.out.stem}.yaw_rate.json"  # the yaw-rate design
    cal = calibrate(flights, base, margin=args.margin, design_path=design,
                    progress=lambda m: print(m, file=sys.stderr, flush=True))
    print("noise model (1 sigma, SI): " + ", ".join(
        f"{k} {v:.3g}" for k, v in cal.noise.items() if math.isfinite(v)))
    yaw = base.family("yaw_rate")
    for line in cal.yaw_rate.summary(yaw.design, yaw.observer.eas_margin):
        print(line)
    print("thresholds J_th (SI): " + ", ".join(f"{k} {v:.4g}" for k, v in
                                               sorted(cal.thresholds.items())))
    print("\nlargest J of each flight as a share of the new J_th (1 / margin at the worst), "
          "when (vehicle time), and the flight's 95th percentile of J (p95) as a share of it:")
    for line in margins_table(cal):
        print(line)
    warnings = spike_warnings(cal)
    if warnings:
        print()
        for line in warnings:
            print(line)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    if cal.yaw_rate.design_path is not None:  # written beside the TOML, named relative to it
        cal = dataclasses.replace(cal, config=cal.config.with_family(
            "yaw_rate", design=os.path.relpath(cal.yaw_rate.design_path.resolve(),
                                               args.out.parent.resolve())))
    args.out.write_text(calibration_toml(cal, base, flights))
    print(f"\nwrote {args.out} (use it with --config)")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    return run_demo(args.out, preset=args.preset)


def cmd_evaluate(args: argparse.Namespace) -> int:
    from gcs_monitor.evaluation import registry

    if args.preset_set:
        from gcs_monitor.evaluation.campaign import run_campaign

        res = run_campaign(args.preset_set, args.runs, args.jobs, args.out, seed=args.seed,
                           config=load_config(args.config) if args.config else None,
                           declare_weather=args.weather == "declared")
        print(res.markdown)
        return 0
    experiments = registry.experiments(args.data_dir)
    if args.list:
        width = max(map(len, experiments))
        for name in sorted(experiments):
            print(f"{name:<{width}}  {registry.summary(experiments[name])}")
        return 0
    if not args.experiment or args.experiment not in experiments:
        names = ", ".join(sorted(experiments))
        what = f"unknown experiment {args.experiment!r}; " if args.experiment else ""
        print(f"{what}choose --preset-set NAME or --experiment NAME (--list describes them); "
              f"experiments: {names}", file=sys.stderr)
        return 2
    print(experiments[args.experiment](args.out, args.jobs, args.quick))
    return 0


def cmd_yaw_design(args: argparse.Namespace) -> int:
    from gcs_monitor.evaluation.papers.chen2020_design import write_design

    for airframe in args.airframe or ["transport", "uav"]:
        path, bands = write_design(airframe, args.out)
        print(f"{airframe}: {path}")
        for d in bands:
            bounds = ", ".join(f"{s}: {v.gamma:.4g}" for s, v in d.sensors.items())
            fit = d.meta["fit"]
            lo, hi = d.alt_range_m
            print(f"  {lo:g}-{hi:g} m: LPV fit A rel. error {fit['rel_A']:.3g}, B "
                  f"{fit['rel_B']:.3g}; L2-gain bounds {bounds}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="gcs-monitor", description=__doc__)
    p.add_argument("-v", "--verbose", action="store_true")
    sub = p.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("live", help="monitor a live MAVLink link")
    s.add_argument("url", help="udpin:HOST:PORT | udpout:HOST:PORT | tcp:HOST:PORT | /dev/ttyX"
                              "[:BAUD] | zenoh:KEYEXPR[@ENDPOINT]")
    s.add_argument("--duration", type=float, help="stop after this many seconds")
    s.add_argument("--idle-timeout", type=float,
                   help="stop after this long without data, counted from the first data (s)")
    s.add_argument("--request-rates", action="store_true",
                   help="ask the autopilot for the message rates the families need "
                        "(MAV_CMD_SET_MESSAGE_INTERVAL, else REQUEST_DATA_STREAM) and report "
                        "the rates measured")
    s.add_argument("--rates-report-after", type=float, default=5.0,
                   help="seconds after the requests to measure and report the rates")
    _add_sink_args(s)
    _add_signing_args(s)
    s.set_defaults(func=cmd_live)
    s = sub.add_parser("bridge", help="put a link's raw MAVLink frames on Zenoh "
                                      "(mavlink/<sysid>/rx) for fleet workers")
    s.add_argument("url", help="udpin:HOST:PORT | udpout:HOST:PORT | tcp:HOST:PORT | /dev/ttyX"
                               "[:BAUD] | FILE.tlog")
    s.add_argument("--name", default="bridge", help="name of the bridge's health queryable")
    s.add_argument("--duration", type=float, help="stop after this many seconds")
    s.add_argument("--idle-timeout", type=float, help="stop after this long without data (s)")
    s.add_argument("--speed", type=float, help="replay speed of a .tlog (default: as fast as "
                                                 "possible)")
    s.add_argument("--flush-ms", type=float, default=20.0,
                   help="a vehicle's frames wait at most this long to be sent together (20; "
                        "fewer, larger samples cost the workers less)")
    _add_signing_args(s)
    _add_zenoh_args(s, listen_default="none", connect_default=DEFAULT_ZENOH,
                    mode_default="client")
    s.set_defaults(func=cmd_bridge)
    s = sub.add_parser("worker", help="monitor a share of the fleet from Zenoh; take over the "
                                      "vehicles of workers that stop")
    s.add_argument("--keyexpr", default="mavlink/*/rx",
                   help="raw frames this worker may monitor (default mavlink/*/rx: any "
                        "vehicle; mavlink/3/rx: only vehicle 3)")
    s.add_argument("--shard", metavar="I/N", help="primary share: the system ids with "
                   "sysid %% N == I (the others take them when no primary lives)")
    s.add_argument("--group", default="default", help="fleet group (default 'default')")
    s.add_argument("--name", help="worker id (default HOST-PID)")
    s.add_argument("--buffer-s", type=float, default=15.0,
                   help="seconds of other workers' vehicles kept for a takeover without a gap")
    s.add_argument("--grace-s", type=float, default=20.0,
                   help="vehicle time within which an inherited alarm must be confirmed")
    s.add_argument("--duration", type=float, help="stop after this many seconds")
    s.add_argument("--config", type=Path, help="monitor TOML (defaults suit the simulator)")
    s.add_argument("--journal", type=Path, help="append alarms as JSON lines to this file "
                                                "(active ones are inherited at a restart)")
    s.add_argument("--quiet", action="store_true", help="print only the summary")
    _add_signing_args(s)
    _add_zenoh_args(s, listen_default="none", connect_default=DEFAULT_ZENOH,
                    mode_default="client")
    s.set_defaults(func=cmd_worker)
    s = sub.add_parser("router", help="a Zenoh router (what zenohd is at a site) for bridges, "
                                      "workers and subscribers")
    s.add_argument("--duration", type=float, help="stop after this many seconds")
    _add_zenoh_args(s, listen_default=DEFAULT_ZENOH, connect_default="none",
                    mode_default="router")
    s.set_defaults(func=cmd_router)
    s = sub.add_parser("replay", help="replay flight logs (.tlog, ArduPilot .bin/.log, PX4 .ulg, "
                                      "CSV) through the monitor")
    s.add_argument("inputs", nargs="+", type=Path, metavar="LOG")
    s.add_argument("--speed", type=float, help="speed factor (default: as fast as possible)")
    _add_log_args(s)
    _add_sink_args(s)
    s.set_defaults(func=cmd_replay)
    s = sub.add_parser("report", help="post-flight fault report: one self-contained HTML page "
                                      "per log")
    s.add_argument("inputs", nargs="+", type=Path, metavar="LOG")
    s.add_argument("--out", type=Path, default=Path("report"), help="folder for the pages")
    s.add_argument("--config", type=Path, help="monitor TOML (defaults suit the simulator)")
    _add_log_args(s)
    s.set_defaults(func=cmd_report)
    s = sub.add_parser("alarms", help="subscribe to the Zenoh alarm stream and print alarms")
    s.add_argument("keyexpr", nargs="?", default="gcs/*/alarm")
    s.add_argument("--connect", action="append", help=f"endpoint (default {DEFAULT_ZENOH})")
    s.add_argument("--connect-timeout", type=float, default=5.0,
                   help="fail when no endpoint answers within this many seconds (5)")
    s.add_argument("--history", type=int, default=256,
                   help="recent alarms fetched per vehicle at start (0: live only)")
    s.add_argument("--duration", type=float)
    s.add_argument("--max", type=int, help="stop after this many alarms")
    s.add_argument("--json", action="store_true", help="print raw JSON payloads")
    _add_zenoh_args(s, listen_default="none", connect_default=DEFAULT_ZENOH,
                    mode_default="client")
    s.set_defaults(func=cmd_alarms)
    s = sub.add_parser("config", help="print the default configuration, or check a file and "
                                      "print the configuration it gives")
    s.add_argument("file", nargs="?", type=Path, help="a monitor TOML to check")
    s.add_argument("--defaults", action="store_true",
                   help="print the complete default configuration (TOML, a comment per key)")
    s.add_argument("--markdown", action="store_true",
                   help="print the configuration reference (docs/configuration.md)")
    s.add_argument("--no-comments", action="store_true", help="TOML without comments")
    s.set_defaults(func=cmd_config)
    s = sub.add_parser("calibrate", help="noise model, thresholds and the yaw-rate family's "
                                         "lateral model from your own fault-free flights; "
                                         "writes a config replay and live accept")
    s.add_argument("flights", nargs="+", help="flight logs replay reads (.tlog, .bin, .ulg, "
                   "the CSV layouts), known to be fault-free; FLIGHT@T0:T1 learns from its "
                   "vehicle times T0..T1 s only (either bound may be left out)")
    s.add_argument("--out", type=Path, default=Path("airframe.toml"),
                   help="config to write; the yaw-rate design goes next to it (OUT.yaw_rate.json)")
    s.add_argument("--config", type=Path, help="start from this config instead of the defaults")
    s.add_argument("--margin", type=float, default=1.5,
                   help="J_th = margin x the largest fault-free residual RMS (default 1.5)")
    s.set_defaults(func=cmd_calibrate)
    s = sub.add_parser("demo", help="simulate a faulty flight, monitor it, write a recording")
    s.add_argument("--out", type=Path, default=Path("gcs_demo"))
    s.add_argument("--preset", default="demo_airdata_faults",
                   help="the flight: demo_airdata_faults (transport; AoA bias, CAS drift and "
                        "runaway), demo_actuator_faults (small UAV; elevator stuck at zero), or "
                        "any sim-vehicle preset")
    s.set_defaults(func=cmd_demo)
    s = sub.add_parser("evaluate", help="campaigns and paper experiments (tables + plots)")
    s.add_argument("--preset-set", help="campaign preset set (triplex, wan2018, fault_free)")
    s.add_argument("--experiment", help="a named paper experiment (see --list)")
    s.add_argument("--list", action="store_true", help="list the experiments and stop")
    s.add_argument("--runs", type=int, default=100, help="runs of a --preset-set campaign")
    s.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    s.add_argument("--seed", type=int, default=0, help="seed of a --preset-set campaign")
    s.add_argument("--quick", action="store_true", help="a small, fast version")
    s.add_argument("--out", type=Path, default=Path("eval_out"),
                   help="folder for tables, CSVs and plots (default eval_out)")
    s.add_argument("--config", type=Path, help="monitor TOML for --preset-set campaigns")
    s.add_argument("--weather", choices=("declared", "estimated"), default="declared",
                   help="--preset-set campaigns: give each run its scenario's weather as a "
                   "forecast (declared, default), or none: the monitor estimates it from the "
                   "flight (estimated)")
    s.add_argument("--data-dir", type=Path, help="real flight data for the real-data experiments "
                   "(default: $GCS_DATA_DIR, else ../shared/data/real beside the repository)")
    s.set_defaults(func=cmd_evaluate)
    s = sub.add_parser("yaw-design", help="Chen2020 observer design of a simulated airframe: "
                                          "LPV fit and LMI gains (the yaw_rate family's data)")
    s.add_argument("--airframe", action="append", choices=["transport", "uav"],
                   help="airframe (repeatable; default both)")
    s.add_argument("--out", type=Path, help="file or folder (default: the shipped designs)")
    s.set_defaults(func=cmd_yaw_design, airframe=None)
    s = sub.add_parser("convert",
                       help="convert flight logs (ArduPilot .bin/.log, PX4 .ulg, CSV) to the "
                            "contract .tlog")
    s.add_argument("inputs", nargs="+", type=Path)
    _add_log_args(s)
    s.add_argument("--out", type=Path, default=Path("converted"))
    s.add_argument("--inject", choices=["none", "lu2016"], default="none",
                   help="inject Lu2016 Table 2 IMU faults open-loop (truth written beside)")
    s.set_defaults(func=cmd_convert)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    from gcs_monitor.link.zenoh_bus import ZenohError

    try:
        return int(args.func(args))
    except ConfigError as exc:
        print(f"gcs-monitor: invalid configuration: {exc}", file=sys.stderr)
        return 2
    except (FileNotFoundError, ValueError, OverflowError) as exc:
        print(f"gcs-monitor: {exc}", file=sys.stderr)
        return 2
    except ZenohError as exc:
        print(f"gcs-monitor: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:
        print(f"gcs-monitor: {exc.strerror or exc}"
              + (f": {exc.filename}" if exc.filename else ""), file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
    except Exception as exc:  # noqa: BLE001 - an operator gets one line; -v shows the trace
        if args.verbose:
            raise
        print(f"gcs-monitor: internal error: {type(exc).__name__}: {exc} (run with -v for the "
              f"traceback)", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
