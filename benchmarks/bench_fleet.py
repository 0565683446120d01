"""Fleet load: N simulated vehicles at full telemetry rates through workers on Zenoh.

Every run is the whole path with processes: a UDP sender (simulated transport flights: 3 IMUs,
triplex AoA/CAS, every contract message, 631 messages/s per vehicle, an AoA-1 bias at 20-35 s
on three vehicles in four), ``gcs-monitor bridge``, ``gcs-monitor router``, ``gcs-monitor
worker`` (default families) and an alarm recorder. Printed per run: vehicles, workers, whether
the workers kept real time (their worst vehicle's lag behind the sender, and drops), alarm
latency from the fault onset to the recorder (p50/p99), worker CPU per vehicle (core seconds per
second of telemetry, hence vehicles per core) and memory per vehicle.

  python benchmarks/bench_fleet.py                      # ladder 10, 20, 30 on one worker,
                                                        # then 2 and 3 workers on namespaces
  python benchmarks/bench_fleet.py --one 40 --workers 2 --same-host   # a process pool
  python benchmarks/bench_fleet.py --profile 6          # where a worker's time goes

Keeping real time: at the end of sending, every vehicle's published vehicle time is within
``LAG_OK_S`` of what the sender sent, the worst lag did not grow over the second half, and no
frame was dropped anywhere (kernel, bridge queue, worker inbox).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from tests.helpers.fleet_procs import FleetResult, Templates, run_fleet  # noqa: E402
from tests.helpers.netns import NetnsLab, skip_reason  # noqa: E402

DURATION_S = 70.0  # of telemetry per run
ONSETS = (20.0, 25.0, 30.0, None, 35.0, 22.0, 28.0, None)
LAG_OK_S = 1.0
WARM_S = 15.0  # CPU per vehicle is taken after this much of the run


def pct(xs: list[float], q: float) -> float:
    if not xs:
        return float("nan")
    s = sorted(xs)
    return s[min(len(s) - 1, max(0, round(q / 100.0 * (len(s) - 1))))]


def summarise(r: FleetResult, workers: int, *, where: str) -> dict[str, object]:
    lags = r.lags_s()
    t_end_send = r.t0_wall_s + DURATION_S / r.speed
    by_worker: dict[str, list[tuple[float, float]]] = {}
    for w, wk, lag in lags:
        by_worker.setdefault(wk, []).append((w, lag))
    final_lag = max((max(lag for w, lag in v if w <= t_end_send + 1.0) for v in by_worker.values()
                     if any(w <= t_end_send + 1.0 for w, _ in v)), default=float("nan"))
    half = r.t0_wall_s + DURATION_S / r.speed / 2
    # growth over the second half of sending (after it, the sender's time stands still)
    growth = max((max((lag for w, lag in v if half <= w <= t_end_send + 1.0), default=0.0)
                  - max((lag for w, lag in v if w < half), default=0.0))
                  for v in by_worker.values()) if by_worker else float("nan")
    raw_dropped = max((st.get("raw_dropped") or 0 for st in r.status_log), default=0)
    bridge_line = r.bridge_out.strip().splitlines()[-1] if r.bridge_out.strip() else ""
    kernel = _num_before(bridge_line, " kernel drops")
    queue = _num_before(bridge_line, " dropped chunks")
    lat = list(r.latencies_s().values())
    faulty = sum(1 for s in range(1, r.n + 1) if r.onset_of(s) is not None)
    # worker CPU and memory over the steady part
    cpu_per_vs, mem_per_v = [], []
    for k in range(workers):
        name = f"w{k}"
        pts = [(s["t_s"], s[name], s["wall_s"]) for s in r.samples if name in s]
        steady = [p for p in pts if WARM_S <= p[0] <= DURATION_S / r.speed]
        owned = _owned(r, name)
        if len(steady) >= 2 and owned:
            dt = steady[-1][0] - steady[0][0]
            cpu = steady[-1][1]["cpu_s"] - steady[0][1]["cpu_s"]
            # per vehicle-second the worker processed (its watermarks), not sent: a worker
            # that falls behind processes less than the wall clock passes
            done = _processed_vs(r, name, steady[0][2], steady[-1][2])
            cpu_per_vs.append(cpu / (done if done else dt * r.speed * owned))
            mem_per_v.append((steady[-1][1]["rss_mb"] - pts[0][1]["rss_mb"]) / owned)
    cpu_v = statistics.mean(cpu_per_vs) if cpu_per_vs else float("nan")
    drops = (kernel or 0) + (queue or 0) + raw_dropped
    return {
        "where": where, "vehicles": r.n, "workers": workers,
        "real_time": bool(final_lag <= LAG_OK_S and growth <= LAG_OK_S / 2 and drops == 0
                          and len(lat) == faulty),
        "final_lag_s": round(final_lag, 2), "lag_growth_s": round(growth, 2),
        "alarms": f"{len(lat)}/{faulty}",
        "latency_p50_s": round(pct(lat, 50), 3), "latency_p99_s": round(pct(lat, 99), 3),
        "cpu_core_s_per_vehicle_s": round(cpu_v, 4),
        "vehicles_per_core": round(1.0 / cpu_v, 1) if cpu_v == cpu_v and cpu_v > 0 else None,
        "mem_mb_per_vehicle": round(statistics.mean(mem_per_v), 1) if mem_per_v else None,
        "kernel_drops": kernel, "bridge_queue_drops": queue, "worker_inbox_drops": raw_dropped,
        "load_avg_1min": round(os.getloadavg()[0], 1),
    }


def _processed_vs(r: FleetResult, worker: str, wall_a: float, wall_b: float) -> float | None:
    """Vehicle-seconds ``worker`` processed between two wall times: the advance of its
    vehicles' watermarks in its last statuses before each (None: no status before ``wall_a``)."""
    mine = [st for st in r.status_log if st.get("worker") == worker and st.get("watermarks")]
    before_a = [st for st in mine if st["recv_wall_s"] <= wall_a]
    before_b = [st for st in mine if st["recv_wall_s"] <= wall_b]
    if not before_a or not before_b:
        return None
    a, b = before_a[-1]["watermarks"], before_b[-1]["watermarks"]
    return sum(b[s] - a[s] for s in b if s in a) * 1e-6 or None


