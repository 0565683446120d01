"""Alarms into a ground station through a real router: simulated vehicle -> MAVProxy ->
``gcs-monitor live --mavlink-alarms`` -> back into MAVProxy -> a second MAVLink client sees
the STATUSTEXT alarms with the right severity and text.

Everything runs on loopback ports this test picks, and is started and stopped here (CI has
nothing running). MAVProxy (PyPI) is in the test extra.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from gcs_monitor.link.mav import mavlink
from gcs_monitor.tools.screenshot import free_port

ROOT = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
SCENARIO = """
[scenario]
description = "AoA vane 1 bias 3 deg at 6 s (mavproxy alarm test)"
airframe = "transport"
duration_s = 18.0
seed = 42
[initial]
alt_m = 3000.0
tas_kts = 250.0
[wind]
kind = "turbulence"
turbulence_sigma_mps = 1.0
[sensors]
set = "lu2016"
n_imu = 3
[[faults]]
channel = "aoa1"
kind = "bias"
t_start_s = 6.0
bias_deg = 3.0
"""


def _udp_ports(n: int) -> list[int]:
    return [free_port() for _ in range(n)]


@pytest.mark.skipif(shutil.which("mavproxy.py", path=str(BIN)) is None,
                    reason="MAVProxy not installed (pip install -e '.[test]')")
def test_alarms_reach_a_second_client_through_mavproxy(tmp_path: Path) -> None:
    p_vehicle, p_alarms, p_monitor, p_client = _udp_ports(4)
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", MAVLINK20="1",
               MAVLINK_DIALECT="ardupilotmega")
    scen = tmp_path / "scenario.toml"
    scen.write_text(SCENARIO)
    procs: list[subprocess.Popen[bytes]] = []

    def start(cmd: list[str], name: str) -> subprocess.Popen[bytes]:
        log = open(tmp_path / f"{name}.log", "wb")  # noqa: SIM115 - closed with the process
        p = subprocess.Popen(cmd, cwd=tmp_path, env=env, stdout=log, stderr=subprocess.STDOUT,
                             stdin=subprocess.DEVNULL)
        procs.append(p)
        return p

    from pymavlink import mavutil

    client = mavutil.mavlink_connection(f"udpin:127.0.0.1:{p_client}", dialect="ardupilotmega")
    try:
        start([str(BIN / "mavproxy.py"), f"--master=udpin:127.0.0.1:{p_vehicle}",
               f"--master=udpin:127.0.0.1:{p_alarms}", f"--out=udp:127.0.0.1:{p_monitor}",
               f"--out=udp:127.0.0.1:{p_client}", "--daemon", "--non-interactive",
               "--default-modules=link", f"--state-basedir={tmp_path}",
               # a simulator slower than real time on a loaded machine must not look like a
               # delayed link (MAVProxy then stops forwarding the telemetry)
               "--cmd=set checkdelay 0"], "mavproxy")
        time.sleep(3.0)
        start([str(BIN / "gcs-monitor"), "live", f"udpin:127.0.0.1:{p_monitor}",
               "--mavlink-alarms", f"udpout:127.0.0.1:{p_alarms}", "--duration", "40",
               "--idle-timeout", "5", "--quiet"], "monitor")
        time.sleep(2.0)
        start([str(BIN / "sim-vehicle"), "run", str(scen), "--live", "--udp",
               f"127.0.0.1:{p_vehicle}", "--no-progress"], "vehicle")
        texts = []
        t_end = time.monotonic() + 45.0
        while time.monotonic() < t_end:
            m = client.recv_match(type="STATUSTEXT", blocking=True, timeout=0.5)
            if m is None:
                continue
            if m.get_srcComponent() == mavlink.MAV_COMP_ID_ONBOARD_COMPUTER:
                texts.append(m)
                if any("aoa1" in t.text and "raised" in t.text for t in texts):
                    break
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
        client.close()
    logs = {f.name: f.read_text(errors="replace")[-2000:] for f in tmp_path.glob("*.log")}
    raised = [t for t in texts if "aoa1" in t.text and " raised " in t.text]
    assert raised, (texts, logs)
    ev = raised[0]
    assert ev.severity == mavlink.MAV_SEVERITY_WARNING
    assert ev.text.startswith("FDI raised aoa1 sensor_fault")
    assert ev.get_srcSystem() == 1  # the vehicle's system id, the monitor's own component
