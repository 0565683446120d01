"""Real-data smoke test: the dronekit ArduCopter tlog (MAVLink 1, noisy radio, a reboot) decodes
and assembles without exception (numbers from shared/data/real/README.md; the folder is found by
the ``real_data_file`` fixture, tests/conftest.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gcs_monitor.link.decode import Decoder
from gcs_monitor.link.transports import TlogSource
from gcs_monitor.telemetry.assembler import FrameAssembler, input_availability

TLOG = "dronekit_flight_replay_copter.tlog"  # in the real-data folder


@pytest.fixture(scope="module")
def tlog(real_data_file) -> Path:
    return real_data_file(TLOG)


@pytest.fixture(scope="module")
def replay(tlog):
    d = Decoder()
    asm: dict[int, FrameAssembler] = {}
    frames = []
    progress: list[int] = []
    src = TlogSource(tlog, on_progress=lambda done, total: progress.append(done))
    for data, wall in src:
        for m in d.feed(data, wall):
            s = m._header.srcSystem
            a = asm.get(s)
            if a is None:
                a = asm[s] = FrameAssembler(stats=d.vehicle_stats(s))
            frames += a.push(m)
    return d, asm, frames, progress, src


def test_decodes_with_the_known_bad_data(replay, tlog):
    d, asm, frames, progress, src = replay
    # README: 1314 BAD_DATA chunks (CRC failures of GCS msg 142); resync may find a few more
    assert 1314 <= d.counters.parse_errors <= 1314 + 20
    assert d.vehicles() == [1]  # 255 is the GCS, 51 the radio (no vehicle heartbeat)
    assert d.stats[1].per_type["ATTITUDE"] > 2800
    assert progress[-1] == tlog.stat().st_size
    assert 0 < src.truncated_bytes < 300  # the file itself ends inside its last record


def test_assembles_from_the_ardupilot_fallback_imus(replay):
    d, asm, frames, progress, src = replay
    av = input_availability(asm[1])
    assert av["imu_source"] == "RAW_IMU" and av["imu_ids"] == [0, 1]  # RAW_IMU + SCALED_IMU2
    assert av["attitude"] and av["gps_velocity"] and av["aoa_instances"] == 0
    assert len(frames) > 2800
    acc = np.array([f.imu[0].acc_frd_mps2 for f in frames])
    # a copter mostly sits or hovers: FRD specific force median about (0, 0, -g)
    np.testing.assert_allclose(np.median(acc, axis=0), [0.0, 0.0, -9.8], atol=0.6)
    st = d.stats[1]
    assert st.reboots >= 1  # the vehicle clock restarts in this log (README "Initialising APM")
    assert not st.duplicate_sysid
    with_gps = sum(f.gps_vel_ned_mps is not None for f in frames)
    assert with_gps > 0.8 * len(frames)
