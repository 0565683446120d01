"""ZenohSink: alarm received by a subscriber in another process, health queryable, no hangs."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
import zenoh

from gcs_monitor.core.types import ChannelId
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState, FaultType
from gcs_monitor.fdi.records import Estimate, StepOutput
from gcs_monitor.sinks.schema import SCHEMA_VERSION, alarm_from_dict
from gcs_monitor.sinks.zenoh_sink import (
    ZenohSink,
    format_alarm,
    keyexpr,
    make_config,
    subscribe_alarms,
)
from gcs_monitor.telemetry.frame import Frame


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _alarm(t_us: int, vehicle: int = 4) -> AlarmEvent:
    return AlarmEvent(
        t_us,
        ChannelId("gyro", 1, "r"),
        AlarmState.RAISED,
        AlarmKind.SENSOR_FAULT,
        FaultType.OSCILLATION,
        0.02,
        0.015,
        0.01,
        "yaw_smo",
        "yaw gyro",
        vehicle,
    )


def test_keyexpr_builder() -> None:
    assert keyexpr(4, "alarm") == "gcs/4/alarm"
    assert keyexpr(4, "estimate", "imu_ts") == "gcs/4/estimate/imu_ts"
    assert keyexpr("*", "health") == "gcs/*/health"
    with pytest.raises(ValueError):
        keyexpr(1, "alarms")


def test_alarm_reaches_other_process_and_health_answers() -> None:
    port = _free_port()
    ep = f"tcp/127.0.0.1:{port}"
    with ZenohSink(4, listen=[ep]) as sink:
        child_code = textwrap.dedent(f"""
            import sys
            from gcs_monitor.sinks.zenoh_sink import run_alarm_printer
            print("READY", flush=True)
            n = run_alarm_printer("gcs/*/alarm", [{ep!r}], duration_s=15, max_alarms=1,
                                  json_lines=True)
            sys.exit(0 if n == 1 else 3)
        """)
        child = subprocess.Popen(
            [sys.executable, "-c", child_code], stdout=subprocess.PIPE, text=True
        )
        try:
            assert child.stdout is not None
            assert child.stdout.readline().strip() == "READY"
            # The subscription needs a moment to propagate; publish until the child has one.
            t_us = 1_000_000
            deadline = time.monotonic() + 12
            while child.poll() is None and time.monotonic() < deadline:
                sink.publish(Frame(t_us=t_us, imu=[]), StepOutput(events=[_alarm(t_us)]))
                t_us += 10_000
                time.sleep(0.1)
            out, _ = child.communicate(timeout=10)
        finally:
            if child.poll() is None:
                child.kill()
                child.wait()
        assert child.returncode == 0
        payload = json.loads(out.strip().splitlines()[-1])
        assert payload["schema_version"] == SCHEMA_VERSION
        ev = alarm_from_dict(payload)
        assert ev.channel == ChannelId("gyro", 1, "r") and ev.vehicle == 4
        assert ev.fault_type == FaultType.OSCILLATION and ev.estimator == "yaw_smo"
        assert sink.n_published >= 1 and sink.n_errors == 0

        # Health queryable, from a second session connecting to the sink.
        sink.update_health({"alarms": [_alarm(5)], "link": {"loss": 0.01}})
        with zenoh.open(make_config(connect=[ep])) as s:
            replies = []
            deadline = time.monotonic() + 5
            while not replies and time.monotonic() < deadline:
                replies = [r for r in s.get("gcs/4/health", timeout=1.0) if r.ok is not None]
        assert len(replies) == 1
        h = json.loads(replies[0].ok.payload.to_string())
        assert h["type"] == "health" and h["vehicle"] == 4
        assert h["health"]["link"] == {"loss": 0.01}
        assert h["health"]["alarms"][0]["channel"] == {"kind": "gyro", "instance": 1, "axis": "r"}


def test_estimates_decimated_in_process() -> None:
    port = _free_port()
    ep = f"tcp/127.0.0.1:{port}"
    got: list[dict[str, object]] = []
    with (
        ZenohSink(2, listen=[ep], estimate_rate_hz=5.0) as sink,
        zenoh.open(make_config(connect=[ep])) as s,
    ):
        sub = s.declare_subscriber(
            "gcs/2/estimate/*", lambda smp: got.append(json.loads(smp.payload.to_string()))
        )
        time.sleep(0.5)  # let the subscription propagate
        for k in range(200):  # 2 s of 100 Hz frames -> 10 estimates at 5 Hz
            t_us = k * 10_000
            est = Estimate("imu_ts", t_us, states={"vel_ned_mps": np.array([1.0, 2.0, 3.0])})
            sink.publish(Frame(t_us=t_us, imu=[]), StepOutput(estimates=[est]))
        deadline = time.monotonic() + 5
        while len(got) < 10 and time.monotonic() < deadline:
            time.sleep(0.05)
        sub.undeclare()
    assert len(got) == 10
    assert [d["t_us"] for d in got] == [k * 200_000 for k in range(10)]
    assert got[0]["states"] == {"vel_ned_mps": [1.0, 2.0, 3.0]}


def test_unreachable_connect_does_not_block_or_crash() -> None:
    dead = f"tcp/127.0.0.1:{_free_port()}"  # nobody listens here
    t0 = time.monotonic()
    sink = ZenohSink(7, listen=[], connect=[dead])
    for k in range(100):
        sink.publish(Frame(t_us=k * 10_000, imu=[]),
                         StepOutput(events=[_alarm(k * 10_000, 7)]))
    sink.close()
    elapsed = time.monotonic() - t0
    assert elapsed < 5.0, elapsed  # open retries in the background (~0.5 s), puts never block
    assert sink.n_errors == 0


def test_bad_listen_endpoint_is_a_clear_error() -> None:
    # 10.255.255.1 is not a local address: binding fails at once (os error 99). The sink does
    # not run on silently without its outputs (issue 19): one line says what failed.
    from gcs_monitor.link.zenoh_bus import ZenohError

    with pytest.raises(ZenohError, match=r"cannot listen on tcp/10\.255\.255\.1:7447: cannot "
                                         r"assign requested address"):
        ZenohSink(8, listen=["tcp/10.255.255.1:7447"])


def test_port_in_use_is_a_clear_error() -> None:
    from gcs_monitor.link.zenoh_bus import ZenohError

    with socket.socket() as holder:
        holder.bind(("127.0.0.1", 0))
        holder.listen()
        port = holder.getsockname()[1]
        with pytest.raises(ZenohError, match=f"cannot listen on tcp/127.0.0.1:{port}: address "
                                             "already in use"):
            ZenohSink(8, listen=[f"tcp/127.0.0.1:{port}"])


def test_subscriber_closes_without_hang() -> None:
    # A process with a callback subscriber that is closed exits promptly (stack-notes pitfall).
    code = textwrap.dedent(f"""
        from gcs_monitor.link.zenoh_bus import ZenohOptions
        from gcs_monitor.sinks.zenoh_sink import subscribe_alarms
        # a peer keeps retrying an endpoint nobody listens on (a client would fail at once)
        sub = subscribe_alarms("gcs/*/alarm", connect=["tcp/127.0.0.1:{_free_port()}"],
                               options=ZenohOptions(mode="peer"))
        sub.close()
    """)
    r = subprocess.run([sys.executable, "-c", code], timeout=60)  # liveness: a hang never ends
    assert r.returncode == 0


def test_format_alarm_line() -> None:
    from gcs_monitor.sinks.schema import alarm_to_dict

    line = format_alarm(alarm_to_dict(_alarm(2_500_000), wall_time_s=0.0))
    assert line.startswith("1970-01-01T00:00:00.000Z v4 t=2.500s RAISED")
    assert ("gyro1.r oscillation mag=+0.02 rad/s conf=0.00 J=0.015 J_th=0.01 [yaw_smo] yaw gyro"
            in line)
    assert subscribe_alarms  # exported helper
