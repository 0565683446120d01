"""IMU evaluation harness (gcs_monitor.evaluation.imu): scoring on hand-built runs, and a short
Lu2016 Table 2 run through the whole MAVLink path (sim -> bytes -> Monitor)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from gcs_monitor.core.types import ChannelId
from gcs_monitor.evaluation import imu
from gcs_monitor.families.imu.imu_ts import FAULT_CHANNELS
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState, FaultType


def _event(t_s: float, ch: ChannelId, estimator: str = "imu_ts") -> AlarmEvent:
    return AlarmEvent(t_us=round(t_s * 1e6), channel=ch, state=AlarmState.RAISED,
                      kind=AlarmKind.SENSOR_FAULT, fault_type=FaultType.BIAS, magnitude=1.0,
                      residual_rms=1.0, threshold=0.5, estimator=estimator)


def _run(events: list[AlarmEvent]) -> imu.ImuRun:
    t = np.arange(0, 4001) * 0.01
    f_true = np.zeros((len(t), 6))
    f_true[(t > 10.0) & (t < 30.0), 0] = 3.0  # only acc x faulty
    return imu.ImuRun(name="synthetic", t_s=t, f_hat={"imu_ts": f_true.copy()}, f_true=f_true,
                      events=events, fault_windows=[(10.0, 30.0)], duration_s=40.0)


def test_fault_truth_interpolates_log_and_is_zero_elsewhere() -> None:
    log = {"imu0.acc.y": ([1.0, 2.0], [0.0, 2.0]), "imu0.gyro.r": ([], [])}
    f = imu.fault_truth(np.array([0.5, 1.5, 2.0, 3.0]), log)
    np.testing.assert_allclose(f[:, 1], [0.0, 1.0, 2.0, 0.0])
    assert np.all(f[:, [0, 2, 3, 4, 5]] == 0.0)


def test_score_masks_follow_the_documented_windows() -> None:
    run = _run([])
    inf, quiet = imu.score_masks(run)
    t = run.t_s
    assert t[inf].min() == pytest.approx(11.0) and t[inf].max() == pytest.approx(30.0)
    assert t[quiet].min() == pytest.approx(2.0)
    assert not np.any(quiet & (t >= 10.0) & (t < 32.0))
    assert t[quiet].max() == pytest.approx(40.0)


def test_rmse_reports_gyro_in_deg_per_s() -> None:
    err = np.zeros((4, 6))
    err[:, 0] = [1.0, -1.0, 1.0, -1.0]
    err[:, 3] = math.radians(2.0)
    r = imu.rmse(err, np.ones(4, dtype=bool))
    np.testing.assert_allclose(r, [1.0, 0.0, 0.0, 2.0, 0.0, 0.0], atol=1e-12)


def test_detection_summary_delays_and_false_alarms() -> None:
    ax, gp = FAULT_CHANNELS[0], FAULT_CHANNELS[3]
    run = _run([_event(5.0, ax), _event(10.56, ax), _event(12.0, gp),
                _event(11.0, ax, estimator="other")])
    d = imu.detection_summary(run)
    assert d["delay_s"][0] == pytest.approx(10.56 - 10.01, abs=1e-9)  # first faulty sample
    assert d["false"] == 2  # acc x before the fault, gyro p never faulty
    assert d["missed"] == 0
    assert all(math.isnan(x) for x in d["delay_s"][1:])


def test_fault_free_variant_has_no_faults_and_the_requested_manoeuvre() -> None:
    sc = imu.fault_free_variant("s_turn", 7, duration_s=12.0)
    assert sc.faults == () and sc.seed == 7 and sc.duration_s == 12.0
    assert sc.manoeuvre.kind == "s_turn" and sc.wind.kind == "turbulence"


def test_lu2016_calm_20s_through_mavlink_all_channels_alarmed(tmp_path: Path) -> None:
    """20 s of lu2016_calm (faults from 10 s) with the default monitor estimator and thresholds:
    all six channels alarm within 3 s of the fault start (the drift: after crossing the
    threshold), none before it, and the GS-KM ATSEKF reconstruction is within bounds from the
    Lu2016 synthetic truth (docs/results.md, "Synthetic truth": f_Az 0.41 m/s^2, f_q 0.146 deg/s)
    with margin for the 10-20 s window."""
    sc = imu.scenario("lu2016_calm", duration_s=20.0)
    run_cfg = imu.detection_config({})
    run = imu.simulate(sc, imu.default_variant, run_cfg)
    d = imu.detection_summary(run)
    assert d["missed"] == 0 and d["false"] == 0
    # the 0.1 m/s^3 drift of f_Ay crosses the 0.5 m/s^2 default threshold after 5 s
    thr_ay = run_cfg.fdi.acc.threshold / 0.1
    bounds = [3.0, thr_ay + 1.5, 3.0, 3.0, 3.0, 3.0]
    assert all(0.0 < x < b for x, b in zip(d["delay_s"], bounds, strict=True)), d["delay_s"]
    inf, quiet = imu.score_masks(run)
    err = run.f_hat["imu_ts"] - run.f_true
    r_fault = imu.rmse(err, inf)
    r_quiet = imu.rmse(err, quiet)
    assert np.all(r_fault[:3] < [0.2, 0.2, 0.6]), r_fault
    assert np.all(r_fault[3:] < [0.1, 0.25, 0.15]), r_fault
    assert np.all(r_quiet[:3] < 0.1) and np.all(r_quiet[3:] < 0.05), r_quiet


@pytest.mark.slow
def test_lu2016_table2_gs_beats_as_in_shear_and_turbulence(tmp_path: Path) -> None:
    md = imu.lu2016_table2(tmp_path, 1, True)
    assert (tmp_path / "lu2016_table2.csv").is_file()
    ratios = {}
    for line in (tmp_path / "lu2016_table2_ratio.csv").read_text().splitlines()[1:]:
        scen, filt, acc, gyro = line.split(",")
        ratios[(scen, filt)] = (float(acc), float(gyro))
    for scen in ("lu2016_shear", "lu2016_turbulence"):
        acc, gyro = ratios[(scen, "atsekf")]
        assert acc > 2.0 and 0.8 < gyro < 1.25, (scen, acc, gyro)
    assert "gs_atsekf" in md


@pytest.mark.slow
def test_imu_detection_quick_no_false_alarms(tmp_path: Path) -> None:
    imu.imu_detection(tmp_path, 1, True)
    rows = (tmp_path / "imu_detection_fault_free.csv").read_text().splitlines()[1:]
    assert rows and all(int(r.split(",")[2]) == 0 for r in rows)
