"""RerunSink: .rrd written and read back with rerun's own reader; paths, levels, quaternions."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest
from rerun.chunk import RrdReader
from scipy.spatial.transform import Rotation

from dashboards.blueprints import default_blueprint
from gcs_monitor.core.frames import quat_from_euler
from gcs_monitor.core.types import ChannelId
from gcs_monitor.fdi.events import (
    AlarmEvent,
    AlarmKind,
    AlarmState,
    ChannelStatus,
    FaultType,
    SetStatus,
)
from gcs_monitor.fdi.records import Estimate, StepOutput
from gcs_monitor.sinks.rerun_sink import (
    APPLICATION_ID,
    RerunSink,
    entity_path,
    geodetic_to_local_ned,
    rerun_quat_xyzw,
)
from gcs_monitor.telemetry.frame import Frame, ImuSample

ACC_X = ChannelId("acc", 0, "x")


def _frame(t_us: int) -> Frame:
    return Frame(
        t_us=t_us,
        imu=[ImuSample(t_us, 0, np.array([0.1, 0.0, -9.8]), np.zeros(3))],
        euler_rad=np.array([0.1, 0.05, 1.0]),
        lat_rad=0.8 + t_us * 1e-12,
        lon_rad=0.14,
        alt_msl_m=300.0,
    )


def _set(t_us: int, bias: float) -> SetStatus:
    return SetStatus(
        "aoa",
        t_us,
        (0.05, 0.051, 0.05 + bias),
        0.05,
        0.0505,
        (0.5, 0.5, 0.0),
        (0.001, 0.001, bias),
        0.01,
        (False, False, bias > 0.01),
        "duplex",
    )


def _run(path: Path, n: int = 300, **kw: object) -> RerunSink:
    sink = RerunSink(1, rrd_path=path, recording_id="test-rec",  # type: ignore[arg-type]
                     blueprint=default_blueprint(1), **kw)
    for k in range(n):
        t_us = k * 10_000  # 100 Hz
        events = []
        if k == 150:
            events.append(
                AlarmEvent(
                    t_us,
                    ChannelId("aoa", 2),
                    AlarmState.RAISED,
                    AlarmKind.SENSOR_FAULT,
                    FaultType.BIAS,
                    0.03,
                    0.03,
                    0.01,
                    "voting",
                )
            )
        if k == 200:
            events.append(
                AlarmEvent(
                    t_us,
                    ChannelId("aoa", 0),
                    AlarmState.RAISED,
                    AlarmKind.SET_LOST,
                    FaultType.UNKNOWN,
                    float("nan"),
                    0.03,
                    0.01,
                    "voting",
                )
            )
        if k == 250:
            events.append(
                AlarmEvent(
                    t_us,
                    ChannelId("aoa", 2),
                    AlarmState.CLEARED,
                    AlarmKind.SENSOR_FAULT,
                    FaultType.BIAS,
                    0.0,
                    0.001,
                    0.01,
                    "voting",
                )
            )
        est = Estimate(
            "imu_ts",
            t_us,
            states={"vel_ned_mps": np.array([20.0, 1.0, 0.0])},
            faults={ACC_X: 0.2},
            virtual={ACC_X: -0.1},
        )
        ch = ChannelStatus(ACC_X, t_us, 0.2, 0.15, 0.3, False, "imu_ts")
        sink.publish(_frame(t_us), StepOutput(events=events, estimates=[est], sets=[
            _set(t_us, 0.03 if k >= 150 else 0.0)], channels=[ch]))
    sink.update_health({"alarms_active": 1})
    sink.close()
    return sink


def _chunks_by_path(path: Path) -> dict[str, list[pa.RecordBatch]]:
    out: dict[str, list[pa.RecordBatch]] = {}
    for c in RrdReader(path).stream():
        out.setdefault(c.entity_path, []).append(c.to_record_batch())
    return out


def _column(batches: list[pa.RecordBatch], suffix: str) -> list[object]:
    vals: list[object] = []
    for b in batches:
        for name in b.schema.names:
            if name.endswith(suffix):
                col = b.column(name)
                if pa.types.is_duration(col.type) or pa.types.is_timestamp(col.type):
                    col = col.cast(pa.int64())  # exact ns; to_pylist() would go through timedelta
                vals.extend(col.to_pylist())
    return vals


def test_entity_path_tree() -> None:
    assert entity_path(3, "sets", "aoa", "measured", 2) == "/3/sets/aoa/measured/2"
    assert entity_path(3, "alarms") == "/3/alarms"
    assert entity_path(3) == "/3"


def test_rrd_contains_residuals_alarms_and_blueprint(tmp_path: Path) -> None:
    p = tmp_path / "v1.rrd"
    _run(p)
    reader = RrdReader(p)
    rec = reader.recordings()
    assert [r.application_id for r in rec] == [APPLICATION_ID]
    assert [b.application_id for b in reader.blueprints()] == [APPLICATION_ID]
    chunks = _chunks_by_path(p)
    for needed in (
        "/1/sets/aoa/rms/2",
        "/1/sets/aoa/threshold",
        "/1/sets/aoa/measured/0",
        "/1/sets/aoa/fused",
        "/1/sets/aoa/weight/1",
        "/1/channels/acc/0/x/rms",
        "/1/channels/acc/0/x/threshold",
        "/1/channels/acc/0/x/measured",
        "/1/channels/acc/0/x/corrected",
        "/1/channels/acc/0/x/fault/imu_ts",
        "/1/estimates/imu_ts/vel_ned_mps",
        "/1/alarms",
        "/1/world/track",
        "/1/world/vehicle",
        "/1/health",
    ):
        assert needed in chunks, needed

    # 300 frames at 100 Hz, plots decimated to 20 Hz -> 60 rows, all sent on close.
    rms2 = [v[0] for v in _column(chunks["/1/sets/aoa/rms/2"], "Scalars:scalars") if v]
    assert len(rms2) == 60
    assert rms2[:30] == [0.0] * 30 and rms2[30:] == [pytest.approx(0.03)] * 30
    times = _column(chunks["/1/sets/aoa/rms/2"], "vehicle_time")
    # Exact vehicle time: every 5th frame of 10 ms -> multiples of 50 ms, in ns.
    assert sorted(times) == [k * 50_000_000 for k in range(60)]

    # Component columns are list arrays (one batch per row).
    texts = [v[0] for v in _column(chunks["/1/alarms"], "TextLog:text")]
    levels = [v[0] for v in _column(chunks["/1/alarms"], "TextLog:level")]
    assert len(texts) == 3
    assert texts[0].startswith("RAISED sensor_fault aoa2 bias magnitude +0.03 rad")
    assert levels == ["WARN", "ERROR", "INFO"]


def test_decimation(tmp_path: Path) -> None:
    # Cost per publish: benchmarks/bench_rerun_sink.py.
    sink = RerunSink(1, rrd_path=tmp_path / "decimation.rrd", plot_rate_hz=20.0)
    est = Estimate("imu_ts", 0, states={"vel_ned_mps": np.zeros(3)}, faults={ACC_X: 0.2})
    ch = [ChannelStatus(ChannelId("acc", 0, a), 0, 0.2, 0.15, 0.3, False, "imu_ts") for a in "xyz"]
    n = 2000
    for k in range(n):
        t_us = k * 10_000
        sink.publish(_frame(t_us), StepOutput(estimates=[est],
                                              sets=[_set(t_us, 0.0), _set(t_us, 0.0)],
                                              channels=ch))
    sink.close()
    assert sink.n_publish == n
    # 2000 frames -> 400 decimated samples; 1 aoa set (same name twice) + 3 channels x 4 leaves ...
    assert sink.n_rows_sent % 400 == 0 and sink.n_rows_sent > 0


def test_quaternion_reorder_matches_scipy() -> None:
    rng = np.random.default_rng(7)
    for _ in range(20):
        phi, theta, psi = rng.uniform(-1.5, 1.5, 3)
        xyzw = rerun_quat_xyzw(quat_from_euler(phi, theta, psi))
        ref = Rotation.from_euler("ZYX", [psi, theta, phi]).as_quat()  # scalar-last
        assert np.allclose(xyzw, ref, atol=1e-12) or np.allclose(xyzw, -ref, atol=1e-12)


def test_geodetic_to_local_ned() -> None:
    origin = (math.radians(47.0), math.radians(8.0), 500.0)
    r = 6_367_000.0
    d_lat = 1000.0 / r
    d_lon = 500.0 / (r * math.cos(origin[0]))
    ned = geodetic_to_local_ned(origin[0] + d_lat, origin[1] + d_lon, 520.0, origin)
    np.testing.assert_allclose(ned, [1000.0, 500.0, -20.0], atol=1e-9)  # exact by construction


def test_needs_an_output() -> None:
    with pytest.raises(ValueError, match="rrd_path"):
        RerunSink(1)