def _owned(r: FleetResult, worker: str) -> int:
    owned = [len(st.get("owned") or []) for st in r.status_log if st.get("worker") == worker]
    return max(owned) if owned else 0


def _num_before(text: str, marker: str) -> int | None:
    i = text.find(marker)
    if i < 0:
        return None
    word = text[:i].split()[-1].strip(",")
    return int(word) if word.isdigit() else None


def run_one(n: int, workers: int, *, lab: NetnsLab | None, same_host: bool,
            tpl: Path, where: str) -> dict[str, object]:
    with tempfile.TemporaryDirectory(prefix="bench_fleet_") as d:
        r = run_fleet(Path(d), tpl, n=n, workers=workers, duration_s=DURATION_S + 3.0,
                      lab=lab, same_host_workers=same_host, sample_s=5.0)
    row = summarise(r, workers, where=where)
    print(json.dumps(row), flush=True)
    return row


def table(rows: list[dict[str, object]]) -> str:
    head = ("| where | vehicles | workers | real time | worst lag at end (s) | alarms | "
            "latency p50 / p99 (s) | worker core-s per vehicle-s | vehicles per core | "
            "MB per vehicle | drops (kernel / bridge / worker) | load avg |")
    lines = [head, "|" + "---|" * 12]
    for r in rows:
        lines.append(
            f"| {r['where']} | {r['vehicles']} | {r['workers']} | "
            f"{'yes' if r['real_time'] else 'no'} | {r['final_lag_s']} | {r['alarms']} | "
            f"{r['latency_p50_s']} / {r['latency_p99_s']} | {r['cpu_core_s_per_vehicle_s']} | "
            f"{r['vehicles_per_core']} | {r['mem_mb_per_vehicle']} | {r['kernel_drops']} / "
            f"{r['bridge_queue_drops']} / {r['worker_inbox_drops']} | {r['load_avg_1min']} |")
    return "\n".join(lines)


