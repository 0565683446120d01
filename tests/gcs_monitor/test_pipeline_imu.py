"""VehiclePipeline and the IMU fault estimators: per-estimator thresholds, re-initialisation
notices (ESTIMATOR events, never sensor faults) and the re-convergence warm-up."""

from __future__ import annotations

import math

from gcs_monitor.config import MonitorConfig
from gcs_monitor.estimators.base import Estimate
from gcs_monitor.estimators.imu_ts import FAULT_CHANNELS
from gcs_monitor.fdi.events import AlarmKind, AlarmState
from gcs_monitor.pipeline import IMU_WARMUP_US, VehiclePipeline
from gcs_monitor.telemetry.frame import Frame


class _Scripted:
    """An IMU estimator whose fault estimates and re-initialisations follow a script."""

    def __init__(self, name: str, value: float, reinit_at_us: int | None = None,
                 warmup_s: float = 2.0) -> None:
        self.name = name
        self.value = value
        self.reinit_at_us = reinit_at_us
        self.warmup_s = warmup_s

    def reset(self) -> None:
        pass

    def step(self, frame: Frame) -> Estimate:
        faults = dict.fromkeys(FAULT_CHANNELS, self.value)
        if frame.t_us == 0:
            return Estimate(self.name, frame.t_us, faults=faults, reinit="start",
                            reinit_warmup_s=IMU_WARMUP_US * 1e-6)
        if frame.t_us == self.reinit_at_us:
            return Estimate(self.name, frame.t_us, faults=faults, reinit="gps velocity step",
                            reinit_warmup_s=self.warmup_s)
        return Estimate(self.name, frame.t_us, faults=faults)


def _run(est: _Scripted, n: int, dt_us: int = 10_000) -> list:
    p = VehiclePipeline(1, MonitorConfig(), imu_estimators=[est])
    events = []
    for k in range(n):
        events += p.step(Frame(t_us=k * dt_us, imu=[None])).events
    return events


def test_reanchoring_is_an_estimator_notice_and_pauses_judgement() -> None:
    # a fault estimate far above threshold, but the estimator re-anchors at 8 s: no sensor-fault
    # alarm is raised while its channels are not judged (8-10 s), one ESTIMATOR notice is raised
    # and cleared when judgement resumes
    thr = MonitorConfig().fdi.acc.threshold
    assert not _run(_Scripted("imu_ts", 0.0), 1000)  # the start itself is silent
    est = _Scripted("imu_ts", 0.0, reinit_at_us=8_000_000)
    p = VehiclePipeline(1, MonitorConfig(), imu_estimators=[est])
    out = []
    for k in range(1200):
        if k * 10_000 >= 8_000_000:
            est.value = 10.0 * thr  # a fault appears with the re-anchoring
        out += [(k * 10_000, e) for e in p.step(Frame(t_us=k * 10_000, imu=[None])).events]
    notices = [(t, e) for t, e in out if e.kind is AlarmKind.ESTIMATOR]
    faults = [(t, e) for t, e in out if e.kind is AlarmKind.SENSOR_FAULT]
    assert [e.state for _, e in notices] == [AlarmState.RAISED, AlarmState.CLEARED]
    assert notices[0][0] == 8_000_000 and notices[1][0] == 10_000_000
    assert "gps velocity step" in notices[0][1].message
    assert faults and min(t for t, _ in faults) > 10_000_000  # judged only after the warm-up


def test_imu_hosm_channels_use_their_own_thresholds() -> None:
    cfg = MonitorConfig()
    p = VehiclePipeline(1, cfg, imu_estimators=[_Scripted("imu_hosm", 0.0)])
    st = p.step(Frame(t_us=0, imu=[None]))
    th = {c.channel.kind: c.threshold for c in st.channels}
    assert math.isclose(th["acc"], cfg.fdi.acc_hosm.threshold)
    assert math.isclose(th["gyro"], cfg.fdi.gyro_hosm.threshold)
    p = VehiclePipeline(1, cfg, imu_estimators=[_Scripted("imu_ts", 0.0)])
    st = p.step(Frame(t_us=0, imu=[None]))
    th = {c.channel.kind: c.threshold for c in st.channels}
    assert math.isclose(th["acc"], cfg.fdi.acc.threshold)
