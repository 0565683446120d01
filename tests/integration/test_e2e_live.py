"""End to end on loopback: simulator -> UDP -> `gcs-monitor live` -> Zenoh/Rerun/journal.

Processes (all started and stopped here, on free ports):

1. ``gcs-monitor live udpin:127.0.0.1:U --rrd --journal --zenoh --zenoh-listen tcp/...:Z``
2. ``sim-vehicle run SCENARIO.toml --live --udp 127.0.0.1:U`` (real time, 25 s of flight)
3. ``gcs-monitor alarms gcs/*/alarm --connect tcp/127.0.0.1:Z --json`` (a second tool)

The scenario is demo_airdata_faults with the faults moved early (AoA vane 1 bias at 8 s, CAS 0
drift at 10 s, CAS 2 runaway at 14 s). While the monitor runs, the test queries the health
queryable ``gcs/1/health``. Afterwards the same scenario is run in file mode and its .tlog is
replayed twice with ``gcs-monitor replay``.

Comparison rule (live vs replay): the set of channels with a RAISED alarm must be equal, and
for each channel the first RAISED event must agree in kind and fault type, with vehicle times
within ``LIVE_REPLAY_TOL_S``. Live UDP on loopback delivers the same bytes in different chunks;
decoding does not depend on chunking, so in practice the times agree exactly, the tolerance
only allows for a datagram lost under load. Replay vs replay must be identical event by event
(same transitions, same vehicle times, same magnitudes): vehicle time drives everything.
"""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

BIN = Path(sys.executable).parent
GCS = BIN / "gcs-monitor"
SIM = BIN / "sim-vehicle"
FAULTS = (("aoa1", 8.0), ("cas0", 10.0), ("cas2", 14.0))  # the faulty instances, onset (s)
DURATION_S = 25.0
LIVE_REPLAY_TOL_S = 0.5
SENSOR = "sensor_fault"

pytestmark = pytest.mark.skipif(not (GCS.exists() and SIM.exists()),
                                reason="console scripts not installed")


def _free_port(kind: int) -> int:
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _scenario(tmp: Path) -> Path:
    from sim_vehicle.scenario import load_scenario, to_toml

    sc = load_scenario("demo_airdata_faults")
    by_channel = dict(FAULTS)
    faults = tuple(dataclasses.replace(f, t_start_s=by_channel[f.channel]) for f in sc.faults)
    assert {f.channel for f in faults} == set(by_channel)
    sc = dataclasses.replace(sc, duration_s=DURATION_S, faults=faults,
                             manoeuvre=dataclasses.replace(sc.manoeuvre, start_s=2.0))
    path = tmp / "e2e.toml"
    path.write_text(to_toml(sc), encoding="utf-8")
    return path


def _env() -> dict[str, str]:
    return os.environ | {"OPENBLAS_NUM_THREADS": "1", "PYTHONUNBUFFERED": "1"}


def _start(args: list[str], log: Path) -> subprocess.Popen[bytes]:
    fh = open(log, "wb")  # noqa: SIM115 - closed with the process in _stop
    p = subprocess.Popen(args, stdout=fh, stderr=subprocess.STDOUT, env=_env(),
                         start_new_session=True)
    p.log_fh = fh  # type: ignore[attr-defined]
    return p


def _stop(p: subprocess.Popen[bytes], sig: int = signal.SIGINT, timeout: float = 10.0) -> None:
    if p.poll() is None:
        p.send_signal(sig)
        try:
            p.wait(timeout)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait(5)
    p.log_fh.close()  # type: ignore[attr-defined]


def _wait_for(cond, timeout: float, what: str) -> None:  # noqa: ANN001
    deadline = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.1)


def _tcp_open(port: int) -> bool:
    with socket.socket() as s:
        s.settimeout(0.2)
        return s.connect_ex(("127.0.0.1", port)) == 0


def _keepalive(udp_port: int, ready):  # noqa: ANN001, ANN202
    from gcs_monitor.link.transports import gcs_heartbeat

    hb = gcs_heartbeat()
    last = [0.0]

    def cond() -> bool:
        if ready():
            return True
        if time.monotonic() - last[0] > 0.5:
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
                s.sendto(hb, ("127.0.0.1", udp_port))
            last[0] = time.monotonic()
        return False

    return cond