def profile(n: int, seconds: float) -> None:
    """Where a worker's time goes: one Monitor per vehicle with its Zenoh sink, as a worker
    runs them, under cProfile; time grouped by package."""
    import cProfile
    import pstats

    from gcs_monitor.link.zenoh_bus import ZenohOptions, open_bus
    from gcs_monitor.monitor import Monitor
    from gcs_monitor.sinks.zenoh_sink import ZenohSink
    from tests.helpers.fleet import fleet_packets, free_port

    pk = fleet_packets(list(range(1, n + 1)), duration_s=seconds,
                       fault_at_s={s: ONSETS[(s - 1) % len(ONSETS)] for s in range(1, n + 1)})
    batches: list[tuple[int, bytes]] = []
    cur: dict[int, list[bytes]] = {}
    edge = 10_000
    for t, p in pk:
        if t >= edge:
            batches += [(s, b"".join(v)) for s, v in cur.items()]
            cur, edge = {}, t + 10_000
        cur.setdefault(p[5], []).append(p)

    def feed(prof: cProfile.Profile | None) -> float:
        with open_bus(ZenohOptions(listen=(f"tcp/127.0.0.1:{free_port()}",))) as bus:
            mons = {s: Monitor(sinks_for=lambda v: [ZenohSink(v, bus=bus)], only_sysid=s)
                    for s in range(1, n + 1)}
            t0 = time.process_time()
            if prof is not None:
                prof.enable()
            for s, data in batches:
                mons[s].feed(data, 0.0)
            if prof is not None:
                prof.disable()
            cpu = time.process_time() - t0
            for m in mons.values():
                m.close()
        return cpu

    plain = feed(None)
    prof = cProfile.Profile()
    cpu = feed(prof)
    st = pstats.Stats(prof)
    groups: dict[str, float] = {}
    rules = [("~", "built-ins (struct, math, dict/list ops) called by the rest"),
             ("pymavlink", "pymavlink decode"), ("gcs_monitor/core/", "core (kernels, types)"),
             ("link/decode", "link: decoder"),
             ("link/stats", "link: statistics"), ("telemetry/", "telemetry: frame assembly"),
             ("families/imu", "IMU family (imu_ts)"), ("families/airdata", "air-data family"),
             ("filters/", "filters"), ("models/", "models"), ("fdi/", "FDI"),
             ("sinks/zenoh_sink", "Zenoh sink"), ("sinks/schema", "payload JSON"),
             ("json/", "payload JSON"), ("zenoh", "Zenoh"), ("monitor.py", "monitor"),
             ("pipeline.py", "pipeline"), ("numba", "numba dispatch"), ("numpy", "numpy"),
             ("scipy", "scipy")]
    for (file, _, _), (_, _, tt, _, _) in st.stats.items():  # type: ignore[attr-defined]
        key = next((label for pat, label in rules if pat in file), "other")
        groups[key] = groups.get(key, 0.0) + tt
    total = sum(groups.values())
    print(f"\n{n} vehicles x {seconds:g} s, one Monitor per vehicle with its Zenoh sink, in "
          f"process: {plain:.2f} CPU s = {plain / (n * seconds):.4f} core-s per vehicle-s "
          f"({n * seconds / plain:.1f} vehicles per core); under cProfile {cpu:.1f} CPU s "
          f"(shares below)\n")
    print("| part | share of the worker's time |\n|---|---|")
    for k, v in sorted(groups.items(), key=lambda kv: -kv[1]):
        print(f"| {k} | {100 * v / total:.1f} % |")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ladder", default="10,20,30", help="vehicle counts on one worker")
    ap.add_argument("--one", type=int, help="one run with this many vehicles")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--same-host", action="store_true", help="workers on one host (a pool)")
    ap.add_argument("--netns", default="2,3", help="worker counts on namespace hosts")
    ap.add_argument("--netns-vehicles", type=int, default=0,
                    help="vehicles of the namespace runs (default: the largest real-time N x "
                         "workers)")
    ap.add_argument("--profile", type=int, help="profile a worker with this many vehicles")
    a = ap.parse_args()
    if a.profile:
        profile(a.profile, 20.0)
        return 0
    with tempfile.TemporaryDirectory(prefix="bench_fleet_tpl_") as d:
        tpl = Templates(DURATION_S + 2.0, ONSETS).build(Path(d) / "templates.pkl")
        rows: list[dict[str, object]] = []
        if a.one:
            rows.append(run_one(a.one, a.workers, lab=None, same_host=a.same_host, tpl=tpl,
                                where="loopback" + (", one host" if a.same_host else "")))
            print("\n" + table(rows))
            return 0
        best = 0
        for n in (int(x) for x in a.ladder.split(",") if x):
            row = run_one(n, 1, lab=None, same_host=False, tpl=tpl, where="loopback")
            rows.append(row)
            if row["real_time"]:
                best = max(best, n)
        reason = skip_reason()
        for k in (int(x) for x in a.netns.split(",") if x):
            if reason is not None:
                print(f"namespace runs skipped: {reason}")
                break
            n = a.netns_vehicles or max(best, 10) * k
            with NetnsLab(k + 1) as lab:
                rows.append(run_one(n, k, lab=lab, same_host=False, tpl=tpl,
                                    where=f"{k + 1} namespace hosts"))
    print("\n" + table(rows))
    print(f"\nlargest N that kept real time on one worker: {best} (this machine: "
          f"{os.cpu_count()} cores shared; load average {os.getloadavg()[0]:.1f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
