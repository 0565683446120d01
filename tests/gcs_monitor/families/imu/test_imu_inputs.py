"""The IMU family names the input it never received (a monitor that cannot judge says why)."""

from __future__ import annotations

import numpy as np

from gcs_monitor.families.base import FamilyContext
from gcs_monitor.families.imu.config import ImuFamilyConfig
from gcs_monitor.families.imu.family import ImuFamily
from gcs_monitor.families.imu.imu_ts import ImuTwoStageEstimator
from gcs_monitor.pipeline import VehiclePipeline
from gcs_monitor.telemetry.frame import Frame, ImuSample


def _run(**kw) -> tuple[str, str, str]:
    """100 Frames at 50 Hz with the given inputs; (coverage state, its reason, estimator's)."""
    cfg = ImuFamilyConfig()
    p = VehiclePipeline(1, [ImuFamily(cfg, FamilyContext(vehicle=1, stale_after_s=0.5))])
    out = None
    for k in range(100):
        t_us = k * 20_000
        imu = ImuSample(t_us, 0, np.array([0.0, 0.0, -9.81]) + 1e-3 * k, np.zeros(3))
        out = p.step(Frame(t_us=t_us, imu=[imu], **kw))
    assert out is not None
    return out.coverage[0].state, out.coverage[0].reason, out.estimates[0].reason


def test_a_log_without_gps_says_no_gps_velocity() -> None:
    # the two real pyulog samples: attitude, IMU, no GPS topic, local position invalid
    state, reason, _ = _run(euler_rad=np.zeros(3), att_age_s=0.0)
    assert (state, reason) == ("unavailable", "no GPS velocity in the telemetry")


def test_a_gps_without_3d_fix_is_named() -> None:
    state, reason, est = _run(euler_rad=np.zeros(3), att_age_s=0.0, gps_fix=2)
    assert state == "unavailable"
    assert reason == "no GPS velocity: GPS without a 3D fix (fix type 2)"
    assert est == "gps velocity missing: no 3D fix (GPS fix type 2)"


def test_no_attitude_and_no_gps_are_both_named() -> None:
    state, reason, _ = _run()
    assert state == "unavailable"
    assert reason == "no GPS velocity in the telemetry; no attitude in the telemetry"


def test_gps_velocity_is_reported_before_the_position_that_comes_with_it() -> None:
    e = ImuTwoStageEstimator().step(Frame(
        t_us=0, imu=[ImuSample(0, 0, np.array([0.0, 0.0, -9.81]), np.zeros(3))],
        euler_rad=np.zeros(3), att_age_s=0.0))
    assert not e.available and e.reason == "gps velocity missing or stale"


def test_pyulog_samples_without_gps_say_so(real_data_file) -> None:
    from pathlib import Path

    from gcs_monitor.config import MonitorConfig
    from gcs_monitor.evaluation.papers.real_flights import monitor_flight

    path: Path = real_data_file("px4_ulog/pyulog_sample.ulg")
    r = monitor_flight(path, MonitorConfig(), "ulog", "defaults")
    assert r.state["imu"] == "unavailable"
    assert r.reason["imu"] == "no GPS velocity in the telemetry"
