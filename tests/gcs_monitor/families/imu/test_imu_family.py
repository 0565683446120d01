"""The IMU family: per-estimator thresholds, re-initialisation notices (ESTIMATOR events, never
sensor faults) and the re-convergence warm-up, with scripted estimators in the pipeline."""

from __future__ import annotations

import math

from gcs_monitor.families.base import FamilyContext
from gcs_monitor.families.imu.config import ImuFamilyConfig, ImuFdiSets
from gcs_monitor.families.imu.family import ImuFamily
from gcs_monitor.families.imu.imu_ts import FAULT_CHANNELS
from gcs_monitor.fdi.events import AlarmKind, AlarmState
from gcs_monitor.fdi.records import Estimate
from gcs_monitor.pipeline import VehiclePipeline
from gcs_monitor.telemetry.frame import Frame

CFG = ImuFamilyConfig()
WARMUP_S = CFG.warmup_s


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
                            reinit_warmup_s=WARMUP_S)
        if frame.t_us == self.reinit_at_us:
            return Estimate(self.name, frame.t_us, faults=faults, reinit="gps velocity step",
                            reinit_warmup_s=self.warmup_s)
        return Estimate(self.name, frame.t_us, faults=faults)


def _pipeline(est: _Scripted, sets: ImuFdiSets | None = None) -> VehiclePipeline:
    fdi = sets if sets is not None else (CFG.hosm.fdi if est.name == "imu_hosm" else CFG.ts.fdi)
    fam = ImuFamily(CFG, FamilyContext(vehicle=1, stale_after_s=0.5), estimators=[(est, fdi)])
    return VehiclePipeline(1, [fam])


def _run(est: _Scripted, n: int, dt_us: int = 10_000) -> list:
    p = _pipeline(est)
    events = []
    for k in range(n):
        events += p.step(Frame(t_us=k * dt_us, imu=[None])).events
    return events


def test_reanchoring_is_an_estimator_notice_and_pauses_judgement() -> None:
    # a fault estimate far above threshold, but the estimator re-anchors at 8 s: no sensor-fault
    # alarm is raised while its channels are not judged (8-10 s), one ESTIMATOR notice is raised
    # and cleared when judgement resumes
    thr = CFG.ts.fdi.acc.threshold
    assert not _run(_Scripted("imu_ts", 0.0), 1000)  # the start itself is silent
    est = _Scripted("imu_ts", 0.0, reinit_at_us=8_000_000)
    p = _pipeline(est)
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
    p = _pipeline(_Scripted("imu_hosm", 0.0))
    st = p.step(Frame(t_us=0, imu=[None]))
    th = {c.channel.kind: c.threshold for c in st.channels}
    assert math.isclose(th["acc"], CFG.hosm.fdi.acc.threshold)
    assert math.isclose(th["gyro"], CFG.hosm.fdi.gyro.threshold)
    assert CFG.hosm.fdi.acc.threshold != CFG.ts.fdi.acc.threshold
    p = _pipeline(_Scripted("imu_ts", 0.0))
    st = p.step(Frame(t_us=0, imu=[None]))
    th = {c.channel.kind: c.threshold for c in st.channels}
    assert math.isclose(th["acc"], CFG.ts.fdi.acc.threshold)


def test_channel_windows_follow_the_measured_imu_rate() -> None:
    # the same 0.5 s window is 50 samples at 100 Hz and 25 at 50 Hz (never an assumed rate)
    for dt_us, n in ((10_000, 50), (20_000, 25)):
        est = _Scripted("imu_ts", 0.0)
        p = _pipeline(est)
        for k in range(int(6e6 / dt_us)):
            p.step(Frame(t_us=k * dt_us, imu=[None]))
        fam = p.families[0]
        assert isinstance(fam, ImuFamily)
        mon = fam._est[0].monitors[0]
        assert mon.p.rms.rms_window_n == n
        assert mon.p.confirmation.detect_n == round(0.8 * n)
        assert mon.p.dt_s == dt_us * 1e-6
