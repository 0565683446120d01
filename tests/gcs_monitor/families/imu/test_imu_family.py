"""The IMU family: per-estimator thresholds, re-initialisation notices (ESTIMATOR events, never
sensor faults) and the re-convergence warm-up, with scripted estimators in the pipeline."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from gcs_monitor.core.constants import EARTH_RADIUS_M
from gcs_monitor.families.base import FamilyContext
from gcs_monitor.families.imu.config import ImuFamilyConfig, ImuFdiSets
from gcs_monitor.families.imu.family import ImuFamily
from gcs_monitor.families.imu.gating import POSITION_LSB_SIGMA_M
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


class _ScriptedAcc(_Scripted):
    """:class:`_Scripted` with the fault estimate on the accelerometer channels only."""

    def step(self, frame: Frame) -> Estimate:
        e = super().step(frame)
        return dataclasses.replace(
            e, faults={c: (v if c.kind == "acc" else 0.0) for c, v in e.faults.items()})


def _ref_frame(t_us: int, sink_mps: float, since_s: float, until_s: float) -> Frame:
    """A Frame whose GPS reference flies north at 20 m/s at 500 m above the sphere, its
    position sinking ``sink_mps`` faster than its (zero) down velocity between ``since_s`` and
    ``until_s`` (a navigation filter correcting itself)."""
    t = t_us * 1e-6
    down = sink_mps * (min(max(t, since_s), until_s) - since_s)
    alt = 500.0 - down
    return Frame(t_us=t_us, imu=[None], gps_vel_ned_mps=np.array([20.0, 0.0, 0.0]),
                 gps_age_s=0.0, gps_new=True, lat_rad=20.0 * t / (EARTH_RADIUS_M + alt),
                 lon_rad=0.0, alt_msl_m=alt)


def test_a_reference_correcting_itself_raises_the_accelerometer_thresholds_only() -> None:
    # 6-9 s: position and velocity disagree by 0.5 m/s down. The allowance is (0.5 - bound) / 1 s
    # with the bound 3 sqrt(2) x 3.2 mm / 1 s (quantisation noise): 0.486 m/s^2 on the acc J_th
    # once a whole window lies in 6-9 s, held reference_hold_s (2 s); the gyro J_th unchanged.
    # A scripted acc fault estimate of 0.4 m/s^2 (what such a reference makes f_hat_Az) from 6.5 s
    # raises nothing; one of 1.0 m/s^2, beyond the reference's own error, is detected.
    acc_th, gyro_th = CFG.ts.fdi.acc.threshold, CFG.ts.fdi.gyro.threshold
    bound = 3.0 * math.sqrt(2.0) * POSITION_LSB_SIGMA_M
    assert CFG.reference_window_s == 1.0 and CFG.reference_hold_s == 2.0
    for fault, alarmed in ((0.4, False), (1.0, True)):
        est = _ScriptedAcc("imu_ts", 0.0)
        p = _pipeline(est)
        th: dict[int, dict[str, float]] = {}
        faults = []
        for k in range(1400):
            t_us = k * 10_000
            est.value = fault if 6.5e6 <= t_us < 9e6 else 0.0
            out = p.step(_ref_frame(t_us, 0.5, 6.0, 9.0))
            th[t_us] = {c.channel.kind: c.threshold for c in out.channels}
            faults += [e for e in out.events if e.kind is AlarmKind.SENSOR_FAULT
                       and e.state is AlarmState.RAISED]
        assert th[5_900_000] == {"acc": acc_th, "gyro": gyro_th}
        assert math.isclose(th[8_000_000]["acc"], acc_th + 0.5 - bound, rel_tol=1e-6)
        assert th[8_000_000]["gyro"] == gyro_th
        # the last window that overlaps 6-9 s by more than the bound ends at ~9.97 s (its
        # inconsistency is 0.5 m/s x the overlap); the allowance is held 2 s after it
        assert th[11_900_000]["acc"] > acc_th
        assert th[12_000_000] == {"acc": acc_th, "gyro": gyro_th}
        assert bool(faults) is alarmed
        assert all(e.channel.kind == "acc" for e in faults)


def test_the_reference_allowance_never_clears_a_raised_alarm() -> None:
    # an acc fault estimate of 0.5 m/s^2 from 5.5 s is raised before the reference starts
    # correcting itself at 6.5 s (allowance 0.486 m/s^2 would put J_th at 0.676, above the
    # fault): the channels in alarm keep J_th 0.19 and stay raised until the fault ends at 10 s
    acc_th = CFG.ts.fdi.acc.threshold
    est = _ScriptedAcc("imu_ts", 0.0)
    p = _pipeline(est)
    th: dict[int, float] = {}
    events = []
    for k in range(1300):
        t_us = k * 10_000
        est.value = 0.5 if 5.5e6 <= t_us < 10e6 else 0.0
        out = p.step(_ref_frame(t_us, 0.5, 6.5, 9.5))
        th[t_us] = next(c.threshold for c in out.channels if c.channel.kind == "acc")
        events += [(t_us, e) for e in out.events if e.kind is AlarmKind.SENSOR_FAULT]
    raised = [t for t, e in events if e.state is AlarmState.RAISED]
    cleared = [t for t, e in events if e.state is AlarmState.CLEARED]
    assert len(raised) == 3 and max(raised) < 6_500_000  # acc x, y, z, before the allowance
    assert th[8_500_000] == acc_th  # frozen in alarm
    assert len(cleared) == 3 and min(cleared) > 10_000_000  # only after the fault ends


class _FaultsAndInnovations:
    """imu_ts-like estimator: gyro r faulty from 10 s with innovations 50x what the noise
    model expects from then on (a fault the filter does not absorb), acc y faulty from 18 s."""

    name = "imu_ts"

    def __init__(self, thr_acc: float, thr_gyro: float, gate2: float) -> None:
        self.thr_acc, self.thr_gyro, self.gate2 = thr_acc, thr_gyro, gate2

    def reset(self) -> None:
        pass

    def step(self, frame: Frame) -> Estimate:
        t = frame.t_us * 1e-6
        faults = dict.fromkeys(FAULT_CHANNELS, 0.0)
        faults[FAULT_CHANNELS[5]] = 10.0 * self.thr_gyro if t >= 10.0 else 0.0
        faults[FAULT_CHANNELS[1]] = 10.0 * self.thr_acc if t >= 18.0 else 0.0
        lam = 50.0 if t >= 10.0 else 1.0
        states = {"test_ratio": np.full(6, lam / self.gate2)}
        if frame.t_us == 0:
            return Estimate(self.name, 0, faults=faults, states=states, reinit="start",
                            reinit_warmup_s=WARMUP_S)
        return Estimate(self.name, frame.t_us, faults=faults, states=states)


def test_innovations_of_a_raised_fault_do_not_switch_judgement_off() -> None:
    """The noise-model consistency check (``max_inconsistency``) reads innovations far above
    the noise model as a model that does not fit the airframe and stops judging. Once a channel
    of the estimator is in alarm, its innovations carry that fault: the average holds, and a
    second fault that comes later is still raised (imu_detection_hosm: the f_Ay drift under
    five raised faults was never raised before)."""
    probe = ImuFamily(CFG, FamilyContext(vehicle=1, stale_after_s=0.5))
    est = _FaultsAndInnovations(CFG.ts.fdi.acc.threshold, CFG.ts.fdi.gyro.threshold,
                                probe._gate2)
    p = VehiclePipeline(1, [ImuFamily(CFG, FamilyContext(vehicle=1, stale_after_s=0.5),
                                      estimators=[(est, CFG.ts.fdi)])])
    raised: dict[str, float] = {}
    judged_late = []
    for k in range(3000):
        out = p.step(Frame(t_us=k * 10_000, imu=[None]))
        for e in out.events:
            if e.kind is AlarmKind.SENSOR_FAULT and e.state is AlarmState.RAISED:
                raised.setdefault(str(e.channel), k * 0.01)
        if k * 0.01 > 20.0:
            judged_late += [f.judged for f in out.families if f.family == "imu"]
    assert 10.0 < raised[str(FAULT_CHANNELS[5])] < 11.5
    assert 18.0 < raised[str(FAULT_CHANNELS[1])] < 19.5
    assert judged_late and all(judged_late)
