"""Scores against truth (gcs_monitor.evaluation.scoring) on hand-built runs and events."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_monitor.core.types import ChannelId
from gcs_monitor.core.units import DEG2RAD, KT2MPS
from gcs_monitor.evaluation import scoring
from gcs_monitor.evaluation.records import FaultTruth, ImuRun
from gcs_monitor.families.imu.imu_ts import FAULT_CHANNELS
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState, FaultType

# ------------------------------------------------------------------------------------------------
# air data
# ------------------------------------------------------------------------------------------------


def _ev(t_s: float, ch: ChannelId, state: AlarmState = AlarmState.RAISED,
        kind: AlarmKind = AlarmKind.SENSOR_FAULT) -> AlarmEvent:
    return AlarmEvent(round(t_s * 1e6), ch, state, kind, FaultType.BIAS, 0.0, 0.0, 1.0, "test")


def test_channel_names_map_to_air_data_channels() -> None:
    assert scoring.channel_of("aoa2") == ChannelId("aoa", 2)
    assert scoring.channel_of("cas0") == ChannelId("cas", 0)
    assert scoring.channel_of("imu0.acc.x") is None  # not an air-data set: not scored here
    assert scoring.channel_of("ssa") is None


def test_score_faults_by_hand() -> None:
    aoa1 = ChannelId("aoa", 1)
    faults = [FaultTruth(aoa1, "bias", 10_000_000, None),
              FaultTruth(ChannelId("cas", 2), "drift", 20_000_000, None)]
    events = [_ev(9.0, aoa1),  # before the fault: not a detection of it
              _ev(10.5, aoa1),  # detection, 0.5 s delay
              _ev(11.0, aoa1, AlarmState.UPDATED),
              _ev(21.0, ChannelId("cas", 2), kind=AlarmKind.LINK),  # link alarms never count
              _ev(22.0, ChannelId("cas", -1), kind=AlarmKind.SET_LOST)]
    res = scoring.score_faults("m", events, faults)
    assert res[0].detected and res[0].delay_s == pytest.approx(0.5)
    assert not res[1].detected and math.isnan(res[1].delay_s)
    assert scoring.n_raised(events) == 2  # the two RAISED sensor alarms on aoa1


def test_table3_aggregates_max_and_mean() -> None:
    d2r, k2m = DEG2RAD, KT2MPS
    stats = [(False, {"aoa": (2 * d2r, 1 * d2r), "cas": (4 * k2m, 2 * k2m)}),
             (False, {"aoa": (3 * d2r, 3 * d2r), "cas": (1 * k2m, 0 * k2m)})]
    t3 = scoring.table3(stats)
    assert t3["fault-free"] == pytest.approx([3.0, 4.0, 2.0, 1.0])
    assert all(math.isnan(x) for x in t3["faulty"])


# ------------------------------------------------------------------------------------------------
# IMU
# ------------------------------------------------------------------------------------------------


def _event(t_s: float, ch: ChannelId, estimator: str = "imu_ts") -> AlarmEvent:
    return AlarmEvent(t_us=round(t_s * 1e6), channel=ch, state=AlarmState.RAISED,
                      kind=AlarmKind.SENSOR_FAULT, fault_type=FaultType.BIAS, magnitude=1.0,
                      residual_rms=1.0, threshold=0.5, estimator=estimator)


def _run(events: list[AlarmEvent]) -> ImuRun:
    t = np.arange(0, 4001) * 0.01
    f_true = np.zeros((len(t), 6))
    f_true[(t > 10.0) & (t < 30.0), 0] = 3.0  # only acc x faulty
    return ImuRun(name="synthetic", t_s=t, f_hat={"imu_ts": f_true.copy()}, f_true=f_true,
                  events=events, fault_windows=[(10.0, 30.0)], duration_s=40.0)


def test_fault_truth_interpolates_log_and_is_zero_elsewhere() -> None:
    log = {"imu0.acc.y": ([1.0, 2.0], [0.0, 2.0]), "imu0.gyro.r": ([], [])}
    f = scoring.imu_fault_truth(np.array([0.5, 1.5, 2.0, 3.0]), log)
    np.testing.assert_allclose(f[:, 1], [0.0, 1.0, 2.0, 0.0])
    assert np.all(f[:, [0, 2, 3, 4, 5]] == 0.0)


def test_score_masks_follow_the_documented_windows() -> None:
    run = _run([])
    inf, quiet = scoring.score_masks(run)
    t = run.t_s
    assert t[inf].min() == pytest.approx(11.0) and t[inf].max() == pytest.approx(30.0)
    assert t[quiet].min() == pytest.approx(2.0)
    assert not np.any(quiet & (t >= 10.0) & (t < 32.0))
    assert t[quiet].max() == pytest.approx(40.0)


def test_rmse_reports_gyro_in_deg_per_s() -> None:
    err = np.zeros((4, 6))
    err[:, 0] = [1.0, -1.0, 1.0, -1.0]
    err[:, 3] = math.radians(2.0)
    r = scoring.rmse(err, np.ones(4, dtype=bool))
    np.testing.assert_allclose(r, [1.0, 0.0, 0.0, 2.0, 0.0, 0.0], atol=1e-12)


def test_detection_summary_delays_and_false_alarms() -> None:
    ax, gp = FAULT_CHANNELS[0], FAULT_CHANNELS[3]
    run = _run([_event(5.0, ax), _event(10.56, ax), _event(12.0, gp),
                _event(11.0, ax, estimator="other")])
    d = scoring.detection_summary(run)
    assert d["delay_s"][0] == pytest.approx(10.56 - 10.01, abs=1e-9)  # first faulty sample
    assert d["false"] == 2  # acc x before the fault, gyro p never faulty
    assert d["missed"] == 0
    assert all(math.isnan(x) for x in d["delay_s"][1:])
