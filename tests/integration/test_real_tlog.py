"""The real ArduCopter tlog (data/real README sec. 4) replays through the Monitor.

MAVLink 1, 2.7 Hz streams, radio noise (BAD_DATA), a radio (sysid 51) and a GCS (sysid 255)
on the link. The Monitor must not raise, must report which estimators and redundant sets have
their inputs on this telemetry, and radio noise must only ever give LINK alarms.
"""

from __future__ import annotations

from gcs_monitor.fdi.events import AlarmKind
from gcs_monitor.link.transports import TlogSource
from gcs_monitor.monitor import Monitor

TLOG = "dronekit_flight_replay_copter.tlog"  # in the real-data folder (tests/conftest.py)


def test_real_copter_tlog_replays_and_reports_availability(real_data_file):
    src = TlogSource(real_data_file(TLOG))
    m = Monitor()
    for chunk, wall_s in src:
        m.feed(chunk, wall_s)
    m.finish()
    h = m.health()
    assert src.records > 70_000 and src.resync_bytes == 0
    assert h["link"]["parse_errors"] > 1000  # README: ~1314 BAD_DATA chunks of radio noise
    assert "255" not in h["vehicles"]  # the GCS is never monitored
    v = h["vehicles"]["1"]
    assert v["link"]["is_vehicle"] and v["link"]["mav_type"] == 2  # quadrotor
    # ArduPilot: RAW_IMU (instance 0) and SCALED_IMU2 (instance 1), no HIGHRES_IMU
    assert v["inputs"]["imu_source"] == "RAW_IMU" and v["inputs"]["imu_ids"] == [0, 1]
    fams = v["families"]
    # its inputs are all there, but ArduCopter streams RAW_IMU at ~3 Hz: the IMU family says it
    # cannot judge at that rate (monitor_degraded), never silently
    assert fams["imu"]["state"] == "degraded"
    assert "below the 10 Hz the IMU family needs" in fams["imu"]["reason"]
    assert fams["airdata"]["state"] == "unavailable"
    assert fams["airdata"]["reason"].startswith("missing AoA, CAS")
    assert v["inputs"]["aoa_instances"] == 0 and v["inputs"]["cas_instances"] == 0
    assert 800 < v["vehicle_time_s"] < 1400  # README: 1377 s recorded
    radio = h["vehicles"]["51"]["link"]
    assert not radio["is_vehicle"]
    assert {e.kind for e in m.events} <= {AlarmKind.LINK, AlarmKind.MONITOR_DEGRADED}
