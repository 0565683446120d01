"""MAVLink 2 with a clean environment: no MAVLINK20 / MAVLINK_DIALECT, and none set on import.

The project imports the MAVLink 2 ``ardupilotmega`` dialect module directly and never goes
through ``mavutil`` (which picks its dialect from those variables at import). Each check runs in a
fresh interpreter with both variables removed, so no earlier import in the test process (nor the
Makefile's exports) can make it pass.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MAVLINK_ENV = ("MAVLINK20", "MAVLINK_DIALECT")


def _run_clean(code: str) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in MAVLINK_ENV}
    env["PYTHONPATH"] = str(ROOT)
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    r = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], env=env, cwd=ROOT,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_encode_decode_round_trip_is_mavlink2_without_env(tmp_path: Path) -> None:
    out = _run_clean(f"""
        import json, math, os, sys
        from pathlib import Path
        import numpy as np
        from gcs_monitor.convert.encode import TlogEncoder
        from gcs_monitor.link.decode import Decoder
        from gcs_monitor.link.transports import TlogSource
        from sim_vehicle.mavlink_out import MavlinkEncoder
        from sim_vehicle.sensors.suite import SensorSample

        # simulator encoder -> bytes -> monitor decoder
        enc = MavlinkEncoder(sysid=3)
        pk = [enc.heartbeat()]
        for group, values in (
                ("imu0", [0.1, -0.2, -9.8, 0.01, 0.02, 0.03]),
                ("airdata", [0.05, 0.06, 0.07, 30.0, 31.0, 32.0, 0.01]),
                ("gps", [20.0, 1.0, -0.5, math.radians(52.0), math.radians(4.4), 120.0])):
            pk += enc.encode_sample(SensorSample(group, 1_000_000, np.array(values)))
        sim_magic = sorted({{p[0] for _, p in pk}})
        sim_msgs = Decoder().feed(b"".join(p for _, p in pk), 0.0)

        # converter's encoder -> .tlog -> TlogSource -> monitor decoder
        path = Path({str(tmp_path / "clean.tlog")!r})
        with TlogEncoder(path, sysid=4) as te:
            te.heartbeat(0)
            te.imu(10_000, 0, (0.0, 0.0, -9.8), (0.0, 0.0, 0.0))
            te.airspeed(10_000, 2, 25.0)
            te.aoa(10_000, [0.05, 0.06, 0.07], 0.0)
        d = Decoder()
        conv_msgs = [m for chunk, wall in TlogSource(path) for m in d.feed(chunk, wall)]
        conv_msgs += d.flush()

        def summary(msgs):
            return [[m.get_type(), m.get_msgbuf()[0], m.get_srcSystem()] for m in msgs]

        print(json.dumps({{
            "env": [os.environ.get(k) for k in {MAVLINK_ENV!r}],
            "mavutil": "pymavlink.mavutil" in sys.modules,
            "sim_magic": sim_magic,
            "sim": summary(sim_msgs),
            "conv": summary(conv_msgs),
        }}))
    """)
    assert out["env"] == [None, None] and not out["mavutil"]
    assert out["sim_magic"] == [0xFD]  # every packet on the wire is a MAVLink 2 frame
    sim = out["sim"]
    assert len(sim) == 1 + 1 + 6 + 2  # HEARTBEAT, HIGHRES_IMU, 3 AIRSPEED + AOA_SSA + 2 NVF, GPS x2
    assert {t for t, _, _ in sim} == {"HEARTBEAT", "HIGHRES_IMU", "AIRSPEED", "AOA_SSA",
                                      "NAMED_VALUE_FLOAT", "GLOBAL_POSITION_INT", "GPS_RAW_INT"}
    assert all(magic == 0xFD and sysid == 3 for _, magic, sysid in sim)
    conv = out["conv"]
    # AIRSPEED (id 295) exists only in MAVLink 2, AOA_SSA only in ardupilotmega
    assert [t for t, _, _ in conv] == ["HEARTBEAT", "HIGHRES_IMU", "AIRSPEED", "AOA_SSA",
                                       "NAMED_VALUE_FLOAT", "NAMED_VALUE_FLOAT"]
    assert all(magic == 0xFD and sysid == 4 for _, magic, sysid in conv)


def test_importing_the_packages_leaves_environment_unchanged() -> None:
    out = _run_clean("""
        import importlib, json, os, pkgutil, sys
        before = dict(os.environ)
        import dashboards, gcs_monitor, sim_vehicle
        names = [m.name for pkg in (gcs_monitor, sim_vehicle, dashboards)
                 for m in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + ".")]
        for name in names:
            importlib.import_module(name)
        after = dict(os.environ)
        changed = sorted(k for k in before.keys() | after.keys() if before.get(k) != after.get(k))
        print(json.dumps({"n": len(names), "changed": changed,
                          "mavutil": "pymavlink.mavutil" in sys.modules}))
    """)
    assert out["n"] > 50  # the walk found the modules
    assert out["changed"] == []
    assert not out["mavutil"]  # nothing on the monitoring path reads the variables either