def _journal(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def _first_raised(events: list[dict]) -> dict[str, dict]:
    out: dict[str, dict] = {}
    for e in events:
        if e["state"] == "raised" and e["channel_name"] not in out:
            out[e["channel_name"]] = e
    return out


def _key(e: dict) -> tuple:
    return (e["channel_name"], e["state"], e["kind"], e["fault_type"], e["t_us"], e["magnitude"])


def _health_query(port: int) -> dict | None:
    import zenoh

    from gcs_monitor.sinks.zenoh_sink import make_config

    with zenoh.open(make_config(connect=[f"tcp/127.0.0.1:{port}"])) as s:
        for _ in range(10):
            for reply in s.get("gcs/1/health", timeout=2.0):
                if reply.ok is not None:
                    return json.loads(reply.ok.payload.to_string())
            time.sleep(0.3)
    return None


def _rrd_paths(path: Path) -> set[str]:
    from rerun.chunk import RrdReader

    return {c.entity_path for c in RrdReader(path).stream()}


def test_live_loopback_zenoh_rerun_and_replay(tmp_path: Path) -> None:
    scen = _scenario(tmp_path)
    udp, zport = _free_port(socket.SOCK_DGRAM), _free_port(socket.SOCK_STREAM)
    zep = f"tcp/127.0.0.1:{zport}"
    rrd, journal = tmp_path / "live.rrd", tmp_path / "live.jsonl"
    procs: list[subprocess.Popen[bytes]] = []
    try:
        # file-mode run of the same scenario (for the replays), in parallel with the live run
        sim_file = _start([str(SIM), "run", str(scen), "--out", str(tmp_path / "file"),
                           "--no-progress"], tmp_path / "sim_file.log")
        procs.append(sim_file)
        mon = _start([str(GCS), "live", f"udpin:127.0.0.1:{udp}", "--rrd", str(rrd),
                      "--journal", str(journal), "--zenoh", "--zenoh-listen", zep,
                      "--idle-timeout", "3", "--duration", "60"], tmp_path / "monitor.log")
        procs.append(mon)
        _wait_for(lambda: b"listening" in (tmp_path / "monitor.log").read_bytes(), 30,
                  "gcs-monitor live to listen")
        sim = _start([str(SIM), "run", str(scen), "--live", "--udp", f"127.0.0.1:{udp}",
                      "--out", str(tmp_path / "live"), "--no-progress"], tmp_path / "sim.log")
        procs.append(sim)
        # The idle timeout runs from the start: until the simulator sends, a GCS heartbeat
        # (sysid 255, never monitored) keeps the link alive. The monitor opens its Zenoh session
        # with the first vehicle; then the second tool starts.
        _wait_for(_keepalive(udp, lambda: _tcp_open(zport)), 30, "the monitor's Zenoh listener")
        sub = _start([str(GCS), "alarms", "gcs/*/alarm", "--connect", zep, "--json",
                      "--duration", "60"], tmp_path / "alarms.jsonl")
        procs.append(sub)
        time.sleep(6.0)  # mid-flight (vehicle time ~10 s): the health queryable answers
        health = _health_query(zport)
        assert sim.wait(DURATION_S + 30) == 0, (tmp_path / "sim.log").read_text()
        assert mon.wait(30) == 0, (tmp_path / "monitor.log").read_text()
        time.sleep(1.0)  # let the subscriber print what is in flight
        _stop(sub)
        assert sim_file.wait(60) == 0, (tmp_path / "sim_file.log").read_text()
    finally:
        for p in procs:
            _stop(p)

    # -- live: alarms on exactly the faulty instances, no link alarm on clean loopback ----------
    live = _journal(journal)
    raised = _first_raised(live)
    assert set(raised) == {ch for ch, _ in FAULTS}, (tmp_path / "monitor.log").read_text()
    for ch, onset_s in FAULTS:
        e = raised[ch]
        assert e["kind"] == SENSOR and e["t_us"] * 1e-6 > onset_s
    assert all(e["kind"] == SENSOR for e in live)

    # -- the second process received the same alarm stream -------------------------------------
    got = [json.loads(line) for line in (tmp_path / "alarms.jsonl").read_text().splitlines()
           if line.startswith("{")]
    assert [_key(e) for e in got] == [_key(e) for e in live]

    # -- the health queryable answered while the monitor ran -------------------------------------
    assert health is not None
    text = json.dumps(health)
    assert '"families"' in text and "Lu2016 ATSEKF" in text

    # -- the recording holds residuals and alarms -----------------------------------------------
    paths = _rrd_paths(rrd)
    for needed in ("/1/alarms", "/1/sets/aoa/rms/1", "/1/sets/cas/rms/0", "/1/sets/cas/rms/2"):
        assert needed in paths, needed

    # -- replay the file-mode tlog twice: deterministic, and the same alarms as live --------------
    (tlog,) = (tmp_path / "file").glob("*.tlog")
    reps = []
    for k in range(2):
        j = tmp_path / f"replay{k}.jsonl"
        res = subprocess.run([str(GCS), "replay", str(tlog), "--journal", str(j), "--quiet"],
                             capture_output=True, env=_env(), timeout=120)
        assert res.returncode == 0, res.stderr.decode()
        reps.append(_journal(j))
    assert reps[0] and [_key(e) for e in reps[0]] == [_key(e) for e in reps[1]]
    rep_raised = _first_raised(reps[0])
    assert set(rep_raised) == set(raised)
    for ch, e in raised.items():
        r = rep_raised[ch]
        assert (r["kind"], r["fault_type"]) == (e["kind"], e["fault_type"]), ch
        assert abs(r["t_us"] - e["t_us"]) * 1e-6 <= LIVE_REPLAY_TOL_S, ch
